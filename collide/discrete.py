"""Discrete detection: which objects touch, and through which triangles, at frame poses.

``scan_frames`` is the kernel for one chunk of frames (single-threaded,
releases the GIL so chunks run in parallel threads): per frame it places every
object's root box in the world, sweeps and prunes to candidate object pairs,
descends each pair's BVHs (broad.overlapping_leaves with RULE_POSE) and tests
triangle pairs exactly (narrow.intersecting_triangles).

Output rows (int64, layouts in rows.py):
- hits (H, HIT_WIDTH): frame, object_a, object_b, number of intersecting
  triangle pairs, tri_a, tri_b (the lexicographically smallest intersecting
  pair). With ``first_only`` a pair's search stops at its first intersecting
  triangle pair: the count is then 1 and (tri_a, tri_b) that first pair.
- pairs (P, PAIR_WIDTH): frame, object_a, object_b, tri_a, tri_b (only when
  collected).
"""
from typing import NamedTuple

import numpy as np
from numba import njit

from . import config
from .broad import RULE_POSE, overlapping_leaves, sweep_and_prune
from .motion import MOTION_WIDTH, swept_box
from .narrow import append_row, intersecting_triangles
from .rows import (HIT_A, HIT_B, HIT_FRAME, HIT_PAIRS, HIT_TRI_A, HIT_TRI_B, HIT_WIDTH, PAIR_A, PAIR_B,
                   PAIR_FRAME, PAIR_TRI_A, PAIR_TRI_B, PAIR_WIDTH)
from .packed import to_world

#: pair_filter values: which object pairs a kernel call tests
ALL_PAIRS = 0
SKIP_STATIC_PAIRS = 1   # pairs of two static objects are skipped
ONLY_STATIC_PAIRS = 2   # only pairs of two static objects


@njit(cache=True)
def object_margins(ps, rp0, rp1, out):
    """Rounding margin (length units) of each object over poses rp0 and rp1 (N, 3, 4) into out (N,)."""
    for o in range(rp0.shape[0]):
        scale = 0.0
        for rp in (rp0, rp1):
            scale = max(scale, abs(rp[o, 0, 3]) + abs(rp[o, 1, 3]) + abs(rp[o, 2, 3]))
        out[o] = config.BOX_MARGIN_REL * (scale + ps.radius[ps.object_mesh[o]]) + config.BOX_MARGIN_ABS


@njit(cache=True)
def object_world_boxes(ps, rp0, rp1, motion, extra, margin):
    """World boxes lo, hi (N, 3) of every object's root box moving from poses rp0 to
    rp1 (N, 3, 4) under motion rows motion (N, MOTION_WIDTH) (pass the same poses
    twice and zero rows for a still frame), widened by each object's rounding margin
    (N,) (object_margins) plus ``extra``."""
    n = rp0.shape[0]
    lo = np.empty((n, 3))
    hi = np.empty((n, 3))
    for o in range(n):
        root = ps.root[ps.object_mesh[o]]
        w_lo, w_hi = swept_box(ps.node_lo[root], ps.node_hi[root], rp0[o], rp1[o], motion[o])
        lo[o] = w_lo - (margin[o] + extra)
        hi[o] = w_hi + (margin[o] + extra)
    return lo, hi


@njit(cache=True)
def pair_leaves(ps, rp0, rp1, motion, a, b, rule, margin, scratch, leaves):
    """Overlapping BVH leaf pairs of objects a and b (broad.overlapping_leaves) for poses
    rp0 -> rp1 (N, 3, 4) and motion rows (N, MOTION_WIDTH); scratch: PairScratch.
    Returns (leaves, count)."""
    pose = scratch.pose
    pose[0] = rp0[a]
    pose[1] = rp1[a]
    pose[2] = rp0[b]
    pose[3] = rp1[b]
    scratch.motion[0] = motion[a]
    scratch.motion[1] = motion[b]
    return overlapping_leaves(ps.node_lo, ps.node_hi, ps.node_first, ps.node_count,
                              ps.root[ps.object_mesh[a]], ps.root[ps.object_mesh[b]], pose,
                              scratch.motion, rule, margin, leaves)


class PairScratch(NamedTuple):
    """Per-kernel scratch of pair_leaves."""
    pose: np.ndarray    #: float64 (4, 3, 4)
    motion: np.ndarray  #: float64 (2, MOTION_WIDTH)


