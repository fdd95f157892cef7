"""Bounding volume hierarchy over primitive boxes, stored as flat arrays.

The builder sees only one axis-aligned box and one centre per primitive, never
triangles, so static triangle boxes and swept boxes go through the same code.

Layout (``BVH``, m nodes, n primitives):

- ``lo``, ``hi``: float64 (m, 3), node box corners.
- ``first``, ``count``: int64 (m,). ``count > 0``: a leaf holding primitives
  ``prim_ids[first:first + count]``. ``count == 0``: an inner node whose
  children are nodes ``first`` and ``first + 1``. Node 0 is the root.
- ``prim_ids``: int64 (n,), primitive indices in leaf order.

Construction is top-down, as in the lecture: bound everything, split the
primitives into two groups, recurse (with an explicit stack), stop at leaves of
at most ``leaf_size`` primitives. The split rule is one of ``SPLIT_RULES``:

- ``sah``: binned surface area heuristic (bin the centres, accumulate bin
  boxes, sweep for the cheapest plane, partition); may stop early when a leaf
  is cheaper than any split.
- ``median``: the median centre along the longest axis of the centres' box.
- ``mean``: the mean centre along that axis.
"""
import time
from typing import NamedTuple

import numpy as np

from . import config
from .jit import njit

#: split rule name -> code used by the numba builder
SPLIT_RULES = {"sah": 0, "median": 1, "mean": 2}


class BVH(NamedTuple):
    lo: np.ndarray
    hi: np.ndarray
    first: np.ndarray
    count: np.ndarray
    prim_ids: np.ndarray


# --- small box helpers ----------------------------------------------------------

@njit(cache=True)
def _half_area(lo, hi):
    dx = max(hi[0] - lo[0], 0.0)
    dy = max(hi[1] - lo[1], 0.0)
    dz = max(hi[2] - lo[2], 0.0)
    return dx * dy + dy * dz + dz * dx


