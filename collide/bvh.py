"""Bounding volume hierarchy over primitive boxes, stored as flat arrays.

The builder sees only one axis-aligned box and one centre per primitive, never
triangles, so static triangle boxes and swept boxes go through the same code.

Layout (``BVH``, m nodes, n primitives):

- ``lo``, ``hi``: float64 (m, 3), node box corners.
- ``first``, ``count``: int64 (m,). ``count > 0``: a leaf holding primitives
  ``prim_ids[first:first + count]``. ``count == 0``: an inner node whose
  children are nodes ``first`` and ``first + 1``. Node 0 is the root.
- ``prim_ids``: int64 (n,), primitive indices in leaf order.

Every builder leaves the tree in *smallest-id order*: the primitives of a leaf
ascend, and of two siblings the one holding the smaller primitive id comes first.
The smallest id under any node is then the first primitive of its leftmost leaf
(``smallest_id_under``), found in O(depth) without a pass over the tree: the search
for the smallest touching triangle pair of a contact needs it at every node it visits.

The rule (``split``) is one of ``SPLIT_RULES``. The first three build top-down, as in
the lecture: bound everything, split the primitives into two groups, recurse (with an
explicit stack), stop at leaves of at most ``leaf_size`` primitives:

- ``sah``: binned surface area heuristic (bin the centres, accumulate bin
  boxes, sweep for the cheapest plane, partition); may stop early when a leaf
  is cheaper than any split.
- ``median``: the median centre along the longest axis of the centres' box.
- ``mean``: the mean centre along that axis.

``lbvh`` builds bottom-up instead, in parallel (Karras 2012, "Maximizing parallelism
in the construction of BVHs, octrees, and k-d trees"): each centre gets a 63-bit
Morton code (21 bits per axis, in the centres' bounding cube), the primitives are
sorted by code (ties by index), and every inner node of the binary radix tree over
the sorted codes is found independently of the others (its range and split from the
codes alone). The tree is laid out as above (one primitive per leaf) and its boxes
refitted from the leaves up; then, bottom-up, every subtree of at most ``leaf_size``
primitives that is cheaper as a leaf (by the SAH cost that ``bvh_stats`` reports)
becomes one (Karras and Aila 2013). On large meshes it builds about ten times faster
than ``sah``; its trees have a higher SAH cost, so queries are slower
(``benchmarks/bench_bvh_build.py`` measures both).
"""
import time
from typing import NamedTuple

import numpy as np

from . import config
from .jit import njit, prange, thread_limit

#: split rule name (config.SPLIT_RULES) -> code used by the numba builder (``lbvh`` has
#: its own builder)
SPLIT_RULES = {name: code for code, name in enumerate(config.SPLIT_RULES)}

#: bits per axis of the lbvh builder's Morton codes (3 x 21 = 63: an int64 >= 0)
MORTON_BITS = 21


class BVH(NamedTuple):
    lo: np.ndarray
    hi: np.ndarray
    first: np.ndarray
    count: np.ndarray
    prim_ids: np.ndarray


# --- small box helpers ----------------------------------------------------------

@njit(cache=True)
def _half_area(lo, hi):
    return _half_area_of(lo[0], lo[1], lo[2], hi[0], hi[1], hi[2])


@njit(cache=True)
def _half_area_of(x0, y0, z0, x1, y1, z1):
    """Half the surface area of the box [x0, x1] x [y0, y1] x [z0, z1] (0 along an empty side)."""
    dx = max(x1 - x0, 0.0)
    dy = max(y1 - y0, 0.0)
    dz = max(z1 - z0, 0.0)
    return dx * dy + dy * dz + dz * dx


@njit(cache=True)
def _range_bounds(ids, start, stop, box_lo, box_hi, centre, out):
    """Box of the primitives ids[start:stop] and box of their centres, into the rows of
    out (4, 3): lo, hi, c_lo, c_hi (a buffer reused for every node: no allocation per node)."""
    for a in range(3):
        out[0, a] = np.inf
        out[1, a] = -np.inf
        out[2, a] = np.inf
        out[3, a] = -np.inf
    for k in range(start, stop):
        p = ids[k]
        for a in range(3):
            out[0, a] = min(out[0, a], box_lo[p, a])
            out[1, a] = max(out[1, a], box_hi[p, a])
            out[2, a] = min(out[2, a], centre[p, a])
            out[3, a] = max(out[3, a], centre[p, a])


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


