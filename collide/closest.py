"""Closest points between triangles, in plain floating point.

Used only to report *where* a contact happens (a point on both surfaces, up to
rounding), never to decide *whether* it happens: that is the exact predicates'
job (predicates.py) and the certified CCD's (ccd.py).
"""
import numpy as np

from .jit import njit, njit_entry
from .motion import MOTION_WIDTH, points_at, screw_motion
from .packed import to_world

# Points and vectors are 3-tuples of floats (values, not arrays: nothing is allocated per
# contact), and each formula keeps the order of operations of its textbook vector form.

@njit(cache=True, inline="always")
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, inline="always")
def _length2(d):
    """Squared length of d: _dot(d, d)."""
    return _dot(d, d)


@njit(cache=True, inline="always")
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True, inline="always")
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True, inline="always")
def _along(a, s, d):
    """a + s d."""
    return (a[0] + s * d[0], a[1] + s * d[1], a[2] + s * d[2])


@njit(cache=True, inline="always")
def _midpoint(a, b):
    return (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2]))


@njit(cache=True)
def closest_point_on_triangle(x, a, b, c):
    """Point of the closed triangle abc nearest to x (3-tuples).

    Walks the Voronoi regions of the vertices, edges and face (Ericson,
    Real-Time Collision Detection, 5.1.5). Zero-area triangles are handled by
    falling back to the nearest point on their three edges.
    """
    ab = _sub(b, a)
    ac = _sub(c, a)
    normal = _cross(ab, ac)
    if _dot(normal, normal) == 0.0:
        return _closest_on_edges(x, a, b, c)
    ax = _sub(x, a)
    d1 = _dot(ab, ax)
    d2 = _dot(ac, ax)
    if d1 <= 0.0 and d2 <= 0.0:
        return a
    bx = _sub(x, b)
    d3 = _dot(ab, bx)
    d4 = _dot(ac, bx)
    if d3 >= 0.0 and d4 <= d3:
        return b
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return _along(a, d1 / (d1 - d3), ab)
    cx = _sub(x, c)
    d5 = _dot(ab, cx)
    d6 = _dot(ac, cx)
    if d6 >= 0.0 and d5 <= d6:
        return c
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return _along(a, d2 / (d2 - d6), ac)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        return _along(b, (d4 - d3) / ((d4 - d3) + (d5 - d6)), _sub(c, b))
    denom = 1.0 / (va + vb + vc)
    return _along(_along(a, vb * denom, ab), vc * denom, ac)


@njit(cache=True)
def closest_point_on_segment(x, a, b):
    """Point of the closed segment ab nearest to x (3-tuples)."""
    ab = _sub(b, a)
    length2 = _dot(ab, ab)
    if length2 == 0.0:
        return a
    t = min(max(_dot(_sub(x, a), ab) / length2, 0.0), 1.0)
    return _along(a, t, ab)


@njit(cache=True)
def _closest_on_edges(x, a, b, c):
    best = closest_point_on_segment(x, a, b)
    for p, q in ((b, c), (c, a)):
        y = closest_point_on_segment(x, p, q)
        if _length2(_sub(y, x)) < _length2(_sub(best, x)):
            best = y
    return best


@njit(cache=True)
def closest_points_of_segments(p1, q1, p2, q2):
    """Nearest points (s, t) of closed segments p1q1 and p2q2 (3-tuples; Ericson 5.1.9)."""
    d1 = _sub(q1, p1)
    d2 = _sub(q2, p2)
    r = _sub(p1, p2)
    a = _dot(d1, d1)
    e = _dot(d2, d2)
    f = _dot(d2, r)
    if a == 0.0 and e == 0.0:
        return p1, p2
    if a == 0.0:
        return p1, _along(p2, min(max(f / e, 0.0), 1.0), d2)
    c = _dot(d1, r)
    if e == 0.0:
        return _along(p1, min(max(-c / a, 0.0), 1.0), d1), p2
    b = _dot(d1, d2)
    denom = a * e - b * b
    s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 0.0 else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t = 1.0
        s = min(max((b - c) / a, 0.0), 1.0)
    return _along(p1, s, d1), _along(p2, t, d2)


