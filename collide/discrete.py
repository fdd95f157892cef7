"""Discrete detection: which objects touch, and through which triangles, at frame poses.

``scan_frames`` is the kernel for one chunk of frames (single-threaded,
releases the GIL so chunks run in parallel threads): per frame it places every
object's root box in the world, sweeps and prunes to candidate object pairs,
skips the pairs the filter excludes (filters.PairFilter), descends each pair's
BVHs (broad.overlapping_leaves with RULE_POSE) and tests triangle pairs exactly
(narrow.intersecting_triangles). When only a yes/no answer per pair is needed
(``first_only``), the triangle pair that touched at the previous frame (motion is
coherent: it usually still does) is tested first, and otherwise the descent hands
over its leaf pairs a few at a time and stops at the first intersecting triangle
pair; for a pair that touched at the previous frame it opens the nodes nearest that
frame's triangle pair first and hands over one leaf pair at a time, since the
touching region has only moved a little.

Output rows (int64, layouts in rows.py):
- hits (H, HIT_WIDTH): frame, object_a, object_b, number of intersecting
  triangle pairs, tri_a, tri_b (the lexicographically smallest intersecting
  pair), and 1 (the pair is known to be the smallest). With ``first_only`` a
  pair's search stops at its first intersecting triangle pair: the count is then
  1, (tri_a, tri_b) that pair (which one depends on the frames before it in the
  chunk) and the last column 0.
- pairs (P, PAIR_WIDTH): frame, object_a, object_b, tri_a, tri_b (only when
  collected).
- counts (COUNT_WIDTH,): work done (rows.COUNT_*).
"""
from typing import NamedTuple

import numpy as np

from . import config
from .broad import (
    RULE_POSE,
    RULE_SWEPT,
    RULE_SWEPT_RIGID,
    abs_rotation,
    grown_rows,
    node_box,
    opens_a,
    oriented_boxes_overlap,
    overlapping_leaves,
    relative_pose,
    sweep_and_prune,
    swept_leaves,
    with_room,
)
from .bvh import smallest_id_under
from .filters import pair_selected
from .jit import njit, njit_borrowing, njit_entry
from .motion import MOTION_WIDTH, swept_box
from .narrow import (
    Placed,
    append_row,
    intersecting_triangles,
    new_stamps,
    placed_triangle,
    triangle_boxes_overlap,
    triangle_pair_count,
)
from .predicates import triangles_intersect
from .rows import (
    COUNT_NODE_PAIRS,
    COUNT_OBJECT_PAIRS,
    COUNT_TRIANGLE_PAIRS,
    COUNT_WIDTH,
    HIT_A,
    HIT_B,
    HIT_FRAME,
    HIT_PAIRS,
    HIT_SMALLEST,
    HIT_TRI_A,
    HIT_TRI_B,
    HIT_WIDTH,
    PAIR_A,
    PAIR_B,
    PAIR_FRAME,
    PAIR_TRI_A,
    PAIR_TRI_B,
    PAIR_WIDTH,
)

#: leaf pairs the descent hands over at a time when one intersecting triangle pair is enough
FIRST_HIT_BATCH = 8
#: and when it looks near the previous frame's pair first (its first leaf pairs usually touch)
NEAR_HIT_BATCH = 1


@njit_borrowing
def object_margins(ps, rp0, rp1, out):
    """Rounding margin (length units) of each object over poses rp0 and rp1 (N, 3, 4) into out (N,)."""
    for o in range(rp0.shape[0]):
        out[o] = object_margin(ps, rp0, rp1, o)


@njit_borrowing
def object_margin(ps, rp0, rp1, o):
    """object_margins of object o alone."""
    scale = 0.0
    for rp in (rp0, rp1):
        scale = max(scale, abs(rp[o, 0, 3]) + abs(rp[o, 1, 3]) + abs(rp[o, 2, 3]))
    return config.BOX_MARGIN_REL * (scale + ps.radius[ps.object_mesh[o]]) + config.BOX_MARGIN_ABS


@njit(cache=True)
def object_world_boxes(ps, rp0, rp1, motion, extra, margin):
    """World boxes lo, hi (N, 3) of every object's root box moving from poses rp0 to
    rp1 (N, 3, 4) under motion rows motion (N, MOTION_WIDTH) (pass the same poses
    twice and zero rows for a still frame), widened by each object's rounding margin
    (N,) (object_margins) plus ``extra``."""
    lo = np.empty((rp0.shape[0], 3))
    hi = np.empty((rp0.shape[0], 3))
    _fill_world_boxes(ps, rp0, rp1, motion, extra, margin, lo, hi)
    return lo, hi


