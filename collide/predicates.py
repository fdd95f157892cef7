"""Exact geometric predicates on float64 coordinates.

``orient2d`` and ``orient3d`` return the exact sign (-1, 0, +1) of a
determinant of float64 inputs: a floating-point filter with a proven error
bound (Shewchuk, "Adaptive precision floating-point arithmetic and fast robust
geometric predicates", 1997) decides almost every call; the rest are evaluated
exactly with floating-point expansions (sums of non-overlapping doubles).

``triangles_intersect`` decides exactly whether two closed triangles share a
point, using only these signs, so touching, coplanar and degenerate (zero-area)
triangles get the right answer.

No fastmath here: the error-free transformations below rely on IEEE-754
round-to-nearest with no reassociation and no fused multiply-add contraction.
Inputs are assumed free of overflow and underflow (coordinates of magnitude
between about 1e-90 and 1e90, or zero).
"""
import numpy as np

from .jit import njit_allocating, njit_borrowing

_EPS = 2.0 ** -53  # half an ulp of 1.0
_SPLITTER = 134217729.0  # 2**27 + 1, splits a double into two 26-bit halves
_ORIENT2D_BOUND = (3.0 + 16.0 * _EPS) * _EPS
_ORIENT3D_BOUND = (7.0 + 56.0 * _EPS) * _EPS


# --- error-free transformations ---------------------------------------------

@njit_borrowing
def _two_sum(a, b):
    """a + b = x + y exactly, with x = fl(a + b)."""
    x = a + b
    b_virtual = x - a
    a_virtual = x - b_virtual
    return x, (a - a_virtual) + (b - b_virtual)


@njit_borrowing
def _split(a):
    c = _SPLITTER * a
    high = c - (c - a)
    return high, a - high


@njit_borrowing
def _two_product(a, b):
    """a * b = x + y exactly, with x = fl(a * b) (Dekker)."""
    x = a * b
    a_hi, a_lo = _split(a)
    b_hi, b_lo = _split(b)
    err = x - a_hi * b_hi
    err = err - a_lo * b_hi
    err = err - a_hi * b_lo
    return x, a_lo * b_lo - err


@njit_allocating
def _grow_expansion(e, n, b, out):
    """out[:m] = e[:n] + b exactly; zero components dropped. Returns m.

    ``e`` is a non-overlapping expansion in increasing magnitude; so is ``out``.
    """
    q = b
    m = 0
    for i in range(n):
        q, h = _two_sum(q, e[i])
        if h != 0.0:
            out[m] = h
            m += 1
    if q != 0.0 or m == 0:
        out[m] = q
        m += 1
    return m


@njit_allocating
def _expansion_sign(terms):
    """Exact sign of the sum of the doubles in ``terms`` (1-D float64)."""
    n_terms = terms.shape[0]
    a = np.zeros(n_terms + 1)
    b = np.zeros(n_terms + 1)
    n = np.int64(1)  # np.int64: no separate compile for the literal first call
    for k in range(n_terms):
        n = _grow_expansion(a, n, terms[k], b)
        a, b = b, a
    top = a[n - 1]
    return 1 if top > 0.0 else (-1 if top < 0.0 else 0)


# --- orient2d ------------------------------------------------------------------

@njit_allocating
def _orient2d_exact(ax, ay, bx, by, cx, cy):
    terms = np.empty(12)
    pairs = ((ax, by, 1.0), (ay, bx, -1.0), (ax, cy, -1.0),
             (ay, cx, 1.0), (bx, cy, 1.0), (by, cx, -1.0))
    for k in range(6):
        u, v, sign = pairs[k]
        x, y = _two_product(u, v)
        terms[2 * k] = sign * x
        terms[2 * k + 1] = sign * y
    return _expansion_sign(terms)


#: the short exact expansions multiply differences: those of this size or zero cannot underflow
_TINY = 2.0 ** -300


@njit_borrowing
def _exact_difference(a, b, x):
    """x = fl(a - b) is exactly a - b (Shewchuk's Two-Diff tail is zero) and is zero or at
    least _TINY in magnitude, so that products of three such differences and their
    rounding errors stay clear of underflow."""
    b_virtual = a - x
    a_virtual = x + b_virtual
    return (a - a_virtual) + (b_virtual - b) == 0.0 and (x == 0.0 or abs(x) >= _TINY)