class SahBins(NamedTuple):
    """Scratch of the binned SAH builder, allocated once per build (n_bins bins)."""
    lo: np.ndarray          #: float64 (n_bins, 3) box of each bin's primitives
    hi: np.ndarray          #: float64 (n_bins, 3)
    n: np.ndarray           #: int64 (n_bins,) primitives in each bin
    right_area: np.ndarray  #: float64 (n_bins,) half area of bins b.. (suffix)
    right_n: np.ndarray     #: int64 (n_bins,) primitives in bins b..


@njit(cache=True)
def _sah_bins(n_bins):
    return SahBins(np.empty((n_bins, 3)), np.empty((n_bins, 3)), np.zeros(n_bins, np.int64), np.zeros(n_bins),
                   np.zeros(n_bins, np.int64))


@njit(cache=True)
def _sah_best_plane(ids, start, stop, box_lo, box_hi, centre, c_lo, c_hi, bins):
    """Binned SAH: returns (cost, axis, position) of the cheapest split plane.

    cost = half_area(left) * n_left + half_area(right) * n_right (unnormalised);
    inf when every centre falls in one bin on every axis. bins: SahBins scratch.
    """
    n_bins = bins.n.shape[0]
    best_cost = np.inf
    best_axis = -1
    best_pos = 0.0
    for axis in range(3):
        extent = c_hi[axis] - c_lo[axis]
        scale = n_bins / extent if extent > 0.0 else np.inf
        if not scale < np.inf:
            continue  # one centre, or a subnormal extent (0 * inf would make a NaN bin)
        # 1. bin the centres, 2. accumulate each bin's box and count
        for b in range(n_bins):
            bins.n[b] = 0
            for a in range(3):
                bins.lo[b, a] = np.inf
                bins.hi[b, a] = -np.inf
        for k in range(start, stop):
            p = ids[k]
            b = min(int((centre[p, axis] - c_lo[axis]) * scale), n_bins - 1)
            bins.n[b] += 1
            for a in range(3):
                bins.lo[b, a] = min(bins.lo[b, a], box_lo[p, a])
                bins.hi[b, a] = max(bins.hi[b, a], box_hi[p, a])
        # 3. sweep from the right to get suffix areas, then from the left
        x0, y0, z0, x1, y1, z1 = np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf
        n = 0
        for b in range(n_bins - 1, 0, -1):
            x0, y0, z0 = min(x0, bins.lo[b, 0]), min(y0, bins.lo[b, 1]), min(z0, bins.lo[b, 2])
            x1, y1, z1 = max(x1, bins.hi[b, 0]), max(y1, bins.hi[b, 1]), max(z1, bins.hi[b, 2])
            n += bins.n[b]
            bins.right_area[b] = _half_area_of(x0, y0, z0, x1, y1, z1)
            bins.right_n[b] = n
        x0, y0, z0, x1, y1, z1 = np.inf, np.inf, np.inf, -np.inf, -np.inf, -np.inf
        n = 0
        for b in range(n_bins - 1):
            x0, y0, z0 = min(x0, bins.lo[b, 0]), min(y0, bins.lo[b, 1]), min(z0, bins.lo[b, 2])
            x1, y1, z1 = max(x1, bins.hi[b, 0]), max(y1, bins.hi[b, 1]), max(z1, bins.hi[b, 2])
            n += bins.n[b]
            if n == 0 or bins.right_n[b + 1] == 0:
                continue
            cost = _half_area_of(x0, y0, z0, x1, y1, z1) * n + bins.right_area[b + 1] * bins.right_n[b + 1]
            if cost < best_cost:
                best_cost = cost
                best_axis = axis
                best_pos = c_lo[axis] + (b + 1) / scale
    return best_cost, best_axis, best_pos