@njit_borrowing
def _fill_world_boxes(ps, rp0, rp1, motion, extra, margin, lo, hi):
    """object_world_boxes into lo, hi (N, 3)."""
    for o in range(rp0.shape[0]):
        root = ps.root[ps.object_mesh[o]]
        swept_box(ps.node_lo[root], ps.node_hi[root], rp0[o], rp1[o], motion[o], lo[o], hi[o], margin[o] + extra)


class PairScratch(NamedTuple):
    """Per-kernel scratch of a pair's descent."""
    pose: np.ndarray    #: float64 (4, 3, 4): A at pose 0, A at pose 1, B at pose 0, B at pose 1
    motion: np.ndarray  #: float64 (2, MOTION_WIDTH): motion rows of A and B
    toward: np.ndarray  #: float64 (2, 3): where the descent looks first, in A's and B's body frames
    p: np.ndarray       #: float64 (3, 3): a triangle of A
    q: np.ndarray       #: float64 (3, 3): a triangle of B


@njit(cache=True)
def pair_scratch():
    return PairScratch(np.empty((4, 3, 4)), np.empty((2, MOTION_WIDTH)), np.empty((2, 3)), np.empty((3, 3)),
                       np.empty((3, 3)))


@njit_borrowing
def start_descent(ps, rp0, rp1, motion, a, b, scratch, stack):
    """Set up the tandem descent of objects a and b for poses rp0 -> rp1 (N, 3, 4) and
    motion rows (N, MOTION_WIDTH): their poses and motions into scratch (PairScratch),
    their roots as the only row of stack (int64 (cap, 2)). Returns top = 1."""
    for i in range(3):  # element by element: no slice assignment (and its error path) to compile
        for j in range(4):
            scratch.pose[0, i, j] = rp0[a, i, j]
            scratch.pose[1, i, j] = rp1[a, i, j]
            scratch.pose[2, i, j] = rp0[b, i, j]
            scratch.pose[3, i, j] = rp1[b, i, j]
    for j in range(scratch.motion.shape[1]):
        scratch.motion[0, j] = motion[a, j]
        scratch.motion[1, j] = motion[b, j]
    stack[0, 0] = ps.root[ps.object_mesh[a]]
    stack[0, 1] = ps.root[ps.object_mesh[b]]
    return np.int64(1)  # not a literal: one compiled overlapping_leaves


@njit(cache=True, inline="always")  # part of its callers: no reference counting of ps per object pair
def pair_leaves(ps, rp0, rp1, motion, a, b, rule, margin, scratch, stack, leaves, counts):
    """All overlapping BVH leaf pairs of objects a and b under broad's ``rule`` for poses
    rp0 -> rp1 (N, 3, 4) and motion rows (N, MOTION_WIDTH). scratch: PairScratch;
    stack, leaves: int64 (cap, 2) buffers. Returns (stack, leaves, count)."""
    top = start_descent(ps, rp0, rp1, motion, a, b, scratch, stack)
    counts[COUNT_OBJECT_PAIRS] += 1
    if rule == RULE_SWEPT or rule == RULE_SWEPT_RIGID:
        stack, top, leaves, n = swept_leaves(ps.node_lo, ps.node_hi, ps.node_first, ps.node_count, ps.leaf_box,
                                             ps.leaf_box_shift[ps.object_mesh[a]],
                                             ps.leaf_box_shift[ps.object_mesh[b]], scratch.pose, scratch.motion,
                                             rule == RULE_SWEPT_RIGID, margin, stack, top, leaves, counts)
    else:  # RULE_POSE, passed as the literal _pair_triangles passes: one compiled overlapping_leaves
        stack, top, leaves, n = overlapping_leaves(ps.node_lo, ps.node_hi, ps.node_first, ps.node_count, ps.leaf_box,
                                                   ps.leaf_box_shift[ps.object_mesh[a]],
                                                   ps.leaf_box_shift[ps.object_mesh[b]], scratch.pose,
                                                   scratch.motion, RULE_POSE, margin, stack, top,
                                                   leaves, np.iinfo(np.int64).max, counts, scratch.toward,
                                                   np.bool_(False))
    return stack, leaves, n