@njit_allocating
def _orient2d_exact_diffs(acx, acy, bcx, bcy):
    """Exact sign of acx * bcy - acy * bcx for float64 inputs (4 exact terms)."""
    terms = np.empty(4)
    terms[0], terms[1] = _two_product(acx, bcy)
    x, y = _two_product(acy, bcx)
    terms[2] = -x
    terms[3] = -y
    return _expansion_sign(terms)


@njit_borrowing
def orient2d(ax, ay, bx, by, cx, cy):
    """Exact sign of det[[ax-cx, ay-cy], [bx-cx, by-cy]].

    +1 when a, b, c turn counter-clockwise, -1 clockwise, 0 when collinear. The
    filter is small enough to be inlined; the rare undecided case is a separate call.
    """
    acx = ax - cx
    acy = ay - cy
    bcx = bx - cx
    bcy = by - cy
    left = acx * bcy
    right = acy * bcx
    det = left - right
    bound = _ORIENT2D_BOUND * (abs(left) + abs(right))
    if det > bound:
        return 1
    if -det > bound:
        return -1
    return _orient2d_undecided(ax, ay, bx, by, cx, cy)


@njit_borrowing
def _orient2d_undecided(ax, ay, bx, by, cx, cy):
    """orient2d where the floating-point filter could not decide: exact."""
    if ((ax == cx and ay == cy) or (bx == cx and by == cy)
            or (ax == cx and bx == cx) or (ay == cy and by == cy)):
        # a row or column of the matrix is exactly zero, and so is the determinant
        # (a == c, b == c, or the points on one axis-parallel line), told by comparing
        # coordinates, with no rounding
        return 0
    acx = ax - cx
    acy = ay - cy
    bcx = bx - cx
    bcy = by - cy
    if (_exact_difference(ax, cx, acx) and _exact_difference(ay, cy, acy) and _exact_difference(bx, cx, bcx)
            and _exact_difference(by, cy, bcy)):
        if acx * bcy == 0.0 and acy * bcx == 0.0:
            return 0  # both exact products are zero (they cannot underflow: _exact_difference)
        return _orient2d_exact_diffs(acx, acy, bcx, bcy)  # the differences are exact: a short expansion
    return _orient2d_exact(ax, ay, bx, by, cx, cy)


# --- orient3d ------------------------------------------------------------------

@njit_borrowing
def _det3_terms(p, q, r, sign, terms, k):
    """Append the 6 triple products of sign*det[p; q; r] (as 4 doubles each)."""
    triples = ((p[0], q[1], r[2], 1.0), (p[0], q[2], r[1], -1.0),
               (p[1], q[0], r[2], -1.0), (p[1], q[2], r[0], 1.0),
               (p[2], q[0], r[1], 1.0), (p[2], q[1], r[0], -1.0))
    for i in range(6):
        u, v, w, s = triples[i]
        s = s * sign
        x, y = _two_product(u, v)
        x1, x0 = _two_product(x, w)
        y1, y0 = _two_product(y, w)
        terms[k] = s * x1
        terms[k + 1] = s * x0
        terms[k + 2] = s * y1
        terms[k + 3] = s * y0
        k += 4
    return k


@njit_allocating
def _orient3d_exact(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz):
    # Scalar arguments on purpose: passing array views into a call that the
    # fast path does not inline costs reference counting on every call.
    # det[a-d; b-d; c-d] = det[a;b;c] - det[a;b;d] + det[a;c;d] - det[b;c;d]
    a = np.array((ax, ay, az))
    b = np.array((bx, by, bz))
    c = np.array((cx, cy, cz))
    d = np.array((dx, dy, dz))
    terms = np.empty(96)
    k = _det3_terms(a, b, c, 1.0, terms, np.int64(0))
    k = _det3_terms(a, b, d, -1.0, terms, k)
    k = _det3_terms(a, c, d, 1.0, terms, k)
    _det3_terms(b, c, d, -1.0, terms, k)
    return _expansion_sign(terms)