@njit(cache=True)
def _edge_crossing(a, b, q0, q1, q2):
    """Where segment ab crosses the plane of triangle q0 q1 q2, or ab's midpoint."""
    normal = _cross(_sub(q1, q0), _sub(q2, q0))
    da = _dot(normal, _sub(a, q0))
    db = _dot(normal, _sub(b, q0))
    if da == db:
        return _midpoint(a, b)
    t = min(max(da / (da - db), 0.0), 1.0)
    return _along(a, t, _sub(b, a))


@njit(cache=True)
def _row(m, i):
    return (m[i, 0], m[i, 1], m[i, 2])


@njit(cache=True)
def contact_point(p, q):
    """A point where triangles p and q (3, 3) touch, or the midpoint of their nearest
    points when they are (slightly) apart. Returns (point (3-tuple), gap)."""
    tri_p = (_row(p, 0), _row(p, 1), _row(p, 2))
    tri_q = (_row(q, 0), _row(q, 1), _row(q, 2))
    best = _midpoint(tri_p[0], tri_q[0])
    best_gap = np.inf
    for tri, other in ((tri_p, tri_q), (tri_q, tri_p)):
        for i in range(3):
            a = tri[i]
            b = tri[(i + 1) % 3]
            # a vertex against the other face
            y = closest_point_on_triangle(a, other[0], other[1], other[2])
            gap = np.sqrt(_length2(_sub(y, a)))
            if gap < best_gap:
                best_gap = gap
                best = _midpoint(a, y)
            # an edge piercing the other face
            x = _edge_crossing(a, b, other[0], other[1], other[2])
            y = closest_point_on_triangle(x, other[0], other[1], other[2])
            gap = np.sqrt(_length2(_sub(y, x)))
            if gap < best_gap:
                best_gap = gap
                best = _midpoint(x, y)
    for i in range(3):
        for j in range(3):
            s, t = closest_points_of_segments(tri_p[i], tri_p[(i + 1) % 3], tri_q[j], tri_q[(j + 1) % 3])
            gap = np.sqrt(_length2(_sub(s, t)))
            if gap < best_gap:
                best_gap = gap
                best = _midpoint(s, t)
    return best, best_gap


@njit_entry
def contact_points(ps, block, rows, row0, row1, fractions, object_a, object_b, tri_a, tri_b, point, start, stop,
                   screw):
    """Fill point (C, 3) float64 at the contact rows rows[start:stop] (rows int64 (R,)):
    contact_point of triangles tri_a of object_a and tri_b of object_b (int (C,) each) at
    fraction fractions[r] of the step between poses block[row0[i]] and block[row1[i]]
    (block float64 (F, N, 3, 4); row1 unused when the fraction is 0), the objects moving
    by screw motion (``screw``) or along their vertices' chords. Releases the GIL: chunks
    of rows (distinct rows of point) run in parallel threads.

    ps: packed.PackedScene. Placed as the scan places them (packed.to_world, then
    motion.points_at), so the point is where the reported pair touches."""
    motion = np.zeros(MOTION_WIDTH)
    body = np.empty((3, 3))
    ends = np.empty((2, 3, 3))  # the triangle at both frames
    triangles = np.empty((2, 3, 3))  # a's, b's at the contact's moment
    for i in range(start, stop):
        r = rows[i]
        u = fractions[r]
        for side in range(2):
            o = object_a[r] if side == 0 else object_b[r]
            mesh = ps.object_mesh[o]
            face = ps.face_start[mesh] + (tri_a[r] if side == 0 else tri_b[r])
            for c in range(3):
                v = ps.vert_start[mesh] + ps.faces[face, c]
                for d in range(3):
                    body[c, d] = ps.vertices[v, d]
            to_world(body, block[row0[i], o], triangles[side], 0)
            if u > 0.0:
                motion[:] = 0.0
                if screw:
                    screw_motion(block[row0[i], o], block[row1[i], o], 0.0, motion)
                to_world(body, block[row0[i], o], ends[0], 0)
                to_world(body, block[row1[i], o], ends[1], 0)
                points_at(motion, ends[0], ends[1], u, triangles[side])
        best, _ = contact_point(triangles[0], triangles[1])
        point[r, 0], point[r, 1], point[r, 2] = best