@njit_borrowing
def _smallest_pair(tri, n):
    best = 0
    for k in range(1, n):
        if tri[k, 0] < tri[best, 0] or (tri[k, 0] == tri[best, 0] and tri[k, 1] < tri[best, 1]):
            best = k
    return tri[best, 0], tri[best, 1]


@njit(cache=True, inline="always")  # part of its caller: njit_borrowing _still_touching gets no array back
def _placed(ps, rp, o, f, static, stamp, world):
    """Object o at frame f (pose rp (N, 3, 4)) as a narrow.Placed view of the lazily filled
    world buffer; static objects share one key over all frames."""
    mesh = ps.object_mesh[o]
    body = ps.vertices[ps.vert_start[mesh]:ps.vert_start[mesh + 1]]
    faces = ps.faces[ps.face_start[mesh]:ps.face_start[mesh + 1]]
    return Placed(body, faces, rp[o], world, stamp, ps.world_start[o], -2 if static[o] else f)


@njit_borrowing
def _centroid(ps, o, t, out):
    """Centroid of triangle t (mesh-local) of object o's mesh, in its body frame, into out (3,)."""
    first = ps.vert_start[ps.object_mesh[o]]
    face = ps.faces[ps.face_start[ps.object_mesh[o]] + t]
    for i in range(3):
        out[i] = (ps.vertices[first + face[0], i] + ps.vertices[first + face[1], i]
                  + ps.vertices[first + face[2], i]) / 3.0


@njit(cache=True, inline="always")  # part of its callers: no reference counting of ps per object pair
def _pair_triangles(ps, rp, still, f, a, b, margin, static, stamp, world, first_only, near_a, near_b, scratch,
                    stack, leaves, tri, counts):
    """Intersecting triangle pairs of objects a and b at frame f (pose rp (N, 3, 4); still:
    zero motion rows (N, MOTION_WIDTH)): all of them, or the first one found when
    first_only (the descent hands over its leaf pairs FIRST_HIT_BATCH at a time and
    stops there). near_a, near_b: a triangle pair (mesh-local ids) near which one is
    likely (the pair that touched at the frame before), or -1, -1 if none: with a pair,
    the descent visits the nodes nearest their centroids first (broad.overlapping_leaves'
    ``toward``) and hands over NEAR_HIT_BATCH leaf pairs at a time. Returns (stack,
    leaves, tri, n_tri)."""
    top = start_descent(ps, rp, rp, still, a, b, scratch, stack)
    counts[COUNT_OBJECT_PAIRS] += 1
    batch = (NEAR_HIT_BATCH if near_a >= 0 else FIRST_HIT_BATCH) if first_only else np.iinfo(np.int64).max
    if near_a >= 0:
        _centroid(ps, a, near_a, scratch.toward[0])
        _centroid(ps, b, near_b, scratch.toward[1])
    lo, hi, first, count, prim_ids = ps.node_lo, ps.node_hi, ps.node_first, ps.node_count, ps.prim_ids
    pose, motion, toward, p, q = scratch.pose, scratch.motion, scratch.toward, scratch.p, scratch.q
    shift_a, shift_b = ps.leaf_box_shift[ps.object_mesh[a]], ps.leaf_box_shift[ps.object_mesh[b]]
    obj_a = _placed(ps, rp, a, f, static, stamp, world)
    obj_b = _placed(ps, rp, b, f, static, stamp, world)
    n_tri = np.int64(0)
    while top > 0 and not (first_only and n_tri > 0):
        stack, top, leaves, n_leaves = overlapping_leaves(lo, hi, first, count, ps.leaf_box, shift_a, shift_b, pose,
                                                          motion, RULE_POSE, margin, stack, top, leaves, batch,
                                                          counts, toward, near_a >= 0)
        if n_leaves > 0:
            tri = with_room(tri, n_tri, n_tri + triangle_pair_count(leaves, n_leaves, count))
            n_tri = intersecting_triangles(leaves, n_leaves, first, count, prim_ids, obj_a, obj_b, tri, n_tri,
                                           first_only, p, q, counts)
    return stack, leaves, tri, n_tri


@njit_borrowing
def key_row(keys, key):
    """Row of key in sorted keys (int64), or -1."""
    i = np.searchsorted(keys, key)
    return i if i < keys.shape[0] and keys[i] == key else -1