@njit(cache=True)
def _split_sah(ids, start, stop, box_lo, box_hi, centre, lo, hi, c_lo, c_hi,
               leaf_size, bins, traversal_cost):
    """Split index, or -1 to make a leaf (only allowed when count <= leaf_size)."""
    count = stop - start
    cost, axis, position = _sah_best_plane(ids, start, stop, box_lo, box_hi, centre,
                                           c_lo, c_hi, bins)
    area = _half_area(lo, hi)
    if count <= leaf_size and (axis < 0 or area <= 0.0
                               or traversal_cost + cost / area >= count):
        return -1
    if axis < 0:  # all centres coincide (or spread subnormally): any balanced split is as good
        return _split_in_halves(ids, start, stop, centre, _longest_axis(lo, hi))
    mid = _partition(ids, start, stop, centre, axis, position)
    if mid == start or mid == stop:
        mid = _split_in_halves(ids, start, stop, centre, axis)
    return mid


# --- the builder ---------------------------------------------------------------------

@njit(cache=True, nogil=True)
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
    stack[0, 0] = 0  # the root: node 0 holds every primitive
    stack[0, 1] = 0
    stack[0, 2] = n
    top = 1
    n_nodes = 1
    bounds = np.empty((4, 3))  # of the node being split (_range_bounds)
    bins = _sah_bins(n_bins)
    while top > 0:
        top -= 1
        node, start, stop = stack[top, 0], stack[top, 1], stack[top, 2]
        _range_bounds(ids, start, stop, box_lo, box_hi, centre, bounds)
        lo, hi, c_lo, c_hi = bounds[0], bounds[1], bounds[2], bounds[3]
        for c in range(3):  # element by element, as _push
            node_lo[node, c] = lo[c]
            node_hi[node, c] = hi[c]
        mid = -1
        if stop - start > 1:
            if rule == 0:
                mid = _split_sah(ids, start, stop, box_lo, box_hi, centre, lo, hi,
                                 c_lo, c_hi, leaf_size, bins, traversal_cost)
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
        top = _push(stack, top, (left + 1, mid, stop))
        top = _push(stack, top, (left, start, mid))
    return (node_lo[:n_nodes].copy(), node_hi[:n_nodes].copy(),
            first[:n_nodes].copy(), count[:n_nodes].copy(), ids)


@njit(cache=True)
def _push(stack, top, row):
    """Put the int64 tuple row on row top of stack (int64 (cap, len(row))), element by
    element (a row assignment compiles numba's shape-error path); returns top + 1."""
    for c in range(len(row)):
        stack[top, c] = row[c]
    return top + 1


# --- the lbvh builder (bottom-up, parallel) -------------------------------------------

_MORTON_MAX = (1 << MORTON_BITS) - 1


@njit(cache=True)
def _spread_bits(v):
    """Bits 0..20 of v (int64 >= 0) moved to bits 0, 3, 6, ..., 60."""
    v &= 0x1FFFFF
    v = (v | (v << 32)) & 0x1F00000000FFFF
    v = (v | (v << 16)) & 0x1F0000FF0000FF
    v = (v | (v << 8)) & 0x100F00F00F00F00F
    v = (v | (v << 4)) & 0x10C30C30C30C30C3
    v = (v | (v << 2)) & 0x1249249249249249
    return v


@njit(cache=True)
def _quantize(x, lo, scale):
    """(x - lo) * scale as an integer in [0, 2**MORTON_BITS - 1] (NaN -> 0)."""
    q = (x - lo) * scale
    if not q > 0.0:
        return 0
    if q >= _MORTON_MAX:
        return _MORTON_MAX
    return int(q)


@njit(cache=True, parallel=True)
def _morton_codes(centre, c_lo, scale):
    """int64 (n,) Morton codes of the centres (x in the highest bit of each triple)."""
    n = centre.shape[0]
    codes = np.empty(n, np.int64)
    for i in prange(n):
        codes[i] = ((_spread_bits(_quantize(centre[i, 0], c_lo[0], scale)) << 2)
                    | (_spread_bits(_quantize(centre[i, 1], c_lo[1], scale)) << 1)
                    | _spread_bits(_quantize(centre[i, 2], c_lo[2], scale)))
    return codes


