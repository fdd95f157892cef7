"""Narrow phase: exact tests between the triangles of two overlapping leaves.

Triangles are read from a world-space vertex buffer ``world`` float64 (W, 3)
holding every object's vertices at the current pose; object o's vertex v is
row ``world_start[o] + v``. Faces are mesh-local vertex indices.
"""
import numpy as np
from numba import njit

from .ccd import EDGE_EDGE, VERTEX_FACE, toi_before
from .predicates import triangles_intersect


@njit(cache=True, inline="always")
def gather_triangle(world, world_base, faces, face, out):
    """out (3, 3) = world coordinates of the triangle with global face row ``face``."""
    for r in range(3):
        row = world_base + faces[face, r]
        for c in range(3):
            out[r, c] = world[row, c]


@njit(cache=True, inline="always")
def _triangle_boxes_overlap(p, q):
    """Exact AABB test of two triangles (min/max of the same floats)."""
    for c in range(3):
        if max(p[0, c], p[1, c], p[2, c]) < min(q[0, c], q[1, c], q[2, c]):
            return False
        if max(q[0, c], q[1, c], q[2, c]) < min(p[0, c], p[1, c], p[2, c]):
            return False
    return True


@njit(cache=True)
def append_row(buf, n, row):
    """Append ``row`` to the (cap, w) buffer holding n rows; grows by doubling."""
    if n == buf.shape[0]:
        grown = np.empty((max(2 * n, 16), buf.shape[1]), buf.dtype)
        grown[:n] = buf[:n]
        buf = grown
    for c in range(buf.shape[1]):
        buf[n, c] = row[c]
    return buf, n + 1


@njit(cache=True)
def intersecting_triangles(leaves, n_leaves, first, count, prim_ids, faces,
                           face_base_a, face_base_b, world, world_base_a, world_base_b,
                           out, n_out, first_only):
    """Append every intersecting triangle pair (tri_a, tri_b) of the leaf pairs
    (only the first one found when ``first_only``).

    leaves int64 (>= n_leaves, 2): (leaf of A, leaf of B) node indices.
    prim_ids hold mesh-local face indices; face_base_* turn them into rows of
    ``faces``. Returns (out, n_out) with out int64 (cap, 2) of mesh-local
    triangle indices.
    """
    p = np.empty((3, 3))
    q = np.empty((3, 3))
    row = np.empty(2, np.int64)
    for k in range(n_leaves):
        la = leaves[k, 0]
        lb = leaves[k, 1]
        for ia in range(first[la], first[la] + count[la]):
            tri_a = prim_ids[ia]
            gather_triangle(world, world_base_a, faces, face_base_a + tri_a, p)
            for ib in range(first[lb], first[lb] + count[lb]):
                tri_b = prim_ids[ib]
                gather_triangle(world, world_base_b, faces, face_base_b + tri_b, q)
                if _triangle_boxes_overlap(p, q) and triangles_intersect(p, q):
                    row[0] = tri_a
                    row[1] = tri_b
                    out, n_out = append_row(out, n_out, row)
                    if first_only:
                        return out, n_out
    return out, n_out


# --- continuous (swept) tests -------------------------------------------------------------

@njit(cache=True, inline="always")
def _swept_triangle_boxes_overlap(p0, p1, q0, q1, margin):
    """Boxes of the 6 positions of each triangle (both ends of the motion) overlap.

    Valid for linear vertex motion: a moving triangle stays in the convex hull
    of its vertices' start and end positions.
    """
    for c in range(3):
        p_lo = min(p0[0, c], p0[1, c], p0[2, c], p1[0, c], p1[1, c], p1[2, c])
        p_hi = max(p0[0, c], p0[1, c], p0[2, c], p1[0, c], p1[1, c], p1[2, c])
        q_lo = min(q0[0, c], q0[1, c], q0[2, c], q1[0, c], q1[1, c], q1[2, c])
        q_hi = max(q0[0, c], q0[1, c], q0[2, c], q1[0, c], q1[1, c], q1[2, c])
        if p_hi + margin < q_lo or q_hi + margin < p_lo:
            return False
    return True


