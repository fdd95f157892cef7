"""Narrow phase: exact tests between the triangles of two overlapping leaves.

Triangles are read from a world-space vertex buffer ``world`` float64 (W, 3)
holding every object's vertices at the current pose; object o's vertex v is
row ``world_start[o] + v``. Faces are mesh-local vertex indices.
"""
import numpy as np
from numba import njit

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
    """Append ``row`` to the int64 (cap, w) buffer holding n rows; grows by doubling."""
    if n == buf.shape[0]:
        grown = np.empty((max(2 * n, 16), buf.shape[1]), np.int64)
        grown[:n] = buf[:n]
        buf = grown
    for c in range(buf.shape[1]):
        buf[n, c] = row[c]
    return buf, n + 1


@njit(cache=True)
def intersecting_triangles(leaves, n_leaves, first, count, prim_ids, faces,
                           face_base_a, face_base_b, world, world_base_a, world_base_b,
                           out, n_out):
    """Append every intersecting triangle pair (tri_a, tri_b) of the leaf pairs.

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
    return out, n_out
