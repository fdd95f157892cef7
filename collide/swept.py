"""Continuous detection: contact between frames, under linear vertex motion.

Between frames k and k+1 every world-space vertex moves on a straight line
(SPEC §3, ``interpolation = "linear-vertex"``). ``scan_intervals`` is the
kernel for a chunk of such motion steps. Per step:

1. objects: world boxes bounding each object's motion (its root box at both
   poses), sweep and prune;
2. object pairs: the lecture's swept-sphere test. Each object lies in a sphere
   of radius r around its body centre c; under linear vertex motion the centre
   moves linearly too and every vertex stays within r of it, so with s the
   centre offset at t = 0 and v the relative velocity over the step, the
   spheres can only overlap when (v·v)t² + 2(v·s)t + (s·s − r²) <= 0;
   a pair whose window misses [0, 1] is skipped;
3. BVH leaves: tandem descent with boxes bounding the motion (RULE_SWEPT);
4. triangles: certified CCD (narrow.swept_contact_hulls) gives each touching
   triangle pair's first and last contact time; their union, per object pair,
   is the object pair's contact during the step.

Output rows float64 (R, 7): step k, object_a, object_b, t_begin, t_end (in
[0, 1] of the step), tri_a, tri_b (the pair touching first).
"""
import numpy as np
from numba import njit

from .analytic import sphere_overlap_window
from .broad import RULE_SWEPT, sweep_and_prune
from .discrete import ensure_world, object_world_boxes, pair_leaves, pair_selected
from .narrow import append_row, swept_contact_hulls


@njit(cache=True)
def _world_centre(c, rp):
    out = np.empty(3)
    for i in range(3):
        out[i] = rp[i, 3] + rp[i, 0] * c[0] + rp[i, 1] * c[1] + rp[i, 2] * c[2]
    return out


@njit(cache=True)
def spheres_may_meet(ps, rp0, rp1, a, b, margin):
    """The swept bounding spheres of objects a and b overlap at some t in [0, 1]."""
    mesh_a = ps.object_mesh[a]
    mesh_b = ps.object_mesh[b]
    ca0 = _world_centre(ps.centre[mesh_a], rp0[a])
    ca1 = _world_centre(ps.centre[mesh_a], rp1[a])
    cb0 = _world_centre(ps.centre[mesh_b], rp0[b])
    cb1 = _world_centre(ps.centre[mesh_b], rp1[b])
    s = ca0 - cb0
    v = (ca1 - ca0) - (cb1 - cb0)
    r = ps.sphere_radius[mesh_a] + ps.sphere_radius[mesh_b] + margin
    t_lo, t_hi = sphere_overlap_window(s, v, r)
    return t_lo <= t_hi


@njit(cache=True)
def merge_hulls(hulls, n):
    """Union of time intervals hulls[:n, 0:2]: rows (t_begin, t_end, tri_a, tri_b) of
    each maximal interval, with the triangle pair of its earliest (then smallest) hull."""
    order = np.argsort(hulls[:n, 0], kind="mergesort")
    out = np.empty((n, 4))
    m = -1
    for k in range(n):
        h = hulls[order[k]]
        if m >= 0 and h[0] <= out[m, 1]:
            out[m, 1] = max(out[m, 1], h[1])
            if h[0] == out[m, 0] and (h[2] < out[m, 2] or (h[2] == out[m, 2] and h[3] < out[m, 3])):
                out[m, 2] = h[2]
                out[m, 3] = h[3]
        else:
            m += 1
            out[m] = h
    return out[:m + 1]


@njit(cache=True, nogil=True)
def scan_intervals(ps, poses, static, step_start, step_stop, pair_filter, time_tol, dist_tol):
    """Continuous scan of motion steps k in [step_start, step_stop) (frame k -> k+1).

    ps: PackedScene; poses float64 (T, N, 3, 4); static bool (N,); time_tol in
    units of the step; dist_tol in length units. Returns float64 (R, 7), see
    the module docstring.
    """
    n_objects = poses.shape[1]
    n_world = ps.world_start[n_objects]
    world0 = np.empty((n_world, 3))
    world1 = np.empty((n_world, 3))
    stamp0 = np.full(n_objects, -1, np.int64)
    stamp1 = np.full(n_objects, -1, np.int64)
    margin = np.empty(n_objects)
    rows = np.empty((16, 7))
    n_rows = 0
    leaves = np.empty((256, 2), np.int64)
    hulls = np.empty((64, 4))
    pose = np.empty((4, 3, 4))
    row = np.empty(7)
    for k in range(step_start, step_stop):
        rp0 = poses[k]
        rp1 = poses[k + 1]
        lo, hi = object_world_boxes(ps, rp0, rp1, dist_tol, margin)
        candidates = sweep_and_prune(lo, hi)
        for c in range(candidates.shape[0]):
            a = candidates[c, 0]
            b = candidates[c, 1]
            if not pair_selected(pair_filter, static, a, b):
                continue
            pair_margin = margin[a] + margin[b] + dist_tol
            if not spheres_may_meet(ps, rp0, rp1, a, b, pair_margin):
                continue
            leaves, n_leaves = pair_leaves(ps, rp0, rp1, a, b, RULE_SWEPT, pair_margin, pose, leaves)
            if n_leaves == 0:
                continue
            for o in (a, b):
                ensure_world(ps, rp0, o, k, static, stamp0, world0)
                ensure_world(ps, rp1, o, k + 1, static, stamp1, world1)
            hulls, n_hulls = swept_contact_hulls(
                leaves, n_leaves, ps.node_first, ps.node_count, ps.prim_ids, ps.faces,
                ps.face_start[ps.object_mesh[a]], ps.face_start[ps.object_mesh[b]], world0, world1,
                ps.world_start[a], ps.world_start[b], time_tol, dist_tol, hulls, 0)
            if n_hulls == 0:
                continue
            merged = merge_hulls(hulls, n_hulls)
            for m in range(merged.shape[0]):
                row[0] = k
                row[1] = a
                row[2] = b
                row[3:] = merged[m]
                rows, n_rows = append_row(rows, n_rows, row)
    return rows[:n_rows].copy()
