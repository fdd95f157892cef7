"""Narrow phase: exact tests between the triangles of two overlapping leaves.

Triangles are read from a world-space vertex buffer ``world`` float64 (W, 3)
holding every object's vertices at the current pose; object o's vertex v is
row ``world_start[o] + v``. Faces are mesh-local vertex indices. The discrete
tests fill that buffer lazily (``Placed``): a vertex is transformed the first
time a tested triangle needs it at a frame, so a frame costs what its tested
triangles need, not the size of the meshes. The stamps that say which rows hold
which frame (``new_stamps``) are themselves set lazily, in blocks of rows, so a scan
of big meshes touching in a small region writes little of either buffer.
"""
from typing import NamedTuple

import numpy as np

from .broad import grown_rows, reorder_rows, with_room
from .ccd import ccd_work
from .jit import njit, njit_borrowing
from .motion import M_ETA, corners_deviation, point_deviation, triangle_pair_contact
from .predicates import triangles_intersect
from .rows import COUNT_TRIANGLE_PAIRS
from .windows import box_window, cross_window, largest_coordinate, moving_box


@njit_borrowing
def gather_triangle(world, world_base, faces, face, out):
    """out (3, 3) = world coordinates of the triangle with global face row ``face``."""
    for r in range(3):
        row = world_base + faces[face, r]
        for c in range(3):
            out[r, c] = world[row, c]


@njit_borrowing
def gathered_corners(world, world_base, faces, face):
    """The world corners of the triangle with global face row ``face`` as a 9-tuple, row
    by row (gather_triangle without a buffer: per-pair helpers take tuples, since array
    arguments and views cost reference counting on every call)."""
    r0 = world_base + faces[face, 0]
    r1 = world_base + faces[face, 1]
    r2 = world_base + faces[face, 2]
    return (world[r0, 0], world[r0, 1], world[r0, 2], world[r1, 0], world[r1, 1], world[r1, 2],
            world[r2, 0], world[r2, 1], world[r2, 2])


STAMP_BLOCK_BITS = 10
STAMP_BLOCK = 1 << STAMP_BLOCK_BITS  #: rows of a world buffer whose stamps are set together, on first use


@njit(cache=True)
def new_stamps(n_rows):
    """Stamps for a world buffer of n_rows rows: the key (a frame) each row was last
    computed for, set lazily. int64 (B * (STAMP_BLOCK + 1),) for B = ceil(n_rows /
    STAMP_BLOCK) blocks: the rows' stamps (not yet set), then one flag per block, block
    b's at [-1 - b], 0 until stamp_is sets the block's stamps to -1 ('not computed').
    Only the blocks a scan asks about are written: fresh memory costs a page fault per
    page touched, and a few triangles of a big mesh touch few blocks."""
    n_blocks = (n_rows + STAMP_BLOCK - 1) // STAMP_BLOCK
    stamps = np.empty(n_blocks * (STAMP_BLOCK + 1), np.int64)
    stamps[n_blocks * STAMP_BLOCK:] = 0
    return stamps


@njit(cache=True, inline="always")
def stamp_is(stamps, row, key):
    """Whether world row ``row`` holds its value for ``key`` (stamps: new_stamps; keys
    are never -1). Sets the row's block of stamps to -1 first if nothing set it yet."""
    block = row >> STAMP_BLOCK_BITS  # row // STAMP_BLOCK
    flag = stamps.shape[0] - 1 - block
    if stamps[flag] == 0:
        for r in range(block * STAMP_BLOCK, (block + 1) * STAMP_BLOCK):
            stamps[r] = -1
        stamps[flag] = 1
    return stamps[row] == key


class Placed(NamedTuple):
    """One object's triangles at one pose, transformed on demand (discrete tests)."""
    body: np.ndarray    #: float64 (V, 3) the mesh's body vertices
    faces: np.ndarray   #: int64 (F, 3) the mesh's faces (mesh-local vertex indices)
    pose: np.ndarray    #: float64 (3, 4) [R | p]
    world: np.ndarray   #: float64 (W, 3) the shared world buffer
    stamp: np.ndarray   #: int64 the world buffer's stamps (new_stamps)
    base: int           #: the object's first row in world
    key: int            #: this pose's key (a frame; static objects: one key for all frames)