@njit_borrowing
def orient3d(a, b, c, d):
    """Exact sign of det[a-d; b-d; c-d] for points a, b, c, d (3,) float64.

    Zero when the four points are coplanar; the sign tells on which side of the
    plane through a, b, c the point d lies.
    """
    return orient3d_xyz(a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2], d[0], d[1], d[2])


@njit_borrowing
def _differences(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz):
    """The rows of [a-d; b-d; c-d] as a 9-tuple (rounded differences)."""
    return ax - dx, ay - dy, az - dz, bx - dx, by - dy, bz - dz, cx - dx, cy - dy, cz - dz


@njit_borrowing
def orient3d_xyz(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz):
    """orient3d of the points (ax, ay, az), ..., (dx, dy, dz), given as 12 float64.

    Scalars on purpose: this filter is small enough to be inlined into its callers,
    and scalar arguments cost no reference counting when it is not; the rare
    undecided case is a separate call (_orient3d_undecided).
    """
    adx, ady, adz, bdx, bdy, bdz, cdx, cdy, cdz = _differences(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz)
    m1 = bdy * cdz
    m2 = bdz * cdy
    m3 = cdy * adz
    m4 = cdz * ady
    m5 = ady * bdz
    m6 = adz * bdy
    det = adx * (m1 - m2) + bdx * (m3 - m4) + cdx * (m5 - m6)
    permanent = ((abs(m1) + abs(m2)) * abs(adx) + (abs(m3) + abs(m4)) * abs(bdx)
                 + (abs(m5) + abs(m6)) * abs(cdx))
    bound = _ORIENT3D_BOUND * permanent
    if det > bound:
        return 1
    if -det > bound:
        return -1
    return _orient3d_undecided(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz)


@njit_borrowing
def _orient3d_undecided(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz):
    """orient3d where the floating-point filter could not decide: exact."""
    if (ax == dx and bx == dx and cx == dx) or (ay == dy and by == dy and cy == dy) or (
            az == dz and bz == dz and cz == dz):
        # a column of [a-d; b-d; c-d] is exactly zero, and so is the determinant: the
        # points lie in one axis-parallel plane (a floor at z = 0, faces of boxes that
        # are not turned), told by comparing coordinates, with no rounding
        return 0
    adx, ady, adz, bdx, bdy, bdz, cdx, cdy, cdz = _differences(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz)
    if (_exact_difference(ax, dx, adx) and _exact_difference(ay, dy, ady) and _exact_difference(az, dz, adz)
            and _exact_difference(bx, dx, bdx) and _exact_difference(by, dy, bdy)
            and _exact_difference(bz, dz, bdz) and _exact_difference(cx, dx, cdx)
            and _exact_difference(cy, dy, cdy) and _exact_difference(cz, dz, cdz)):
        # the differences are exact (Shewchuk's stage B case, common for coplanar grids):
        # the determinant of the differences themselves, 24 exact terms instead of 96.
        # Their products cannot underflow (_exact_difference), so a zero permanent means
        # every term is exactly zero.
        permanent = ((abs(bdy * cdz) + abs(bdz * cdy)) * abs(adx) + (abs(cdy * adz) + abs(cdz * ady)) * abs(bdx)
                     + (abs(ady * bdz) + abs(adz * bdy)) * abs(cdx))
        if permanent == 0.0:
            return 0
        return _orient3d_exact_diffs(adx, ady, adz, bdx, bdy, bdz, cdx, cdy, cdz)
    return _orient3d_exact(ax, ay, az, bx, by, bz, cx, cy, cz, dx, dy, dz)


@njit_allocating
def _orient3d_exact_diffs(adx, ady, adz, bdx, bdy, bdz, cdx, cdy, cdz):
    """Exact sign of det[[adx, ady, adz], [bdx, bdy, bdz], [cdx, cdy, cdz]] (float64 entries)."""
    terms = np.empty(24)
    _det3_terms(np.array((adx, ady, adz)), np.array((bdx, bdy, bdz)), np.array((cdx, cdy, cdz)), 1.0, terms,
                    np.int64(0))
    return _expansion_sign(terms)