@njit(cache=True)
def _leading_zeros(x):
    """Leading zero bits of 0 < x < 2**63 as a 64-bit word."""
    p = 0
    if x >= 1 << 32:
        x >>= 32
        p += 32
    if x >= 1 << 16:
        x >>= 16
        p += 16
    if x >= 1 << 8:
        x >>= 8
        p += 8
    if x >= 1 << 4:
        x >>= 4
        p += 4
    if x >= 1 << 2:
        x >>= 2
        p += 2
    if x >= 2:
        p += 1
    return 63 - p


@njit(cache=True)
def _prefix(codes, i, j):
    """Common prefix length of the keys (codes[i], i) and (codes[j], j): equal codes are
    told apart by their index (Karras's tie-break); -1 when j is outside the array."""
    if j < 0 or j >= codes.shape[0]:
        return -1
    x = codes[i] ^ codes[j]
    if x == 0:
        return 64 + _leading_zeros(i ^ j)
    return _leading_zeros(x)


@njit(cache=True, parallel=True)
def _radix_splits(codes):
    """Splits of the binary radix tree over the sorted codes (n,) (Karras 2012).

    The tree has n - 1 inner nodes; inner node 0 covers every primitive. The inner node
    covering sorted primitives a..b (a < b) splits them into a..s and s + 1..b, where
    s = split[node]; those children are inner nodes s and s + 1 respectively (unless
    they hold one primitive). Every node is found independently: int64 (n - 1,).
    """
    n = codes.shape[0]
    split = np.empty(max(n - 1, 0), np.int64)
    for i in prange(n - 1):
        d = 1 if _prefix(codes, i, i + 1) > _prefix(codes, i, i - 1) else -1
        # the other end of the range: the farthest j whose prefix with i is longer than
        # that of i's neighbour on the other side (exponential, then binary search)
        shortest = _prefix(codes, i, i - d)
        reach = 2
        while _prefix(codes, i, i + reach * d) > shortest:
            reach *= 2
        length = 0
        step = reach // 2
        while step >= 1:
            if _prefix(codes, i, i + (length + step) * d) > shortest:
                length += step
            step //= 2
        # the split: the last position (from i) whose prefix with i is longer than the node's
        node_prefix = _prefix(codes, i, i + length * d)
        s = 0
        div = 2
        while True:
            step = (length + div - 1) // div
            if _prefix(codes, i, i + (s + step) * d) > node_prefix:
                s += step
            if step <= 1:
                break
            div *= 2
        split[i] = i + s * d + min(d, 0)
    return split


@njit(cache=True)
def _radix_layout(split, n, leaf_size):
    """first, count (m,) of the radix tree in the BVH layout (preorder; the children of an
    inner node side by side), subtrees of at most leaf_size primitives as leaves; leaf
    ranges index the sorted primitives."""
    if n <= leaf_size:
        return np.zeros(1, np.int64), np.full(1, n, np.int64)
    max_nodes = 2 * n - 1
    first = np.zeros(max_nodes, np.int64)
    count = np.zeros(max_nodes, np.int64)
    # stack of (output node, radix node, first primitive, last primitive), all inner nodes
    stack = np.empty((n, 4), np.int64)
    for c in range(3):  # the root: every primitive, 0 to n - 1
        stack[0, c] = 0
    stack[0, 3] = n - 1
    top = 1
    n_nodes = 1
    while top > 0:
        top -= 1
        out, node, a, b = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        s = split[node]
        left = n_nodes
        n_nodes += 2
        first[out] = left
        if b - s <= leaf_size:
            first[left + 1] = s + 1
            count[left + 1] = b - s
        else:
            top = _push(stack, top, (left + 1, s + 1, s + 1, b))
        if s - a + 1 <= leaf_size:
            first[left] = a
            count[left] = s - a + 1
        else:
            top = _push(stack, top, (left, s, a, s))
    return first[:n_nodes].copy(), count[:n_nodes].copy()