@njit_borrowing
def placed_triangle(obj, face, out):
    """out (3, 3) = world corners of mesh-local triangle ``face`` of the Placed object,
    computing (p + R0 x + R1 y + R2 z, as packed.to_world) the vertices not yet known
    for this key."""
    for r in range(3):
        v = obj.faces[face, r]
        row = obj.base + v
        if not stamp_is(obj.stamp, row, obj.key):
            x = obj.body[v, 0]
            y = obj.body[v, 1]
            z = obj.body[v, 2]
            for c in range(3):
                obj.world[row, c] = obj.pose[c, 3] + obj.pose[c, 0] * x + obj.pose[c, 1] * y + obj.pose[c, 2] * z
            obj.stamp[row] = obj.key
        for c in range(3):
            out[r, c] = obj.world[row, c]


@njit_borrowing
def triangle_boxes_overlap(p, q):
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
        buf = grown_rows(buf, n)
    for c in range(buf.shape[1]):
        buf[n, c] = row[c]
    return buf, n + 1


@njit_borrowing
def intersecting_triangles(leaves, n_leaves, first, count, prim_ids, obj_a, obj_b, out, n_out, first_only, p,
                           q, counts):
    """Append every intersecting triangle pair (tri_a, tri_b) of the leaf pairs
    (only the first one found when ``first_only``).

    leaves int64 (>= n_leaves, 2): (leaf of A, leaf of B) node indices; prim_ids
    hold mesh-local face indices; obj_a, obj_b: the two objects (Placed). p, q:
    float64 (3, 3) scratch. counts: int64 rows.COUNT_* counters. out: int64 (cap, 2)
    mesh-local triangle indices, n_out rows filled and room for every pair of the leaf
    pairs after them (the caller makes it: with_room and triangle_pair_count). Returns
    the new n_out.
    """
    for k in range(n_leaves):
        la = leaves[k, 0]
        lb = leaves[k, 1]
        for ia in range(first[la], first[la] + count[la]):
            tri_a = prim_ids[ia]
            placed_triangle(obj_a, tri_a, p)
            for ib in range(first[lb], first[lb] + count[lb]):
                tri_b = prim_ids[ib]
                placed_triangle(obj_b, tri_b, q)
                counts[COUNT_TRIANGLE_PAIRS] += 1
                if triangle_boxes_overlap(p, q) and triangles_intersect(p, q):
                    out[n_out, 0] = tri_a
                    out[n_out, 1] = tri_b
                    n_out += 1
                    if first_only:
                        return n_out
    return n_out


@njit_borrowing
def triangle_pair_count(leaves, n_leaves, count):
    """Number of triangle pairs in the first n_leaves leaf pairs (room to make before a
    loop appends some of them, so that it never rebinds its buffer)."""
    total = 0
    for k in range(n_leaves):
        total += count[leaves[k, 0]] * count[leaves[k, 1]]
    return total


# --- continuous (swept) tests -------------------------------------------------------------

@njit(cache=True)
def swept_candidates(leaves, n_leaves, first, count, prim_ids, faces, face_base_a, face_base_b,
                     world0, world1, world_base_a, world_base_b, motion_a, motion_b, dist_tol, after, before, out,
                     counts):
    """Triangle pairs (tri_a, tri_b) of the leaf pairs whose moving boxes, widened by
    dist_tol, both triangles' deviation bounds and rounding margins, overlap at some
    moment of the step in [after, before] (windows.swept_window_of, its per-triangle parts
    computed once per triangle and leaf pair). Returns (out int64 (cap, 2), n, windows
    float64 (n, 2)): rows sorted by (tri_a, tri_b), windows their (t_lo, t_hi)."""
    n = np.int64(0)
    room = triangle_pair_count(leaves, n_leaves, count)
    windows = np.empty((max(room, 1), 2))
    out = with_room(out, n, room)
    widest = 0
    for k in range(n_leaves):
        widest = max(widest, count[leaves[k, 1]])
    side_b = np.empty((widest, SIDE_WIDTH))  # a leaf of B's triangles (_set_side_row)
    for k in range(n_leaves):  # out and windows have room for every pair: not rebound in here
        n = leaf_pair_candidates(leaves[k, 0], leaves[k, 1], first, count, prim_ids, faces, face_base_a,
                                 face_base_b, world0, world1, world_base_a, world_base_b, motion_a, motion_b, dist_tol,
                                 after, before, side_b, out, windows, n, counts)
    if n > 1:  # order by (tri_a, tri_b): keys tri_a * span + tri_b (most calls find 0 or 1: no scratch)
        span = 0
        for r in range(n):
            span = max(span, out[r, 1] + 1)
        keys = np.empty(n, np.int64)
        for r in range(n):
            keys[r] = out[r, 0] * span + out[r, 1]
        order = stable_order(keys)
        reorder_rows(out, order)
        reorder_rows(windows, order)
    return out, n, windows[:n]