# --- closed segments and triangles -------------------------------------------
# Helpers take whole (3, 3) triangle arrays plus row indices, or scalars, never
# array views: views handed to calls cost reference counting in the hot path.

@njit_borrowing
def _segments_intersect_2d(px, py, qx, qy, rx, ry, sx, sy):
    """Closed 2-D segments pq and rs share a point."""
    o1 = orient2d(px, py, qx, qy, rx, ry)
    o2 = orient2d(px, py, qx, qy, sx, sy)
    o3 = orient2d(rx, ry, sx, sy, px, py)
    o4 = orient2d(rx, ry, sx, sy, qx, qy)
    return _segments_meet(o1, o2, o3, o4, px, py, qx, qy, rx, ry, sx, sy)


@njit_borrowing
def _segments_meet(o1, o2, o3, o4, px, py, qx, qy, rx, ry, sx, sy):
    """Closed 2-D segments pq and rs share a point, given the exact sides o1, o2 of r, s
    against line pq and o3, o4 of p, q against line rs."""
    if o1 == 0 and o2 == 0 and o3 == 0 and o4 == 0:
        # collinear: they meet iff their bounding boxes overlap on both axes
        return (max(px, qx) >= min(rx, sx) and max(rx, sx) >= min(px, qx)
                and max(py, qy) >= min(ry, sy) and max(ry, sy) >= min(py, qy))
    return o1 * o2 <= 0 and o3 * o4 <= 0


@njit_borrowing
def _point_in_triangle_2d(px, py, ax, ay, bx, by, cx, cy):
    """2-D point p lies in the closed, non-degenerate triangle abc."""
    s0 = orient2d(ax, ay, bx, by, px, py)
    s1 = orient2d(bx, by, cx, cy, px, py)
    s2 = orient2d(cx, cy, ax, ay, px, py)
    return (s0 >= 0 and s1 >= 0 and s2 >= 0) or (s0 <= 0 and s1 <= 0 and s2 <= 0)


@njit_borrowing
def _segment_meets_triangle_2d(s, i, j, t, x, y):
    """Closed segment s[i] s[j] meets closed triangle t, projected on axes (x, y)."""
    ax, ay, bx, by = s[i, x], s[i, y], s[j, x], s[j, y]
    q0x, q0y, q1x, q1y, q2x, q2y = t[0, x], t[0, y], t[1, x], t[1, y], t[2, x], t[2, y]
    if orient2d(q0x, q0y, q1x, q1y, q2x, q2y) != 0:
        if _point_in_triangle_2d(ax, ay, q0x, q0y, q1x, q1y, q2x, q2y):
            return True
        if _point_in_triangle_2d(bx, by, q0x, q0y, q1x, q1y, q2x, q2y):
            return True
    # a segment entering the triangle crosses its boundary; a degenerate
    # (flat) triangle is the union of its three edges
    return (_segments_intersect_2d(ax, ay, bx, by, q0x, q0y, q1x, q1y)
            or _segments_intersect_2d(ax, ay, bx, by, q1x, q1y, q2x, q2y)
            or _segments_intersect_2d(ax, ay, bx, by, q2x, q2y, q0x, q0y))


@njit_borrowing
def _coplanar_segment_meets_triangle(s, i, j, t):
    """Closed segment s[i] s[j] meets closed triangle t, all five points coplanar.

    The projection along the dominant axis of their common plane's normal is
    one-to-one on the plane, and every projection keeps an intersection, so
    they meet iff they meet in all three axis projections (this also covers
    collinear and degenerate configurations, where the plane is not unique).
    """
    # np.int64 indices: one compiled version, not one per literal
    return (_segment_meets_triangle_2d(s, i, j, t, np.int64(0), np.int64(1))
            and _segment_meets_triangle_2d(s, i, j, t, np.int64(1), np.int64(2))
            and _segment_meets_triangle_2d(s, i, j, t, np.int64(2), np.int64(0)))