@njit_borrowing
def _still_touching(ps, rp, f, a, b, static, stamp, world, tri_a, tri_b, scratch, tri, counts):
    """Whether triangle pair (tri_a, tri_b) of objects a and b (the one they touched
    through at the previous frame) still intersects at frame f; if so it is tri[0].
    scratch: PairScratch (its triangles p and q)."""
    counts[COUNT_OBJECT_PAIRS] += 1
    counts[COUNT_TRIANGLE_PAIRS] += 1
    p, q = scratch.p, scratch.q
    placed_triangle(_placed(ps, rp, a, f, static, stamp, world), tri_a, p)
    placed_triangle(_placed(ps, rp, b, f, static, stamp, world), tri_b, q)
    if not (triangle_boxes_overlap(p, q) and triangles_intersect(p, q)):
        return False
    tri[0, 0] = tri_a
    tri[0, 1] = tri_b
    return True


@njit(cache=True)
def _frame_keys(hits, start, stop, n_objects):
    """Sorted keys a * N + b of hits[start:stop] (one frame's) and their triangle pairs."""
    keys = hits[start:stop, HIT_A] * n_objects + hits[start:stop, HIT_B]
    order = np.argsort(keys, kind="mergesort")
    tris = np.empty((stop - start, 2), np.int64)
    for k in range(stop - start):
        tris[k, 0] = hits[start + order[k], HIT_TRI_A]
        tris[k, 1] = hits[start + order[k], HIT_TRI_B]
    return keys[order], tris


@njit(cache=True)
def append_hit(hits, n_hits, hit, f, a, b, n_tri, tri_a, tri_b, smallest):
    """Append the hit row (frame f, objects a and b, n_tri triangle pairs, one of them
    (tri_a, tri_b), the smallest when ``smallest``) to hits (H, HIT_WIDTH), grown when
    full, through the scratch row hit (HIT_WIDTH,). Returns (hits, n_hits)."""
    hit[HIT_FRAME] = f
    hit[HIT_A] = a
    hit[HIT_B] = b
    hit[HIT_PAIRS] = n_tri
    hit[HIT_TRI_A] = tri_a
    hit[HIT_TRI_B] = tri_b
    hit[HIT_SMALLEST] = 1 if smallest else 0
    return append_row(hits, n_hits, hit)


@njit(cache=True, inline="always")  # part of its callers (scan_frames, swept.scan_intervals)
def frame_test(ps, rp, f, static, pairs, margin, still, stamp, world, sweep_order, previous_keys, previous_tris,
               collect_pairs, first_only, smallest, scratch, stack, leaves, tri, hit, hits, n_hits, row, found,
               n_found, counts):
    """The frame test of frame f (poses rp (N, 3, 4)): the touching object pairs appended to
    hits (n_hits rows used) and, when collect_pairs, their intersecting triangle pairs to
    found. previous_keys, previous_tris: the previous frame's hits (_frame_keys; empty
    unless first_only), whose triangle pair is tried first. With ``smallest`` (and not
    collect_pairs) each hit names the smallest intersecting triangle pair, not the first
    found, and says so (HIT_SMALLEST): _smallest_pair_of, from the vertices the test
    placed (its work is not counted, as that of smallest_touching_pairs is not).
    margin (N,) is filled here; still: zero motion rows; stamp, world: the lazily placed
    vertices; sweep_order: sweep_and_prune's, carried from frame to frame. Returns
    (hits, n_hits, found, n_found, stack, leaves, tri) (buffers grown when full)."""
    n_objects = rp.shape[0]
    object_margins(ps, rp, rp, margin)
    lo, hi = object_world_boxes(ps, rp, rp, still, 0.0, margin)
    candidates = sweep_and_prune(lo, hi, sweep_order)
    for c in range(candidates.shape[0]):
        a = candidates[c, 0]
        b = candidates[c, 1]
        if not pair_selected(pairs, a, b):
            continue
        before = key_row(previous_keys, a * n_objects + b)  # -1 unless first_only
        near_a = previous_tris[before, 0] if before >= 0 else -1
        near_b = previous_tris[before, 1] if before >= 0 else -1
        if before >= 0 and _still_touching(ps, rp, f, a, b, static, stamp, world, near_a, near_b, scratch, tri,
                                           counts):
            n_tri = np.int64(1)
        else:
            stack, leaves, tri, n_tri = _pair_triangles(ps, rp, still, f, a, b, margin[a] + margin[b], static,
                                                        stamp, world, first_only, near_a, near_b, scratch, stack,
                                                        leaves, tri, counts)
        if n_tri == 0:
            continue
        tri_a, tri_b = _smallest_pair(tri, n_tri)
        known = collect_pairs  # all pairs found: the smallest of them is the smallest
        if smallest and not collect_pairs:
            _, small_a, small_b = _smallest_pair_of(ps, rp, f, a, b, margin[a] + margin[b], static, stamp, world,
                                                    np.empty((64, 4), np.int64), np.zeros(COUNT_WIDTH, np.int64))
            if small_a >= 0:  # it always finds one: the same triangle test says they touch
                tri_a, tri_b, known = small_a, small_b, True
        hits, n_hits = append_hit(hits, n_hits, hit, f, a, b, n_tri, tri_a, tri_b, known)
        if collect_pairs:
            for k in range(n_tri):
                row[PAIR_FRAME] = f
                row[PAIR_A] = a
                row[PAIR_B] = b
                row[PAIR_TRI_A] = tri[k, 0]
                row[PAIR_TRI_B] = tri[k, 1]
                found, n_found = append_row(found, n_found, row)
    return hits, n_hits, found, n_found, stack, leaves, tri