@njit(cache=True)
def _range_bounds(ids, start, stop, box_lo, box_hi, centre):
    """Box of the primitives ids[start:stop] and box of their centres."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    c_lo = np.full(3, np.inf)
    c_hi = np.full(3, -np.inf)
    for k in range(start, stop):
        p = ids[k]
        for a in range(3):
            lo[a] = min(lo[a], box_lo[p, a])
            hi[a] = max(hi[a], box_hi[p, a])
            c_lo[a] = min(c_lo[a], centre[p, a])
            c_hi[a] = max(c_hi[a], centre[p, a])
    return lo, hi, c_lo, c_hi


@njit(cache=True)
def _longest_axis(lo, hi):
    ext = hi - lo
    axis = 0
    if ext[1] > ext[axis]:
        axis = 1
    if ext[2] > ext[axis]:
        axis = 2
    return axis


# --- partitions ---------------------------------------------------------------------

@njit(cache=True)
def _partition(ids, start, stop, centre, axis, position):
    """Move ids with centre[axis] < position to the front; return the split index."""
    mid = start
    for k in range(start, stop):
        if centre[ids[k], axis] < position:
            ids[k], ids[mid] = ids[mid], ids[k]
            mid += 1
    return mid


@njit(cache=True)
def _split_in_halves(ids, start, stop, centre, axis):
    """Sort ids[start:stop] by centre[axis] (ties by id) and split in the middle."""
    chunk = ids[start:stop].copy()
    keys = centre[chunk, axis]
    order = np.argsort(keys, kind="mergesort")
    for k in range(chunk.shape[0]):
        ids[start + k] = chunk[order[k]]
    return start + (stop - start) // 2


# --- split rules (one small function each) ------------------------------------------

@njit(cache=True)
def _split_median(ids, start, stop, centre, c_lo, c_hi):
    return _split_in_halves(ids, start, stop, centre, _longest_axis(c_lo, c_hi))


@njit(cache=True)
def _split_mean(ids, start, stop, centre, c_lo, c_hi):
    axis = _longest_axis(c_lo, c_hi)
    total = 0.0
    for k in range(start, stop):
        total += centre[ids[k], axis]
    mid = _partition(ids, start, stop, centre, axis, total / (stop - start))
    if mid == start or mid == stop:  # all centres on one side of the mean
        mid = _split_in_halves(ids, start, stop, centre, axis)
    return mid


@njit(cache=True)
def _sah_best_plane(ids, start, stop, box_lo, box_hi, centre, c_lo, c_hi, n_bins):
    """Binned SAH: returns (cost, axis, position) of the cheapest split plane.

    cost = half_area(left) * n_left + half_area(right) * n_right (unnormalised);
    inf when every centre falls in one bin on every axis.
    """
    best_cost = np.inf
    best_axis = -1
    best_pos = 0.0
    for axis in range(3):
        extent = c_hi[axis] - c_lo[axis]
        if not extent > 0.0:
            continue
        # 1. bin the centres, 2. accumulate each bin's box and count
        bin_lo = np.full((n_bins, 3), np.inf)
        bin_hi = np.full((n_bins, 3), -np.inf)
        bin_n = np.zeros(n_bins, np.int64)
        scale = n_bins / extent
        for k in range(start, stop):
            p = ids[k]
            b = min(int((centre[p, axis] - c_lo[axis]) * scale), n_bins - 1)
            bin_n[b] += 1
            for a in range(3):
                bin_lo[b, a] = min(bin_lo[b, a], box_lo[p, a])
                bin_hi[b, a] = max(bin_hi[b, a], box_hi[p, a])
        # 3. sweep from the right to get suffix areas, then from the left
        right_area = np.zeros(n_bins)
        right_n = np.zeros(n_bins, np.int64)
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        n = 0
        for b in range(n_bins - 1, 0, -1):
            lo = np.minimum(lo, bin_lo[b])
            hi = np.maximum(hi, bin_hi[b])
            n += bin_n[b]
            right_area[b] = _half_area(lo, hi)
            right_n[b] = n
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        n = 0
        for b in range(n_bins - 1):
            lo = np.minimum(lo, bin_lo[b])
            hi = np.maximum(hi, bin_hi[b])
            n += bin_n[b]
            if n == 0 or right_n[b + 1] == 0:
                continue
            cost = _half_area(lo, hi) * n + right_area[b + 1] * right_n[b + 1]
            if cost < best_cost:
                best_cost = cost
                best_axis = axis
                best_pos = c_lo[axis] + (b + 1) / scale
    return best_cost, best_axis, best_pos


@njit(cache=True)
def _split_sah(ids, start, stop, box_lo, box_hi, centre, lo, hi, c_lo, c_hi,
               leaf_size, n_bins, traversal_cost):
    """Split index, or -1 to make a leaf (only allowed when count <= leaf_size)."""
    count = stop - start
    cost, axis, position = _sah_best_plane(ids, start, stop, box_lo, box_hi, centre,
                                           c_lo, c_hi, n_bins)
    area = _half_area(lo, hi)
    if count <= leaf_size and (axis < 0 or area <= 0.0
                               or traversal_cost + cost / area >= count):
        return -1
    if axis < 0:  # all centres coincide: any balanced split is as good
        return _split_in_halves(ids, start, stop, centre, _longest_axis(lo, hi))
    mid = _partition(ids, start, stop, centre, axis, position)
    if mid == start or mid == stop:
        mid = _split_in_halves(ids, start, stop, centre, axis)
    return mid


# --- the builder ---------------------------------------------------------------------

@njit(cache=True)
def _build(box_lo, box_hi, centre, rule, leaf_size, n_bins, traversal_cost):
    n = box_lo.shape[0]
    max_nodes = max(2 * n - 1, 1)
    node_lo = np.empty((max_nodes, 3))
    node_hi = np.empty((max_nodes, 3))
    first = np.zeros(max_nodes, np.int64)
    count = np.zeros(max_nodes, np.int64)
    ids = np.arange(n)
    # stack of (node, start, stop) still to be processed
    stack = np.empty((max_nodes, 3), np.int64)
    stack[0] = (0, 0, n)
    top = 1
    n_nodes = 1
    while top > 0:
        top -= 1
        node, start, stop = stack[top, 0], stack[top, 1], stack[top, 2]
        lo, hi, c_lo, c_hi = _range_bounds(ids, start, stop, box_lo, box_hi, centre)
        node_lo[node] = lo
        node_hi[node] = hi
        mid = -1
        if stop - start > 1:
            if rule == 0:
                mid = _split_sah(ids, start, stop, box_lo, box_hi, centre, lo, hi,
                                 c_lo, c_hi, leaf_size, n_bins, traversal_cost)
            elif stop - start > leaf_size:
                if rule == 1:
                    mid = _split_median(ids, start, stop, centre, c_lo, c_hi)
                else:
                    mid = _split_mean(ids, start, stop, centre, c_lo, c_hi)
        if mid < 0:
            first[node] = start
            count[node] = stop - start
            continue
        left = n_nodes
        n_nodes += 2
        first[node] = left
        count[node] = 0
        stack[top] = (left + 1, mid, stop)
        stack[top + 1] = (left, start, mid)
        top += 2
    return (node_lo[:n_nodes].copy(), node_hi[:n_nodes].copy(),
            first[:n_nodes].copy(), count[:n_nodes].copy(), ids)


def build_bvh(box_lo, box_hi, centre, split="sah", leaf_size=None):
    """Build a BVH over n primitives.

    Parameters
    ----------
    box_lo, box_hi : float64 (n, 3)
        Primitive box corners (any length unit).
    centre : float64 (n, 3)
        A representative point per primitive (e.g. the triangle centroid).
    split : {"sah", "median", "mean"}
    leaf_size : int, optional
        Maximum primitives per leaf (default ``config.DEFAULT_LEAF_SIZE``).
    """
    if split not in SPLIT_RULES:
        raise ValueError(f"unknown split rule {split!r}; expected one of {sorted(SPLIT_RULES)}")
    leaf_size = config.DEFAULT_LEAF_SIZE if leaf_size is None else int(leaf_size)
    if leaf_size < 1:
        raise ValueError(f"leaf_size must be >= 1, got {leaf_size}")
    box_lo, box_hi, centre = (np.ascontiguousarray(a, dtype=np.float64)
                              for a in (box_lo, box_hi, centre))
    if box_lo.shape[0] == 0:
        raise ValueError("cannot build a BVH over zero primitives")
    return BVH(*_build(box_lo, box_hi, centre, SPLIT_RULES[split], leaf_size,
                       config.SAH_BINS, config.SAH_TRAVERSAL_COST))


def triangle_boxes(vertices, faces):
    """Per-triangle boxes and centroids.

    vertices float64 (V, 3), faces int64 (F, 3) -> (lo, hi, centroid), each (F, 3).
    Corner by corner: the values of ``vertices[faces].min(axis=1)``, ``.max(axis=1)``
    and ``.mean(axis=1)`` (the centroid is (a + b + c) / 3 in that order, as numpy's mean
    sums over a short axis), several times faster than reducing the (F, 3, 3) array.
    """
    columns = np.ascontiguousarray(np.asarray(faces).T)
    a, b, c = (np.asarray(vertices).take(columns[k], axis=0) for k in range(3))
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    np.minimum(lo, c, out=lo)
    np.maximum(hi, c, out=hi)
    centre = np.add(a, b, dtype=np.float64)
    centre += c
    centre /= 3
    return lo, hi, centre


def build_mesh_bvh(vertices, faces, split="sah", leaf_size=None):
    """BVH over a mesh's triangles in its body frame."""
    return build_bvh(*triangle_boxes(vertices, faces), split=split, leaf_size=leaf_size)