@njit(cache=True)
def triangle_pair_toi(p0, p1, q0, q1, time_tol, dist_tol, x0, x1):
    """Earliest time in [0, 1] at which moving triangles p and q touch, inf if never.

    p0, p1, q0, q1: (3, 3) vertex positions at t = 0 and t = 1 (linear motion).
    The first contact of two disjoint triangles is a vertex touching a face or
    an edge touching an edge: the minimum over the 6 vertex-face and 9
    edge-edge certified CCD queries (conservative: never later than the true
    time, at most time_tol earlier); each query only searches up to the best
    time found so far. Triangles already intersecting at t = 0
    (decided exactly) give 0. x0, x1: (4, 3) scratch buffers.
    """
    if triangles_intersect(p0, q0):
        return 0.0
    best = np.inf
    for tri0, tri1, other0, other1 in ((p0, p1, q0, q1), (q0, q1, p0, p1)):
        for v in range(3):  # vertex of one triangle against the other's face
            for c in range(3):
                x0[0, c] = tri0[v, c]
                x1[0, c] = tri1[v, c]
                for r in range(3):
                    x0[r + 1, c] = other0[r, c]
                    x1[r + 1, c] = other1[r, c]
            best = min(best, toi_before(VERTEX_FACE, x0, x1, time_tol, dist_tol, best))
            if best == 0.0:
                return 0.0
    for i in range(3):  # edge i of p against edge j of q
        for j in range(3):
            for c in range(3):
                x0[0, c] = p0[i, c]
                x0[1, c] = p0[(i + 1) % 3, c]
                x0[2, c] = q0[j, c]
                x0[3, c] = q0[(j + 1) % 3, c]
                x1[0, c] = p1[i, c]
                x1[1, c] = p1[(i + 1) % 3, c]
                x1[2, c] = q1[j, c]
                x1[3, c] = q1[(j + 1) % 3, c]
            best = min(best, toi_before(EDGE_EDGE, x0, x1, time_tol, dist_tol, best))
            if best == 0.0:
                return 0.0
    return best


@njit(cache=True)
def swept_contact_hulls(leaves, n_leaves, first, count, prim_ids, faces, face_base_a, face_base_b,
                        world0, world1, world_base_a, world_base_b, time_tol, dist_tol, out, n_out):
    """Contact time hulls of every touching triangle pair of the leaf pairs over one motion step.

    Appends rows (t_first, t_last, tri_a, tri_b) (float64) to ``out`` (cap, 4):
    t_first is the earliest contact (conservative, see triangle_pair_toi) and
    t_last the latest one (the same test run backwards in time: 1 - toi of the
    reversed motion; 1 when the triangles intersect at t = 1). Stops early once a
    pair touches over the whole step (the union of the hulls is then [0, 1]).
    Returns (out, n_out).
    """
    p0 = np.empty((3, 3))
    p1 = np.empty((3, 3))
    q0 = np.empty((3, 3))
    q1 = np.empty((3, 3))
    x0 = np.empty((4, 3))
    x1 = np.empty((4, 3))
    row = np.empty(4)
    for k in range(n_leaves):
        la = leaves[k, 0]
        lb = leaves[k, 1]
        for ia in range(first[la], first[la] + count[la]):
            tri_a = prim_ids[ia]
            gather_triangle(world0, world_base_a, faces, face_base_a + tri_a, p0)
            gather_triangle(world1, world_base_a, faces, face_base_a + tri_a, p1)
            for ib in range(first[lb], first[lb] + count[lb]):
                tri_b = prim_ids[ib]
                gather_triangle(world0, world_base_b, faces, face_base_b + tri_b, q0)
                gather_triangle(world1, world_base_b, faces, face_base_b + tri_b, q1)
                if not _swept_triangle_boxes_overlap(p0, p1, q0, q1, dist_tol):
                    continue
                t_first = triangle_pair_toi(p0, p1, q0, q1, time_tol, dist_tol, x0, x1)
                if t_first == np.inf:
                    continue
                t_last = 1.0 - triangle_pair_toi(p1, p0, q1, q0, time_tol, dist_tol, x0, x1)
                row[0] = t_first
                row[1] = max(t_last, t_first)
                row[2] = tri_a
                row[3] = tri_b
                out, n_out = append_row(out, n_out, row)
                if t_first == 0.0 and t_last == 1.0:
                    # in contact for the whole step: no other pair can change the union
                    return out, n_out
    return out, n_out