@njit(cache=True, parallel=True)
def _refit(first, count, prim_ids, box_lo, box_hi):
    """Node boxes (m, 3) x 2: leaves from their primitives (in parallel), then inner nodes
    from their children, last node first (children come after their parent)."""
    m = first.shape[0]
    lo = np.empty((m, 3))
    hi = np.empty((m, 3))
    for node in prange(m):
        if count[node] > 0:
            for a in range(3):
                lo[node, a] = np.inf
                hi[node, a] = -np.inf
            for k in range(first[node], first[node] + count[node]):
                p = prim_ids[k]
                for a in range(3):
                    lo[node, a] = min(lo[node, a], box_lo[p, a])
                    hi[node, a] = max(hi[node, a], box_hi[p, a])
    for node in range(m - 1, -1, -1):
        if count[node] == 0:
            c = first[node]
            for a in range(3):
                lo[node, a] = min(lo[c, a], lo[c + 1, a])
                hi[node, a] = max(hi[c, a], hi[c + 1, a])
    return lo, hi


@njit(cache=True)
def _sah_collapse(first, count, lo, hi, leaf_size, traversal_cost):
    """The tree (first, count, lo, hi: a BVH's node arrays, children after parents) with
    the subtrees that are cheaper as leaves collapsed into leaves, renumbered (preorder,
    children side by side): returns (lo, hi, first, count).

    Bottom-up, every node's cheapest cost is its leaf cost (half area x primitives; only
    with at most leaf_size primitives) or its cost as an inner node (traversal_cost x half
    area + its children's cheapest costs), whichever is lower (a leaf on ties); the sum is
    the SAH cost that bvh_stats reports (before dividing by the root's half area), and the
    choice minimises it over all collapses of the given tree (Karras and Aila 2013).
    """
    m = first.shape[0]
    size = np.empty(m, np.int64)
    start = np.empty(m, np.int64)
    cost = np.empty(m)
    leaf = np.empty(m, np.bool_)
    n_out = np.empty(m, np.int64)   # nodes of the collapsed subtree
    for node in range(m - 1, -1, -1):
        area = _half_area(lo[node], hi[node])
        if count[node] > 0:
            size[node] = count[node]
            start[node] = first[node]
            cost[node] = area * count[node]
            leaf[node] = True
            n_out[node] = 1
            continue
        c = first[node]
        size[node] = size[c] + size[c + 1]
        start[node] = start[c]
        split_cost = traversal_cost * area + cost[c] + cost[c + 1]
        leaf_cost = area * size[node]
        if size[node] <= leaf_size and leaf_cost <= split_cost:
            cost[node] = leaf_cost
            leaf[node] = True
            n_out[node] = 1
        else:
            cost[node] = split_cost
            leaf[node] = False
            n_out[node] = 1 + n_out[c] + n_out[c + 1]
    n_nodes = n_out[0]
    out_lo = np.empty((n_nodes, 3))
    out_hi = np.empty((n_nodes, 3))
    out_first = np.zeros(n_nodes, np.int64)
    out_count = np.zeros(n_nodes, np.int64)
    stack = np.empty((n_nodes, 2), np.int64)   # (node, output node)
    stack[0, 0] = 0  # the root, output as node 0
    stack[0, 1] = 0
    top = 1
    used = 1
    while top > 0:
        top -= 1
        node, out = stack[top, 0], stack[top, 1]
        for c in range(3):  # element by element, as _push
            out_lo[out, c] = lo[node, c]
            out_hi[out, c] = hi[node, c]
        if leaf[node]:
            out_first[out] = start[node]
            out_count[out] = size[node]
            continue
        left = used
        used += 2
        out_first[out] = left
        top = _push(stack, top, (first[node] + 1, left + 1))
        top = _push(stack, top, (first[node], left))
    return out_lo, out_hi, out_first, out_count


def _build_lbvh(box_lo, box_hi, centre, leaf_size):
    """The lbvh builder: the arrays of a BVH (see the module docstring); parallel from
    config.LBVH_PARALLEL_MIN primitives on."""
    n = centre.shape[0]
    if n < config.LBVH_PARALLEL_MIN:
        with thread_limit(1):
            return _build_lbvh_kernels(box_lo, box_hi, centre, leaf_size)
    return _build_lbvh_kernels(box_lo, box_hi, centre, leaf_size)