@njit_borrowing
def _one_to_one_projection(t):
    """Axes (x, y) on which triangle t (3, 3) has non-zero area (exact), the first of
    (0, 1), (1, 2), (2, 0); (-1, -1) when t has zero area on all three (is degenerate)."""
    for x, y in ((0, 1), (1, 2), (2, 0)):
        if orient2d(t[0, x], t[0, y], t[1, x], t[1, y], t[2, x], t[2, y]) != 0:
            return np.int64(x), np.int64(y)
    return np.int64(-1), np.int64(-1)


@njit_borrowing
def _side(t, s, m):
    """orient3d(t[0], t[1], t[2], s[m]) for triangles t and s (3, 3): the side of t's plane
    that point m of s is on."""
    return orient3d_xyz(t[0, 0], t[0, 1], t[0, 2], t[1, 0], t[1, 1], t[1, 2], t[2, 0], t[2, 1], t[2, 2],
                        s[m, 0], s[m, 1], s[m, 2])


@njit_borrowing
def _edge_side(s, i, j, t, k, m):
    """orient3d(s[i], s[j], t[k], t[m]) for triangles s and t (3, 3)."""
    return orient3d_xyz(s[i, 0], s[i, 1], s[i, 2], s[j, 0], s[j, 1], s[j, 2], t[k, 0], t[k, 1], t[k, 2],
                        t[m, 0], t[m, 1], t[m, 2])


@njit_borrowing
def segment_meets_triangle(s, i, j, t, side_i, side_j):
    """Closed segment s[i] s[j] and closed triangle t (3, 3) share a point (exact).

    ``side_i`` and ``side_j`` are ``orient3d(t[0], t[1], t[2], s[i])`` and the
    same for s[j], passed in because callers already have them.
    """
    if side_i * side_j > 0:
        return False
    if side_i == 0 and side_j == 0:
        x, y = _one_to_one_projection(t)
        if x >= 0:
            # t spans a plane holding s[i] and s[j]; projecting along an axis the plane is not
            # parallel to maps it one-to-one onto the (x, y) plane, so they meet there iff
            # they meet in space
            return _segment_meets_triangle_2d(s, i, j, t, x, y)
        # the "triangle" is a segment or a point: the two can only meet
        # if they are coplanar
        i0, i1, i2 = np.int64(0), np.int64(1), np.int64(2)
        if (_edge_side(s, i, j, t, i0, i1) != 0 or _edge_side(s, i, j, t, i1, i2) != 0
                or _edge_side(s, i, j, t, i0, i2) != 0):
            return False
        return _coplanar_segment_meets_triangle(s, i, j, t)
    # the segment crosses the (non-degenerate) triangle's plane at one point;
    # that point is in the closed triangle iff the line ab passes on the same
    # side of all three edges (or on one of them)
    i0, i1, i2 = np.int64(0), np.int64(1), np.int64(2)
    s0 = _edge_side(s, i, j, t, i0, i1)
    s1 = _edge_side(s, i, j, t, i1, i2)
    s2 = _edge_side(s, i, j, t, i2, i0)
    return (s0 >= 0 and s1 >= 0 and s2 >= 0) or (s0 <= 0 and s1 <= 0 and s2 <= 0)


@njit_borrowing
def _vertex_sides_2d(p, q, x, y):
    """Exact sides of q's vertices of p's edges on axes (x, y): a 9-tuple whose entry
    3 * e + k is orient2d(p[e], p[e + 1], q[k]) (edges e = 0, 1, 2; p[3] is p[0])."""
    return (orient2d(p[0, x], p[0, y], p[1, x], p[1, y], q[0, x], q[0, y]),
            orient2d(p[0, x], p[0, y], p[1, x], p[1, y], q[1, x], q[1, y]),
            orient2d(p[0, x], p[0, y], p[1, x], p[1, y], q[2, x], q[2, y]),
            orient2d(p[1, x], p[1, y], p[2, x], p[2, y], q[0, x], q[0, y]),
            orient2d(p[1, x], p[1, y], p[2, x], p[2, y], q[1, x], q[1, y]),
            orient2d(p[1, x], p[1, y], p[2, x], p[2, y], q[2, x], q[2, y]),
            orient2d(p[2, x], p[2, y], p[0, x], p[0, y], q[0, x], q[0, y]),
            orient2d(p[2, x], p[2, y], p[0, x], p[0, y], q[1, x], q[1, y]),
            orient2d(p[2, x], p[2, y], p[0, x], p[0, y], q[2, x], q[2, y]))