@njit_borrowing
def leaf_pair_candidates(la, lb, first, count, prim_ids, faces, face_base_a, face_base_b, world0, world1,
                         world_base_a, world_base_b, motion_a, motion_b, dist_tol, after, before, side_b, out, windows,
                         n, counts):
    """swept_candidates of the one leaf pair (la, lb), in the order of its leaves'
    triangles, written to rows n on of out and windows (room for count[la] * count[lb]
    more); side_b: float64 (at least count[lb], SIDE_WIDTH) scratch. Returns the new n."""
    eta = motion_a[M_ETA] + motion_b[M_ETA]
    for j in range(count[lb]):
        face = face_base_b + prim_ids[first[lb] + j]
        q0 = gathered_corners(world0, world_base_b, faces, face)
        _set_side_row(side_b, j, q0, gathered_corners(world1, world_base_b, faces, face),
                      corners_deviation(motion_b, q0))
    for ia in range(first[la], first[la] + count[la]):
        tri_a = prim_ids[ia]
        p0 = gathered_corners(world0, world_base_a, faces, face_base_a + tri_a)
        p1 = gathered_corners(world1, world_base_a, faces, face_base_a + tri_a)
        p_box = moving_box(p0, p1)
        dev_p = corners_deviation(motion_a, p0)
        for j in range(count[lb]):
            counts[COUNT_TRIANGLE_PAIRS] += 1
            margin = dist_tol + (dev_p + side_b[j, _SIDE_DEV]) + eta
            q_box = _side_box(side_b, j)
            t_lo, t_hi = box_window(p_box, q_box, margin)
            if t_lo > t_hi or t_hi < after or t_lo > before:
                continue
            t_lo, t_hi = cross_window(p0, p1, _side_corners(side_b, j, 0), _side_corners(side_b, j, 9), margin,
                                      largest_coordinate(p_box, q_box), t_lo, t_hi)
            if t_lo <= t_hi and t_hi >= after and t_lo <= before:
                out[n, 0] = tri_a
                out[n, 1] = prim_ids[first[lb] + j]
                windows[n, 0] = t_lo
                windows[n, 1] = t_hi
                n += 1
    return n


class Pending(NamedTuple):
    """Triangle pairs (or node pairs) waiting to be tried, first the smallest (key, tri_a,
    tri_b): a binary heap (swept._one_sided_window, swept._best_first_window). Grown by
    pending_push, which returns it, or pending_with_room before heap_insert."""
    keys: np.ndarray   #: float64 (cap,)
    pairs: np.ndarray  #: int64 (cap, 2): tri_a, tri_b
    size: np.ndarray   #: int64 (1,): rows in use


@njit(cache=True)
def new_pending(capacity=64):
    """An empty Pending with room for ``capacity`` rows (it grows when full)."""
    return Pending(np.empty(capacity), np.empty((capacity, 2), np.int64), np.zeros(1, np.int64))


@njit_borrowing
def pending_size(pending):
    return pending.size[0]


@njit_borrowing
def pending_lacks_room(pending, extra):
    """Whether pending has room for fewer than ``extra`` more rows (pending_with_room)."""
    return pending.size[0] + extra > pending.keys.shape[0]


@njit_borrowing
def pending_first_key(pending):
    """The smallest key (pending not empty)."""
    return pending.keys[0]


@njit_borrowing
def _heap_before(pending, i, j):
    """Row i of the heap comes before row j: smaller key, then smaller (tri_a, tri_b)."""
    keys, pairs = pending.keys, pending.pairs
    if keys[i] != keys[j]:
        return keys[i] < keys[j]
    if pairs[i, 0] != pairs[j, 0]:
        return pairs[i, 0] < pairs[j, 0]
    return pairs[i, 1] < pairs[j, 1]


@njit_borrowing
def _swap(pending, i, j):
    keys, pairs = pending.keys, pending.pairs
    keys[i], keys[j] = keys[j], keys[i]
    for c in range(2):
        pairs[i, c], pairs[j, c] = pairs[j, c], pairs[i, c]


@njit(cache=True)
def pending_push(pending, key, tri_a, tri_b):
    """Add (key, tri_a, tri_b); returns pending (grown when full)."""
    if pending.size[0] == pending.keys.shape[0]:
        pending = pending_with_room(pending, 1)
    heap_insert(pending, key, tri_a, tri_b)
    return pending


@njit(cache=True)
def pending_with_room(pending, extra):
    """pending, or a copy with room for at least ``extra`` more rows when it lacks it."""
    n = pending.size[0]
    if n + extra <= pending.keys.shape[0]:
        return pending
    cap = max(2 * pending.keys.shape[0], n + extra)
    keys = np.empty(cap)
    pairs = np.empty((cap, 2), np.int64)
    for i in range(n):
        keys[i] = pending.keys[i]
        pairs[i, 0] = pending.pairs[i, 0]
        pairs[i, 1] = pending.pairs[i, 1]
    return Pending(keys, pairs, pending.size)