# --- statistics (for `collide inspect`) ------------------------------------------------

@njit(cache=True)
def _depths(first, count):
    depth = np.zeros(first.shape[0], np.int64)
    for node in range(first.shape[0]):  # children always come after parents
        if count[node] == 0:
            depth[first[node]] = depth[node] + 1
            depth[first[node] + 1] = depth[node] + 1
    return depth


def bvh_stats(bvh, traversal_cost=config.SAH_TRAVERSAL_COST):
    """Node count, depth, leaf sizes and SAH cost (relative to the root's area)."""
    areas = np.array([_half_area(lo, hi) for lo, hi in zip(bvh.lo, bvh.hi)])
    root_area = areas[0] if areas[0] > 0 else 1.0
    leaves = bvh.count > 0
    leaf_sizes = bvh.count[leaves]
    sah = (traversal_cost * areas[~leaves].sum() + (areas[leaves] * leaf_sizes).sum()) / root_area
    return {
        "nodes": int(bvh.count.shape[0]),
        "leaves": int(leaves.sum()),
        "depth": int(_depths(bvh.first, bvh.count).max()),
        "leaf_size_min": int(leaf_sizes.min()),
        "leaf_size_mean": float(leaf_sizes.mean()),
        "leaf_size_max": int(leaf_sizes.max()),
        "sah_cost": float(sah),
    }


def timed_build(vertices, faces, split, leaf_size=None):
    """(bvh, seconds) for a mesh BVH build."""
    start = time.perf_counter()
    bvh = build_mesh_bvh(vertices, faces, split, leaf_size)
    return bvh, time.perf_counter() - start