@njit_entry
def scan_frames(ps, poses, static, pairs, frame_start, frame_stop, collect_pairs, first_only):
    """Discrete scan of frames [frame_start, frame_stop).

    ps: PackedScene; poses float64 (T, N, 3, 4); static bool (N,) (objects that never
    move: their world vertices are computed once); pairs: filters.PairFilter; first_only
    must be False when collect_pairs is True. Returns (hits int64 (H, HIT_WIDTH), pairs
    int64 (P, PAIR_WIDTH), counts int64 (COUNT_WIDTH,)): rows.py layouts.
    """
    n_objects = poses.shape[1]
    world = np.empty((ps.world_start[n_objects], 3))
    stamp = new_stamps(ps.world_start[n_objects])  # the key each world row was computed for
    margin = np.empty(n_objects)
    counts = np.zeros(COUNT_WIDTH, np.int64)
    hits = np.empty((16, HIT_WIDTH), np.int64)
    n_hits = np.int64(0)
    found = np.empty((16, PAIR_WIDTH), np.int64)
    n_found = np.int64(0)
    stack = np.empty((64, 2), np.int64)
    leaves = np.empty((256, 2), np.int64)
    tri = np.empty((64, 2), np.int64)
    scratch = pair_scratch()
    still = np.zeros((n_objects, MOTION_WIDTH))
    hit = np.empty(HIT_WIDTH, np.int64)
    row = np.empty(PAIR_WIDTH, np.int64)
    previous_keys = np.zeros(0, np.int64)
    previous_tris = np.zeros((0, 2), np.int64)
    sweep_order = np.arange(n_objects)  # sweep_and_prune's, carried from frame to frame
    for f in range(frame_start, frame_stop):
        frame_hits = n_hits
        hits, n_hits, found, n_found, stack, leaves, tri = frame_test(
            ps, poses[f], f, static, pairs, margin, still, stamp, world, sweep_order, previous_keys, previous_tris,
            collect_pairs, first_only, np.bool_(False), scratch, stack, leaves, tri, hit, hits, n_hits, row, found,
            n_found, counts)
        if first_only:
            previous_keys, previous_tris = _frame_keys(hits, frame_hits, n_hits, n_objects)
    return hits[:n_hits].copy(), found[:n_found].copy(), counts


# --- the smallest touching triangle pair (what contacts report) ---------------------------------

@njit_borrowing
def _before(a0, b0, a1, b1):
    """(a0, b0) < (a1, b1) lexicographically."""
    return a0 < a1 or (a0 == a1 and b0 < b1)