@njit_borrowing
def heap_insert(pending, key, tri_a, tri_b):
    """Add (key, tri_a, tri_b) to a pending with room for it (pending_with_room)."""
    n = pending.size[0]
    pending.keys[n] = key
    pending.pairs[n, 0] = tri_a
    pending.pairs[n, 1] = tri_b
    pending.size[0] = n + 1
    i = n
    while i > 0 and _heap_before(pending, i, (i - 1) // 2):
        _swap(pending, i, (i - 1) // 2)
        i = (i - 1) // 2


@njit_borrowing
def pending_pop(pending):
    """Remove and return the first row (key, tri_a, tri_b) (pending not empty)."""
    key, tri_a, tri_b = pending.keys[0], pending.pairs[0, 0], pending.pairs[0, 1]
    n = pending.size[0] - 1
    pending.size[0] = n
    if n > 0:
        _swap(pending, 0, n)
        _sift_down(pending, 0, n)
    return key, tri_a, tri_b


@njit_borrowing
def _sift_down(pending, i, n):
    """Move row i down the heap of rows [0, n) until no child comes before it."""
    while True:
        first = i
        for child in (2 * i + 1, 2 * i + 2):
            if child < n and _heap_before(pending, child, first):
                first = child
        if first == i:
            return
        _swap(pending, i, first)
        i = first


@njit(cache=True)
def pending_of_keys(keys, n):
    """A Pending of the rows (keys[i], i, 0) for i < n, heap-ordered in one pass from the
    bottom up (O(n); n pending_push calls take O(n log n), and each call counts
    references to the heap's arrays). Rows are distinct, so they pop in the same order
    as after pushing them one by one."""
    pending = new_pending(max(n, 64))
    pending.size[0] = n
    for i in range(n):
        pending.keys[i] = keys[i]
        pending.pairs[i, 0] = i
        pending.pairs[i, 1] = 0
    for i in range(n // 2 - 1, -1, -1):
        _sift_down(pending, i, n)
    return pending


@njit(cache=True)
def stable_order(keys):
    """int64 (n,): the stable ascending argsort of keys (n,) (np.argsort kind="mergesort"),
    by insertion for the short arrays of most calls (no merge sort set-up)."""
    n = keys.shape[0]
    if n > 16:
        return np.argsort(keys, kind="mergesort")
    order = np.empty(n, np.int64)
    for i in range(n):
        j = i
        while j > 0 and keys[order[j - 1]] > keys[i]:
            order[j] = order[j - 1]
            j -= 1
        order[j] = i
    return order


#: columns of swept_candidates' rows of B's triangles: corners at the step's start (0-8)
#: and end (9-17), moving_box (18-32), deviation bound (33)
_SIDE_BOX = 18
_SIDE_DEV = 33
SIDE_WIDTH = 34


@njit_borrowing
def _set_side_row(side, j, t0, t1, deviation):
    """Row j of side: a triangle's corners t0, t1 (9-tuples) at both ends of the step,
    its moving_box and its deviation bound (length units). One array argument: each
    costs reference counting per call."""
    box = moving_box(t0, t1)
    for i in range(9):
        side[j, i] = t0[i]
        side[j, 9 + i] = t1[i]
    for i in range(15):
        side[j, _SIDE_BOX + i] = box[i]
    side[j, _SIDE_DEV] = deviation


@njit_borrowing
def _side_corners(side, j, at):
    """Corners (9-tuple) of row j of side from column ``at`` (0: step start, 9: end)."""
    return (side[j, at], side[j, at + 1], side[j, at + 2], side[j, at + 3], side[j, at + 4], side[j, at + 5],
            side[j, at + 6], side[j, at + 7], side[j, at + 8])


@njit_borrowing
def _side_box(side, j):
    """moving_box (15-tuple) of row j of side."""
    b = _SIDE_BOX
    return (side[j, b], side[j, b + 1], side[j, b + 2], side[j, b + 3], side[j, b + 4], side[j, b + 5],
            side[j, b + 6], side[j, b + 7], side[j, b + 8], side[j, b + 9], side[j, b + 10], side[j, b + 11],
            side[j, b + 12], side[j, b + 13], side[j, b + 14])


@njit(cache=True)
def candidates_contact_window(candidates, n, windows, faces, face_base_a, face_base_b, world0, world1,
                              world_base_a, world_base_b, motion_a, motion_b, time_tol, dist_tol, find_first,
                              find_last, counts):
    """When two objects touch during one step, from their candidate triangle pairs.

    candidates[:n] int64 (n, 2) and their windows float64 (n, 2): swept_candidates of
    the objects' overlapping leaf pairs. Returns (t_first, t_last, tri_a, tri_b): the
    earliest contact of any triangle pair and the latest one (fractions of the step,
    both conservative: motion.triangle_pair_contact, under the objects' motion rows
    motion_a and motion_b), and the smallest pair touching at t_first; t_first = inf
    when none touches. A contact that ends and starts again within the step is reported
    as one (the step is the resolution of gaps). Pairs are searched in order of the
    earliest (latest) moment their moving boxes meet, and each search only looks for
    contacts that could still move t_first (t_last); the searches stop once no remaining
    pair's boxes meet early (late) enough to move it.
    With find_first False only t_last is searched (t_first stays inf, t_last is -inf
    when none touches); with find_last False only t_first (t_last is returned as
    t_first: the caller knows better). counts: int64 rows.COUNT_* counters.
    """
    if n == 0:  # most calls: no scratch to allocate, nothing to sort
        return np.inf, np.inf if find_first else -np.inf, -1, -1
    corners = np.empty((4, 3, 3))  # p0, p1, q0, q1
    work = ccd_work()
    t_first = np.inf
    best_a = -1
    best_b = -1
    # stable sorts (ties stay in (tri_a, tri_b) order) of contiguous copies: one compiled sort
    by_start = stable_order(windows[:, 0].copy())
    for i in range(n if find_first else 0):  # earliest contact
        k = by_start[i]
        if windows[k, 0] > t_first:
            break  # no later pair's boxes meet before the contact found
        t = candidate_contact(candidates[k, 0], candidates[k, 1], faces, face_base_a, face_base_b, world0,
                              world1, world_base_a, world_base_b, motion_a, motion_b, time_tol, dist_tol,
                              t_first, np.bool_(False), corners, work, counts)
        if comes_first(t, candidates[k, 0], candidates[k, 1], t_first, best_a, best_b):
            t_first = t
            best_a = candidates[k, 0]
            best_b = candidates[k, 1]
    t_last = t_first if find_first else -np.inf  # the last contact is no earlier than the first
    by_end = stable_order(-windows[:, 1])
    for i in range(n if find_last else 0):
        k = by_end[i]
        if (find_first and t_first == np.inf) or t_last == 1.0 or windows[k, 1] < t_last:
            break  # no remaining pair's boxes meet after the contact found
        t = candidate_contact(candidates[k, 0], candidates[k, 1], faces, face_base_a, face_base_b, world0,
                              world1, world_base_a, world_base_b, motion_a, motion_b, time_tol, dist_tol,
                              t_last, np.bool_(True), corners, work, counts)
        t_last = max(t_last, t)
    return t_first, t_last, best_a, best_b


@njit_borrowing
def comes_first(t, tri_a, tri_b, t_first, best_a, best_b):
    """Contact time t of triangle pair (tri_a, tri_b) replaces the earliest one found so far,
    t_first of (best_a, best_b): it is earlier, or as early (and finite) with the smaller
    pair, so that ties keep the smaller pair whatever the order they are found in."""
    return t < t_first or (t == t_first and t < np.inf and (tri_a < best_a or (tri_a == best_a and tri_b < best_b)))


@njit_borrowing
def candidate_contact(tri_a, tri_b, faces, face_base_a, face_base_b, world0, world1, world_base_a,
                       world_base_b, motion_a, motion_b, time_tol, dist_tol, limit, backwards, corners, work,
                       counts):
    """motion.triangle_pair_contact of triangles tri_a of A and tri_b of B; corners (4, 3, 3)
    and work (ccd.CCDWork) scratch."""
    p0 = corners[0]
    p1 = corners[1]
    q0 = corners[2]
    q1 = corners[3]
    gather_triangle(world0, world_base_a, faces, face_base_a + tri_a, p0)
    gather_triangle(world1, world_base_a, faces, face_base_a + tri_a, p1)
    gather_triangle(world0, world_base_b, faces, face_base_b + tri_b, q0)
    gather_triangle(world1, world_base_b, faces, face_base_b + tri_b, q1)
    dev = point_deviation(motion_a, p0) + point_deviation(motion_b, q0)
    eta = motion_a[M_ETA] + motion_b[M_ETA]
    return triangle_pair_contact(motion_a, motion_b, p0, p1, q0, q1, dev, eta, time_tol, dist_tol, limit,
                                 backwards, work, counts)