def _build_lbvh_kernels(box_lo, box_hi, centre, leaf_size):
    n = centre.shape[0]
    c_lo = centre.min(axis=0)
    extent = float((centre.max(axis=0) - c_lo).max())
    scale = 2.0 ** MORTON_BITS / extent if 0.0 < extent < np.inf else 0.0
    if not scale < np.inf:  # subnormal extent
        scale = 0.0
    codes = _morton_codes(centre, c_lo, scale)
    prim_ids = np.argsort(codes, kind="stable").astype(np.int64, copy=False)
    split = _radix_splits(np.ascontiguousarray(codes[prim_ids]))
    first, count = _radix_layout(split, n, 1)
    lo, hi = _refit(first, count, prim_ids, box_lo, box_hi)
    lo, hi, first, count = _sah_collapse(first, count, lo, hi, leaf_size, config.SAH_TRAVERSAL_COST)
    return lo, hi, first, count, prim_ids


def builder_kernels(split):
    """The numba kernels the ``split`` rule's builder calls (for compile notices)."""
    if split == "lbvh":
        return [_morton_codes, _radix_splits, _radix_layout, _refit, _sah_collapse]
    return [_build]


def build_bvh(box_lo, box_hi, centre, split="sah", leaf_size=None):
    """Build a BVH over n primitives.

    Parameters
    ----------
    box_lo, box_hi : float64 (n, 3)
        Primitive box corners (any length unit).
    centre : float64 (n, 3)
        A representative point per primitive (e.g. the triangle centroid).
    split : {"sah", "median", "mean", "lbvh"}
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
    if split == "lbvh":
        bvh = BVH(*_build_lbvh(box_lo, box_hi, centre, leaf_size))
    else:
        bvh = BVH(*_build(box_lo, box_hi, centre, SPLIT_RULES[split], leaf_size,
                          config.SAH_BINS, config.SAH_TRAVERSAL_COST))
    _put_smallest_ids_first(*bvh)
    return bvh


# --- smallest-id order (see the module docstring) ----------------------------------------

@njit(cache=True, nogil=True)
def _put_smallest_ids_first(lo, hi, first, count, prim_ids):
    """Reorder a BVH's arrays in place into smallest-id order: sort each leaf's
    primitives, and swap two siblings' rows (their subtrees move with them) when the
    second holds the smaller id. One backward pass: children come after parents."""
    smallest = np.empty(first.shape[0], np.int64)
    for node in range(first.shape[0] - 1, -1, -1):
        if count[node] > 0:
            prim_ids[first[node]:first[node] + count[node]].sort()
            smallest[node] = prim_ids[first[node]]
            continue
        left = first[node]
        if smallest[left + 1] < smallest[left]:
            _swap_rows(lo, hi, first, count, smallest, left, left + 1)
        smallest[node] = smallest[left]


@njit(cache=True, nogil=True)
def _swap_rows(lo, hi, first, count, smallest, i, j):
    """Exchange nodes i and j (every per-node array)."""
    for c in range(3):
        lo[i, c], lo[j, c] = lo[j, c], lo[i, c]
        hi[i, c], hi[j, c] = hi[j, c], hi[i, c]
    first[i], first[j] = first[j], first[i]
    count[i], count[j] = count[j], count[i]
    smallest[i], smallest[j] = smallest[j], smallest[i]


@njit(cache=True)
def in_smallest_id_order(first, count, prim_ids):
    """Whether a BVH (any tree of this layout) is in smallest-id order: every leaf's
    primitives ascend and every first child holds a smaller id than its sibling. One
    backward pass (children come after parents); for checking stored trees."""
    smallest = np.empty(first.shape[0], np.int64)
    for node in range(first.shape[0] - 1, -1, -1):
        start = first[node]
        if count[node] > 0:
            for i in range(start + 1, start + count[node]):
                if prim_ids[i] <= prim_ids[i - 1]:
                    return False
            smallest[node] = prim_ids[start]
        elif smallest[start] < smallest[start + 1]:
            smallest[node] = smallest[start]
        else:
            return False
    return True


@njit(cache=True)
def smallest_id_under(first, count, prim_ids, node):
    """The smallest primitive id under ``node`` of a BVH in smallest-id order: the
    first primitive of its leftmost leaf."""
    while count[node] == 0:
        node = first[node]
    return prim_ids[first[node]]


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