@njit(cache=True)
def pair_scratch():
    return PairScratch(np.empty((4, 3, 4)), np.empty((2, MOTION_WIDTH)))


@njit(cache=True)
def ensure_world(ps, rp, o, frame, static, stamp, world):
    """Transform object o's vertices to the world buffer once per frame
    (once per call for static objects)."""
    if stamp[o] == frame or (static[o] and stamp[o] >= 0):
        return
    mesh = ps.object_mesh[o]
    body = ps.vertices[ps.vert_start[mesh]:ps.vert_start[mesh + 1]]
    to_world(body, rp[o], world, ps.world_start[o])
    stamp[o] = frame


@njit(cache=True)
def pair_selected(pair_filter, static, a, b):
    both_static = static[a] and static[b]
    if pair_filter == SKIP_STATIC_PAIRS:
        return not both_static
    if pair_filter == ONLY_STATIC_PAIRS:
        return both_static
    return True


@njit(cache=True)
def _smallest_pair(tri, n):
    best = 0
    for k in range(1, n):
        if tri[k, 0] < tri[best, 0] or (tri[k, 0] == tri[best, 0] and tri[k, 1] < tri[best, 1]):
            best = k
    return tri[best, 0], tri[best, 1]


@njit(cache=True, nogil=True)
def scan_frames(ps, poses, static, frame_start, frame_stop, pair_filter, collect_pairs, first_only):
    """Discrete scan of frames [frame_start, frame_stop).

    ps: PackedScene; poses float64 (T, N, 3, 4); static bool (N,);
    first_only must be False when collect_pairs is True.
    Returns (hits int64 (H, HIT_WIDTH), pairs int64 (P, PAIR_WIDTH)): rows.py layouts.
    """
    n_objects = poses.shape[1]
    world = np.empty((ps.world_start[n_objects], 3))
    stamp = np.full(n_objects, -1, np.int64)
    margin = np.empty(n_objects)
    hits = np.empty((16, HIT_WIDTH), np.int64)
    n_hits = 0
    pairs = np.empty((16, PAIR_WIDTH), np.int64)
    n_pairs = 0
    leaves = np.empty((256, 2), np.int64)
    tri = np.empty((64, 2), np.int64)
    scratch = pair_scratch()
    still = np.zeros((n_objects, MOTION_WIDTH))
    hit = np.empty(HIT_WIDTH, np.int64)
    row = np.empty(PAIR_WIDTH, np.int64)
    for f in range(frame_start, frame_stop):
        rp = poses[f]
        object_margins(ps, rp, rp, margin)
        lo, hi = object_world_boxes(ps, rp, rp, still, 0.0, margin)
        candidates = sweep_and_prune(lo, hi)
        for c in range(candidates.shape[0]):
            a = candidates[c, 0]
            b = candidates[c, 1]
            if not pair_selected(pair_filter, static, a, b):
                continue
            leaves, n_leaves = pair_leaves(ps, rp, rp, still, a, b, RULE_POSE, margin[a] + margin[b], scratch,
                                           leaves)
            if n_leaves == 0:
                continue
            ensure_world(ps, rp, a, f, static, stamp, world)
            ensure_world(ps, rp, b, f, static, stamp, world)
            tri, n_tri = intersecting_triangles(
                leaves, n_leaves, ps.node_first, ps.node_count, ps.prim_ids, ps.faces,
                ps.face_start[ps.object_mesh[a]], ps.face_start[ps.object_mesh[b]],
                world, ps.world_start[a], ps.world_start[b], tri, 0, first_only)
            if n_tri == 0:
                continue
            tri_a, tri_b = _smallest_pair(tri, n_tri)
            hit[HIT_FRAME] = f
            hit[HIT_A] = a
            hit[HIT_B] = b
            hit[HIT_PAIRS] = n_tri
            hit[HIT_TRI_A] = tri_a
            hit[HIT_TRI_B] = tri_b
            hits, n_hits = append_row(hits, n_hits, hit)
            if collect_pairs:
                for k in range(n_tri):
                    row[PAIR_FRAME] = f
                    row[PAIR_A] = a
                    row[PAIR_B] = b
                    row[PAIR_TRI_A] = tri[k, 0]
                    row[PAIR_TRI_B] = tri[k, 1]
                    pairs, n_pairs = append_row(pairs, n_pairs, row)
    return hits[:n_hits].copy(), pairs[:n_pairs].copy()