@njit(cache=True)
def _smallest_pair_of(ps, rp, f, a, b, margin, static, stamp, world, stack, counts):
    """The lexicographically smallest intersecting triangle pair (tri_a, tri_b) of objects
    a and b at frame f (pose rp (N, 3, 4)), or (-1, -1): a tandem descent that visits
    node pairs in order of their smallest ids and skips those that cannot hold a pair
    before the best one found. The BVHs are in smallest-id order (collide.bvh): a first
    child's smallest id is its parent's, a second child's that of its leftmost leaf.
    stack: int64 (cap, 4) rows (node_a, node_b, smallest id under node_a, under node_b).
    Returns (stack, tri_a, tri_b)."""
    lo, hi, first, count, prim_ids = ps.node_lo, ps.node_hi, ps.node_first, ps.node_count, ps.prim_ids
    rel = relative_pose(rp[a], rp[b])
    abs_r = abs_rotation(rel)
    obj_a = _placed(ps, rp, a, f, static, stamp, world)
    obj_b = _placed(ps, rp, b, f, static, stamp, world)
    p = np.empty((3, 3))
    q = np.empty((3, 3))
    best_a = np.iinfo(np.int64).max
    best_b = np.iinfo(np.int64).max
    root_a = ps.root[ps.object_mesh[a]]
    root_b = ps.root[ps.object_mesh[b]]
    stack[0, 0] = root_a
    stack[0, 1] = root_b
    stack[0, 2] = smallest_id_under(first, count, prim_ids, root_a)
    stack[0, 3] = smallest_id_under(first, count, prim_ids, root_b)
    top = 1
    while top > 0:
        top -= 1
        na = stack[top, 0]
        nb = stack[top, 1]
        min_a = stack[top, 2]
        min_b = stack[top, 3]
        if not _before(min_a, min_b, best_a, best_b):
            continue
        counts[COUNT_NODE_PAIRS] += 1
        box_a = node_box(lo, hi, na)
        box_b = node_box(lo, hi, nb)
        if not oriented_boxes_overlap(box_a, box_b, rel, abs_r, margin):
            continue
        leaf_a = count[na] > 0
        leaf_b = count[nb] > 0
        if leaf_a and leaf_b:
            for ia in range(first[na], first[na] + count[na]):  # ascending ids
                tri_a = prim_ids[ia]
                if tri_a > best_a:
                    break
                placed_triangle(obj_a, tri_a, p)
                for ib in range(first[nb], first[nb] + count[nb]):
                    tri_b = prim_ids[ib]
                    if not _before(tri_a, tri_b, best_a, best_b):
                        break
                    placed_triangle(obj_b, tri_b, q)
                    counts[COUNT_TRIANGLE_PAIRS] += 1
                    if triangle_boxes_overlap(p, q) and triangles_intersect(p, q):
                        best_a = tri_a
                        best_b = tri_b
            continue
        if top + 2 > stack.shape[0]:
            stack = grown_rows(stack, top)
        # open the node that is not a leaf, or the larger of two inner nodes (as overlapping_leaves);
        # its first child (smaller ids) is popped first
        open_a = opens_a(leaf_a, leaf_b, box_a, box_b)
        c0 = first[na] if open_a else first[nb]
        min_c1 = smallest_id_under(first, count, prim_ids, c0 + 1)
        stack[top, 0] = c0 + 1 if open_a else na
        stack[top, 1] = nb if open_a else c0 + 1
        stack[top, 2] = min_c1 if open_a else min_a
        stack[top, 3] = min_b if open_a else min_c1
        stack[top + 1, 0] = c0 if open_a else na
        stack[top + 1, 1] = nb if open_a else c0
        stack[top + 1, 2] = min_a
        stack[top + 1, 3] = min_b
        top += 2
    if best_a == np.iinfo(np.int64).max:
        return stack, -1, -1
    return stack, best_a, best_b


@njit_entry
def smallest_touching_pairs(ps, poses, static, rows, wanted, start, stop):
    """The smallest intersecting triangle pair of object pair wanted[k] = (a, b) (int64
    (K, 2)) at poses[rows[k]] (rows int64 (K,)), for k in [start, stop): int64
    (stop - start, 2) rows (tri_a, tri_b), (-1, -1) where a pair does not touch. The same
    pair as the smallest of scan_frames' collected pairs, found without enumerating them.
    ps's BVHs must be in smallest-id order (as collide.bvh builds them). Items of one
    pose row next to each other share its placed vertices. Releases the GIL (chunks of
    items run in parallel threads)."""
    n_objects = poses.shape[1]
    world = np.empty((ps.world_start[n_objects], 3))
    stamp = new_stamps(ps.world_start[n_objects])
    stack = np.empty((64, 4), np.int64)
    counts = np.zeros(COUNT_WIDTH, np.int64)
    out = np.empty((stop - start, 2), np.int64)
    for k in range(start, stop):
        rp = poses[rows[k]]
        a = wanted[k, 0]
        b = wanted[k, 1]
        margin = object_margin(ps, rp, rp, a) + object_margin(ps, rp, rp, b)
        stack, out[k - start, 0], out[k - start, 1] = _smallest_pair_of(ps, rp, rows[k], a, b, margin, static,
                                                                        stamp, world, stack, counts)
    return out