@njit_borrowing
def _inside(sides, k):
    """Vertex k is in the closed triangle (of non-zero area) whose edge sides are ``sides``
    (_vertex_sides_2d): on one side of, or on, all three edges."""
    s0, s1, s2 = sides[k], sides[3 + k], sides[6 + k]
    return (s0 >= 0 and s1 >= 0 and s2 >= 0) or (s0 <= 0 and s1 <= 0 and s2 <= 0)


@njit_borrowing
def _coplanar_triangles_meet(p, q, x, y):
    """Closed triangles p and q (3, 3) in one plane share a point (exact); q has non-zero
    area on axes (x, y), so projecting along the third axis maps the plane one-to-one
    and they meet iff their projections do.

    Two convex polygons meet iff a vertex of one lies in the other or an edge of one
    crosses an edge of the other. The 18 vertex-edge sides decide all of it (orient2d
    is exact, so permuted arguments give consistent signs); a zero-area p is the union
    of its edges, covered by the edge tests.
    """
    sides_p = _vertex_sides_2d(p, q, x, y)  # q's vertices against p's edges
    sides_q = _vertex_sides_2d(q, p, x, y)  # p's vertices against q's edges
    for m in range(3):
        if _inside(sides_q, m):
            return True
    if orient2d(p[0, x], p[0, y], p[1, x], p[1, y], p[2, x], p[2, y]) != 0:
        for k in range(3):
            if _inside(sides_p, k):
                return True
    for e in range(3):
        i, j = e, (e + 1) % 3
        for f in range(3):
            k, m = f, (f + 1) % 3
            if _segments_meet(sides_p[3 * e + k], sides_p[3 * e + m], sides_q[3 * f + i], sides_q[3 * f + j],
                              p[i, x], p[i, y], p[j, x], p[j, y], q[k, x], q[k, y], q[m, x], q[m, y]):
                return True
    return False


@njit_borrowing
def triangles_intersect(p, q):
    """Closed triangles p and q, (3,3) float64 rows = vertices, share a point.

    Exact for any float64 input, including touching, coplanar and zero-area
    triangles. Two triangles meet iff an edge of one meets the other
    (the ends of their intersection lie on edges), so after a quick
    both-on-one-side rejection the six edge-triangle tests decide; two triangles in
    one plane take a single 2-D test instead (_coplanar_triangles_meet).
    """
    i0, i1, i2 = np.int64(0), np.int64(1), np.int64(2)  # one compiled version, not one per literal
    side_q0 = _side(p, q, i0)
    side_q1 = _side(p, q, i1)
    side_q2 = _side(p, q, i2)
    if side_q0 * side_q1 > 0 and side_q0 * side_q2 > 0:
        return False
    side_p0 = _side(q, p, i0)
    side_p1 = _side(q, p, i1)
    side_p2 = _side(q, p, i2)
    if side_p0 * side_p1 > 0 and side_p0 * side_p2 > 0:
        return False
    if side_q0 == 0 and side_q1 == 0 and side_q2 == 0 and side_p0 == 0 and side_p1 == 0 and side_p2 == 0:
        # one plane holds both (or both have zero area): one 2-D test on a projection
        # that is one-to-one on the plane of a triangle of non-zero area
        x, y = _one_to_one_projection(q)
        if x >= 0:
            return _coplanar_triangles_meet(p, q, x, y)
        x, y = _one_to_one_projection(p)
        if x >= 0:
            return _coplanar_triangles_meet(q, p, x, y)
    return (segment_meets_triangle(p, i0, i1, q, side_p0, side_p1)
            or segment_meets_triangle(p, i1, i2, q, side_p1, side_p2)
            or segment_meets_triangle(p, i2, i0, q, side_p2, side_p0)
            or segment_meets_triangle(q, i0, i1, p, side_q0, side_q1)
            or segment_meets_triangle(q, i1, i2, p, side_q1, side_q2)
            or segment_meets_triangle(q, i2, i0, p, side_q2, side_q0))
