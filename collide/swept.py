"""Continuous detection: contact between frames.

Between frames k and k+1 (a *step*) objects move as motion.py describes
(``--interpolation``: screw or linear-vertex). ``scan_intervals`` is the
kernel for a chunk of steps. Per step:

0. motion: each object's motion row (motion.step_motions);
1. objects: world boxes bounding each object's motion (its root box at both
   poses, widened by its deviation bound), sweep and prune;
2. object pairs: the lecture's swept-sphere test. Each object lies in a sphere
   of radius r around its body centre c at every moment. The chord of c moves
   linearly; with s the chords' offset at t = 0 and v their relative velocity
   over the step, spheres of radius r_a + r_b + dev (dev: both centres'
   deviation bounds) around the chords can only meet when
   (v·v)t² + 2(v·s)t + (s·s − r²) <= 0; a pair whose window misses [0, 1] is
   skipped; so is one touching at neither frame that stays apart along the line
   through its centres or along either object's axes (apart_along_axes: root
   boxes, then vertices, at both frames, widened by the deviation bounds);
3. BVH leaves: tandem descent with boxes bounding the motion (broad.RULE_SWEPT_RIGID
   under screw motion, RULE_SWEPT under linear-vertex motion);
4. triangles: certified CCD (narrow.candidates_contact_window) gives the object
   pair's first and last contact during the step, over all its triangle pairs.

What touches at the frames spares work: a pair touching at both frames of a
step touches from its start to its end (the step's window runs from the
earliest to the latest contact), so it is not searched; a pair touching at one
frame is searched for the other end only. Either the frame tests
(discrete.scan_frames) have run before and say which pairs touch, or
(``find_frames``) the kernel runs them itself: its first frame's as scan_frames
does (discrete.frame_test; at frame 0 naming each touching pair's smallest
triangle pair, which a contact beginning there reports), then each step's last
frame's as part of the step:
a pair touching at the step's first frame is tested as scan_frames would (the
triangle pair that touched there first, then a descent to the first
intersecting pair); any other pair is tested only if its swept
test gets as far as leaf pairs, and then on those leaf pairs (they hold every
leaf pair overlapping at the last frame), not by a descent of its own; and not
at all if no triangle pair's moving boxes come near each other over the step
(they would at its end if two triangles touched there). So a continuous scan
costs one broad phase and, for most pairs, one descent per step instead of two.

A search for one end only (a contact that ends or begins in the step) stops at
the first triangle pair that cannot move the answer, in the order of their
windows. When the descent finds many leaf pairs (a large patch lifting off or
landing: config.ONE_SIDED_LEAVES), their triangle pairs are not all listed first:
the leaf pairs are opened in the order of their own windows, which hold their
triangle pairs', so only the triangle pairs the search reaches are computed, and
in the same order (_one_sided_window: the same contacts, bit for bit). A pair
apart at the step's start then gets its frame test on the leaf pairs first, to
know whether a contact begins.

Between big meshes (config.PROBED_FACES) under screw motion, such a search avoids
the whole swept descent. Meshes with leaf boxes (config.LEAF_BOX_TRIANGLES) first
probe: frame tests at moments inside the step, halving the part of the step where
the contact's end (beginning) can lie, each stopping at the first touching
triangle pair, find a moment the objects touch; the swept descent then covers
only the step after it (before it), where few leaf pairs come near
(_probed_window). Bigger meshes search best first (_best_first_window): node pairs
wait in a heap keyed by their time windows (broad.rigid_pair_window), the one
whose window reaches furthest toward the answer is opened first, and the search
stops once no window left can move the contact found. Contact times move by at
most the time tolerance either way. A pair of such meshes apart at the step's start
gets its frame test first, on a budget (one that gives up after
config.PROBE_LEAF_PAIRS leaf pairs: then the search above, its frame test from the
swept leaf pairs).

Objects that turn a lot in one step sweep large volumes, and boxes around a
whole step's arc are loose; for such a pair steps 3 and 4 run on equal
sub-steps (motion.substeps), each a small screw motion of its own with tight
boxes: the first sub-step (in time) with a contact gives t_first, the last
one t_last.

Output (layouts in rows.py): hits int64 (H, HIT_WIDTH), the frame contacts found
with ``find_frames`` (as scan_frames' first_only hits, but naming the smallest pair at
a chunk's frame 0, see scan_intervals); ids int64 (R,
SWEPT_WIDTH): step k, object_a, object_b, tri_a, tri_b (the pair touching first);
times float64 (R, TIMES_WIDTH): t_begin, t_end, fractions of the step.
"""
import math
from typing import NamedTuple

import numpy as np

from .analytic import sphere_overlap_window
from .broad import (
    RULE_POSE,
    RULE_SWEPT,
    RULE_SWEPT_RIGID,
    abs_rotation,
    leaf_pair_windows,
    node_box,
    opens_a,
    oriented_boxes_overlap,
    overlapping_leaves,
    relative_pose,
    rigid_deviations,
    rigid_pair_window,
    rigid_placed_node,
    sweep_and_prune,
    with_room,
)
from .ccd import ccd_work
from .discrete import (
    FIRST_HIT_BATCH,
    NEAR_HIT_BATCH,
    _centroid,
    _frame_keys,
    _pair_triangles,
    _placed,
    _still_touching,
    append_hit,
    frame_test,
    key_row,
    object_margin,
    object_margins,
    object_world_boxes,
    pair_leaves,
    pair_scratch,
    start_descent,
)
from .filters import pair_selected
from .jit import njit, njit_borrowing, njit_entry
from .motion import (
    M_ETA,
    M_THETA,
    MOTION_WIDTH,
    SCREW,
    ball_deviation,
    pose_at,
    rotation_magnitudes,
    screw_motion,
    sphere_deviation,
    step_motions,
    substeps,
)
from .narrow import (
    SIDE_WIDTH,
    append_row,
    candidate_contact,
    candidates_contact_window,
    comes_first,
    heap_insert,
    intersecting_triangles,
    leaf_pair_candidates,
    new_pending,
    new_stamps,
    pending_first_key,
    pending_lacks_room,
    pending_of_keys,
    pending_pop,
    pending_push,
    pending_size,
    pending_with_room,
    stamp_is,
    swept_candidates,
    triangle_pair_count,
)
from .packed import NO_LEAF_BOXES, to_world
from .rows import (
    COUNT_LEAF_PAIRS,
    COUNT_NODE_PAIRS,
    COUNT_OBJECT_PAIRS,
    COUNT_SUBSTEPS,
    COUNT_WIDTH,
    HIT_WIDTH,
    PAIR_WIDTH,
    SWEPT_A,
    SWEPT_B,
    SWEPT_STEP,
    SWEPT_TRI_A,
    SWEPT_TRI_B,
    SWEPT_WIDTH,
    T_BEGIN,
    T_END,
    TIMES_WIDTH,
)


@njit(cache=True, inline="always")
def place_pair_leaves(ps, rp0, rp1, k, a, b, static, leaves, n_leaves, stamp0, world0, stamp1, world1):
    """World positions at frames k and k + 1 (poses rp0, rp1 (N, 3, 4)) of the vertices of
    the triangles of the leaf pairs leaves[:n_leaves] of objects a and b, into their rows
    of world0 and world1 (W, 3) whose stamps (narrow.new_stamps) do not hold that frame
    yet (then set to it; static objects: key -2 at every frame). A pair's window reads
    only the triangles of its leaf pairs, so big meshes are not transformed whole at
    every frame. The arithmetic of narrow.placed_triangle. One call per object pair: a
    call costs reference counting for every array it is passed."""
    for side in range(2):
        o = a if side == 0 else b
        base = ps.world_start[o]
        key0 = -2 if static[o] else k
        key1 = -2 if static[o] else k + 1
        mesh = ps.object_mesh[o]
        v_start = ps.vert_start[mesh]
        f_start = ps.face_start[mesh]
        for i in range(n_leaves):
            node = leaves[i, side]
            for j in range(ps.node_first[node], ps.node_first[node] + ps.node_count[node]):
                face = f_start + ps.prim_ids[j]
                for corner in range(3):
                    v = ps.faces[face, corner]
                    row = base + v
                    if not stamp_is(stamp0, row, key0):
                        _place(ps.vertices, v_start + v, rp0[o], world0, row)
                        stamp0[row] = key0
                    if not stamp_is(stamp1, row, key1):
                        _place(ps.vertices, v_start + v, rp1[o], world1, row)
                        stamp1[row] = key1


@njit(cache=True, inline="always")
def _place(vertices, v, pose, world, row):
    """world[row] = vertices[v] placed by pose (3, 4)."""
    x = vertices[v, 0]
    y = vertices[v, 1]
    z = vertices[v, 2]
    for c in range(3):
        world[row, c] = pose[c, 3] + pose[c, 0] * x + pose[c, 1] * y + pose[c, 2] * z


@njit_borrowing
def _world_centre(centre, m, rp, o):
    """Sphere centre (M, 3) of mesh m placed by pose rp (N, 3, 4) of object o: a 3-tuple
    (indices, not array views: no allocation or reference counting per pair and step)."""
    x = centre[m, 0]
    y = centre[m, 1]
    z = centre[m, 2]
    return (rp[o, 0, 3] + rp[o, 0, 0] * x + rp[o, 0, 1] * y + rp[o, 0, 2] * z,
            rp[o, 1, 3] + rp[o, 1, 0] * x + rp[o, 1, 1] * y + rp[o, 1, 2] * z,
            rp[o, 2, 3] + rp[o, 2, 0] * x + rp[o, 2, 1] * y + rp[o, 2, 2] * z)


@njit(cache=True)
def spheres_meet(ps, rp0, rp1, motion, margin, dist_tol, candidates):
    """bool (C,): whether the swept bounding spheres of each candidate object pair (a, b)
    (int64 (C, 2)) overlap at some t in [0, 1], widened by both objects' rounding
    margins (N,) and dist_tol. One call per step: a call costs reference counting for
    every array it is passed, which per pair would cost more than the test itself."""
    centre = ps.centre
    radius = ps.sphere_radius
    object_mesh = ps.object_mesh
    meet = np.empty(candidates.shape[0], np.bool_)
    for c in range(candidates.shape[0]):
        a = candidates[c, 0]
        b = candidates[c, 1]
        mesh_a = object_mesh[a]
        mesh_b = object_mesh[b]
        ca0 = _world_centre(centre, mesh_a, rp0, a)
        ca1 = _world_centre(centre, mesh_a, rp1, a)
        cb0 = _world_centre(centre, mesh_b, rp0, b)
        cb1 = _world_centre(centre, mesh_b, rp1, b)
        s = (ca0[0] - cb0[0], ca0[1] - cb0[1], ca0[2] - cb0[2])
        v = ((ca1[0] - ca0[0]) - (cb1[0] - cb0[0]), (ca1[1] - ca0[1]) - (cb1[1] - cb0[1]),
             (ca1[2] - ca0[2]) - (cb1[2] - cb0[2]))
        dev = 0.0
        if motion[a, M_THETA] != 0.0 or motion[b, M_THETA] != 0.0:  # screw motion: paths bend
            dev = sphere_deviation(motion[a], ca0) + sphere_deviation(motion[b], cb0)
            if dev > 0.0:
                dev += motion[a, M_ETA] + motion[b, M_ETA]
        r = radius[mesh_a] + radius[mesh_b] + margin[a] + margin[b] + dist_tol + dev
        t_lo, t_hi = sphere_overlap_window(s, v, r)
        meet[c] = t_lo <= t_hi
    return meet


#: apart_along_axes reads the vertices of object pairs whose meshes have at most this many
#: together; larger pairs get only its test of their root boxes along the centre line
AXIS_TEST_VERTICES = 1024


@njit(cache=True)
def boxed_meshes(ps):
    """bool (M,): the meshes of at most AXIS_TEST_VERTICES vertices that have a vertex at
    each corner of their root box (so the box is their convex hull, and its extent along
    any direction is theirs: apart_along_axes need not read their vertices)."""
    n_meshes = ps.root.shape[0]
    boxed = np.zeros(n_meshes, np.bool_)
    for mesh in range(n_meshes):
        first, stop = ps.vert_start[mesh], ps.vert_start[mesh + 1]
        if stop - first > AXIS_TEST_VERTICES:
            continue
        node = ps.root[mesh]
        found = 0  # bit c: a vertex sits on corner c (bit i of c: hi along axis i)
        for v in range(first, stop):
            corner = 0
            for i in range(3):
                if ps.vertices[v, i] == ps.node_hi[node, i]:
                    corner |= 1 << i
                elif ps.vertices[v, i] != ps.node_lo[node, i]:
                    corner = -1
                    break
            if corner >= 0:
                found |= 1 << corner
        boxed[mesh] = found == 255
    return boxed


@njit_borrowing
def apart_along_axes(ps, boxed, rp0, rp1, motion, margin, dist_tol, a, b):
    """Objects a and b stay apart all over the step along some simple direction d: every
    point of one stays below every point of the other along d by more than dist_tol plus
    both rounding margins (N,). Directions tried: the line through their sphere centres
    at mid-step, then the axes of both objects' body frames at the step's start.

    Why this holds: a point's chord projects on d linearly in t, so between its values
    at both ends; the point itself stays within its object's deviation bound of its
    chord (0 for linear-vertex motion); a triangle's points are convex combinations of
    its corners. So an object's points stay within its vertices' extent along d over
    both ends of the step, widened by its bound. The root boxes are tried first along
    the centre line (they hold the vertices: a weaker bound, but O(1)); then, for
    meshes with at most AXIS_TEST_VERTICES vertices together, the vertices (the box of
    a ``boxed`` mesh, boxed_meshes, which is as tight): both objects' along the centre
    line, and along one object's axes its box (exact at the step's start) against the
    other's vertices. Unused vertices only weaken it. Shapes whose bounding spheres
    meet while they do not touch (boxes, ellipsoids, bodies side by side or at an
    angle) are told apart here without a descent."""
    mesh_a = ps.object_mesh[a]
    mesh_b = ps.object_mesh[b]
    ca0 = _world_centre(ps.centre, mesh_a, rp0, a)
    ca1 = _world_centre(ps.centre, mesh_a, rp1, a)
    cb0 = _world_centre(ps.centre, mesh_b, rp0, b)
    cb1 = _world_centre(ps.centre, mesh_b, rp1, b)
    d = _unit((cb0[0] + cb1[0]) - (ca0[0] + ca1[0]), (cb0[1] + cb1[1]) - (ca0[1] + ca1[1]),
              (cb0[2] + cb1[2]) - (ca0[2] + ca1[2]))
    gap = (ball_deviation(motion[a], ca0, ps.sphere_radius[mesh_a]) + ball_deviation(motion[b], cb0,
                                                                                    ps.sphere_radius[mesh_b])
           + margin[a] + margin[b] + dist_tol)
    if _extents_apart(_box_extent_along(ps, mesh_a, rp0[a], rp1[a], d),
                      _box_extent_along(ps, mesh_b, rp0[b], rp1[b], d), gap):
        return True
    if (ps.vert_start[mesh_a + 1] - ps.vert_start[mesh_a] + ps.vert_start[mesh_b + 1] - ps.vert_start[mesh_b]
            > AXIS_TEST_VERTICES):
        return False
    if not (boxed[mesh_a] and boxed[mesh_b]) and _extents_apart(  # (both boxed: just tested)
            _extent_along(ps, boxed, mesh_a, rp0[a], rp1[a], d), _extent_along(ps, boxed, mesh_b, rp0[b], rp1[b], d),
            gap):
        return True
    for o, other in ((a, b), (b, a)):  # o's box is exact along its own axes at the step's start
        for i in range(3):
            axis = _unit(rp0[o, 0, i], rp0[o, 1, i], rp0[o, 2, i])
            if _extents_apart(_box_extent_along(ps, ps.object_mesh[o], rp0[o], rp1[o], axis),
                              _extent_along(ps, boxed, ps.object_mesh[other], rp0[other], rp1[other], axis), gap):
                return True
    return False


@njit_borrowing
def _unit(x, y, z):
    """(x, y, z) scaled to length 1; zeros when it has no length (then nothing is apart)."""
    length = math.sqrt(x * x + y * y + z * z)
    if not length > 0.0:
        return 0.0, 0.0, 0.0
    return x / length, y / length, z / length


@njit_borrowing
def _extents_apart(extent_a, extent_b, gap):
    """Intervals (lo, hi) more than gap apart, either one below the other."""
    return extent_a[1] + gap < extent_b[0] or extent_b[1] + gap < extent_a[0]


@njit_borrowing
def _body_direction(pose, d):
    """R^T d (3-tuple) for pose [R | p] (3, 4) and a world direction d (3-tuple)."""
    return (pose[0, 0] * d[0] + pose[1, 0] * d[1] + pose[2, 0] * d[2],
            pose[0, 1] * d[0] + pose[1, 1] * d[1] + pose[2, 1] * d[2],
            pose[0, 2] * d[0] + pose[1, 2] * d[1] + pose[2, 2] * d[2])


@njit_borrowing
def _shift_along(pose, d):
    """d . p for pose [R | p] (3, 4)."""
    return pose[0, 3] * d[0] + pose[1, 3] * d[1] + pose[2, 3] * d[2]


@njit_borrowing
def _extent_along(ps, boxed, mesh, pose0, pose1, d):
    """(lowest, highest) d . x (length units) over the vertices x of mesh placed by pose0
    and by pose1 ((3, 4) each); d a unit 3-tuple; from the root box when the mesh is
    ``boxed``. Computed as (R^T d) . v + d . p: within a few ulps of |v| + |p| of the
    placed vertices' projections, far inside the objects' rounding margins. One pass,
    the four running extremes side by side (independent chains run faster)."""
    if boxed[mesh]:
        return _box_extent_along(ps, mesh, pose0, pose1, d)
    e0, e1, e2 = _body_direction(pose0, d)
    f0, f1, f2 = _body_direction(pose1, d)
    vertices = ps.vertices
    lo0 = lo1 = np.inf
    hi0 = hi1 = -np.inf
    for v in range(ps.vert_start[mesh], ps.vert_start[mesh + 1]):
        x = vertices[v, 0]
        y = vertices[v, 1]
        z = vertices[v, 2]
        s0 = e0 * x + e1 * y + e2 * z
        s1 = f0 * x + f1 * y + f2 * z
        lo0 = min(lo0, s0)
        hi0 = max(hi0, s0)
        lo1 = min(lo1, s1)
        hi1 = max(hi1, s1)
    shift0 = _shift_along(pose0, d)
    shift1 = _shift_along(pose1, d)
    return min(lo0 + shift0, lo1 + shift1), max(hi0 + shift0, hi1 + shift1)


@njit_borrowing
def _box_extent_along(ps, mesh, pose0, pose1, d):
    """_extent_along's bounds from the mesh's root box (it holds the vertices): its
    centre's d . x -+ its half extents against |R^T d|, at both poses (exact when the
    mesh reaches its box's corners)."""
    node = ps.root[mesh]
    lo = np.inf
    hi = -np.inf
    for pose in (pose0, pose1):
        e = _body_direction(pose, d)
        centre = _shift_along(pose, d)
        half = 0.0
        for i in range(3):
            centre += 0.5 * (ps.node_lo[node, i] + ps.node_hi[node, i]) * e[i]
            half += 0.5 * (ps.node_hi[node, i] - ps.node_lo[node, i]) * abs(e[i])
        lo = min(lo, centre - half)
        hi = max(hi, centre + half)
    return lo, hi


class Buffers(NamedTuple):
    """Growable int64 (cap, 2) buffers of one kernel call, passed along and returned
    (grown) by the functions that fill them."""
    stack: np.ndarray        #: node pairs still to open in a tandem descent
    leaves: np.ndarray       #: overlapping leaf pairs
    tri_pairs: np.ndarray    #: candidate triangle pairs (narrow.swept_candidates)
    frame_pairs: np.ndarray  #: intersecting triangle pairs of a frame test


class SubStep(NamedTuple):
    """Buffers for the sub-steps of one object pair (N objects, W world vertex rows;
    only the rows of the pair's two objects are used)."""
    pose0: np.ndarray   #: float64 (N, 3, 4) poses at a sub-step's start
    pose1: np.ndarray   #: float64 (N, 3, 4) and end
    motion: np.ndarray  #: float64 (N, MOTION_WIDTH) motion rows over the sub-step
    world0: np.ndarray  #: float64 (W, 3) world vertices at the sub-step's start
    world1: np.ndarray  #: float64 (W, 3) and end


@njit(cache=True)
def _sub_step_buffers(n_objects, n_world):
    return SubStep(np.empty((n_objects, 3, 4)), np.empty((n_objects, 3, 4)),
                   np.zeros((n_objects, MOTION_WIDTH)), np.empty((n_world, 3)), np.empty((n_world, 3)))


# _window, _sub_step_window, _sub_stepped_window and _pair_window are inlined into
# scan_intervals (numba's inline="always"; each has one or two callers). As functions of
# their own, numba optimised and compiled all the CCD code below them once per level: a
# cold compile of the step scan took 75 s instead of 60 s.
#
# A constant passed from one compiled function to another (True, -1, 0, a module
# constant) is typed as a literal, and each literal value compiles another copy of the
# callee and of everything it calls (three copies of the frame descent made the step
# scan's compile a third longer). Where a callee is also called with variables, the
# calls below pass np.int64(...) / np.bool_(...), which are not literals.

@njit(cache=True, inline="always")
def _candidates(ps, motion, world0, world1, a, b, n_leaves, leaves, dist_tol, tri_pairs, counts, after, before):
    """narrow.swept_candidates of objects a and b (windows meeting [after, before]):
    (tri_pairs, n, windows)."""
    return swept_candidates(leaves, n_leaves, ps.node_first, ps.node_count, ps.prim_ids, ps.faces,
                            ps.face_start[ps.object_mesh[a]], ps.face_start[ps.object_mesh[b]], world0, world1,
                            ps.world_start[a], ps.world_start[b], motion[a], motion[b], dist_tol, after, before,
                            tri_pairs, counts)


@njit(cache=True, inline="always")
def _search(ps, motion, world0, world1, a, b, tri_pairs, n, windows, time_tol, dist_tol, find_first, find_last,
            counts):
    """narrow.candidates_contact_window of objects a and b over the candidates of
    _candidates: (t_first, t_last, tri_a, tri_b)."""
    return candidates_contact_window(tri_pairs, n, windows, ps.faces, ps.face_start[ps.object_mesh[a]],
                                     ps.face_start[ps.object_mesh[b]], world0, world1, ps.world_start[a],
                                     ps.world_start[b], motion[a], motion[b], time_tol, dist_tol, find_first,
                                     find_last, counts)


@njit(cache=True, inline="always")
def _window(ps, motion, world0, world1, a, b, n_leaves, leaves, time_tol, dist_tol, find_first, find_last,
            tri_pairs, counts):
    """Contact window of objects a and b under motion rows (N, MOTION_WIDTH), with world
    vertices world0, world1 at both ends and their n_leaves overlapping leaf pairs:
    _candidates, then _search. Returns (tri_pairs, t_first, t_last, tri_a, tri_b)."""
    tri_pairs, n, windows = _candidates(ps, motion, world0, world1, a, b, n_leaves, leaves, dist_tol, tri_pairs,
                                        counts, -np.inf, np.inf)
    t_first, t_last, tri_a, tri_b = _search(ps, motion, world0, world1, a, b, tri_pairs, n, windows, time_tol,
                                            dist_tol, find_first, find_last, counts)
    return tri_pairs, t_first, t_last, tri_a, tri_b


@njit(cache=True, inline="always")
def _sub_step_window(ps, rp0, rp1, motion, margin, a, b, j, n_sub, pair_margin, time_tol, dist_tol,
                     find_first, sub, pair, buffers, counts):
    """Contact window of objects a and b over sub-step j of n_sub (fractions j / n_sub to
    (j + 1) / n_sub of the step), a screw motion between their poses there. buffers:
    Buffers. Returns (buffers, t_first, t_last, tri_a, tri_b), times as fractions of
    the sub-step."""
    t0 = j / n_sub
    t1 = (j + 1) / n_sub
    for o in (a, b):
        pose_at(motion[o], rp0[o], rp1[o], t0, sub.pose0[o])
        pose_at(motion[o], rp0[o], rp1[o], t1, sub.pose1[o])
        screw_motion(sub.pose0[o], sub.pose1[o], margin[o], sub.motion[o])  # a small turn: never half
    counts[COUNT_SUBSTEPS] += 1
    rule = np.int64(RULE_SWEPT_RIGID)  # not a literal (see above _candidates)
    stack, leaves, n_leaves = pair_leaves(ps, sub.pose0, sub.pose1, sub.motion, a, b, rule, pair_margin, pair,
                                          buffers.stack, buffers.leaves, counts)
    if n_leaves == 0:
        return Buffers(stack, leaves, buffers.tri_pairs, buffers.frame_pairs), np.inf, -np.inf, -1, -1
    for o in (a, b):
        mesh = ps.object_mesh[o]
        body = ps.vertices[ps.vert_start[mesh]:ps.vert_start[mesh + 1]]
        to_world(body, sub.pose0[o], sub.world0, ps.world_start[o])
        to_world(body, sub.pose1[o], sub.world1, ps.world_start[o])
    tri_pairs, t_first, t_last, tri_a, tri_b = _window(ps, sub.motion, sub.world0, sub.world1, a, b, n_leaves,
                                                       leaves, time_tol * n_sub, dist_tol, find_first,
                                                       np.bool_(True), buffers.tri_pairs, counts)
    return Buffers(stack, leaves, tri_pairs, buffers.frame_pairs), t_first, t_last, tri_a, tri_b


@njit_borrowing
def _step_time(j, u, n_sub, upward):
    """Fraction of the step at fraction u of sub-step j of n_sub, rounded down (up when
    upward) unless exact."""
    t = (j + u) / n_sub
    if 0.0 < u < 1.0:
        t = np.nextafter(t, np.inf) if upward else np.nextafter(t, -np.inf)
    return min(max(t, 0.0), 1.0)


@njit(cache=True, inline="always")
def _sub_stepped_window(ps, rp0, rp1, motion, margin, a, b, n_sub, pair_margin, time_tol, dist_tol, sub,
                        pair, buffers, counts):
    """Contact window of objects a and b over the step, from its n_sub sub-steps: the first
    sub-step with a contact gives t_first (and the touching pair), the last one t_last.
    Returns (buffers, t_first, t_last, tri_a, tri_b)."""
    t_first = np.inf
    t_last = -np.inf
    pair_a = -1
    pair_b = -1
    j_first = n_sub
    for j in range(n_sub):
        buffers, first, last, tri_a, tri_b = _sub_step_window(
            ps, rp0, rp1, motion, margin, a, b, j, n_sub, pair_margin, time_tol, dist_tol, np.bool_(True), sub, pair,
            buffers, counts)
        if first < np.inf:
            t_first = _step_time(j, first, n_sub, np.bool_(False))
            t_last = _step_time(j, last, n_sub, np.bool_(True))
            pair_a = tri_a
            pair_b = tri_b
            j_first = j
            break
    for j in range(n_sub - 1, j_first, -1):
        buffers, _, last, _, _ = _sub_step_window(
            ps, rp0, rp1, motion, margin, a, b, j, n_sub, pair_margin, time_tol, dist_tol, np.bool_(False), sub,
            pair,
            buffers, counts)
        if last > -np.inf:
            t_last = _step_time(j, last, n_sub, np.bool_(True))
            break
    return buffers, t_first, t_last, pair_a, pair_b


class FrameTests(NamedTuple):
    """Buffers of the frame tests scan_intervals runs itself (``find_frames``), at each
    step's last frame (N objects, W world vertex rows)."""
    world: np.ndarray   #: float64 (W, 3) world vertices, filled lazily (discrete._placed)
    stamp: np.ndarray   #: int64 the frame each world row was computed for (narrow.new_stamps)
    margin: np.ndarray  #: float64 (N,) rounding margins at the frame (discrete.object_margins)
    still: np.ndarray   #: float64 (N, MOTION_WIDTH) zero motion rows


@njit(cache=True)
def _frame_tests(n_objects, n_world):
    return FrameTests(np.empty((n_world, 3)), new_stamps(n_world), np.empty(n_objects),
                      np.zeros((n_objects, MOTION_WIDTH)))


@njit(cache=True)
def _descent_hit(ps, rp, f, a, b, static, frame, near_a, near_b, scratch, buffers, counts):
    """A triangle pair (tri_a, tri_b) of objects a and b intersecting at frame f (poses rp
    (N, 3, 4)), or (-1, -1): the frame test's tandem descent, stopped at the first one,
    looking near triangle pair (near_a, near_b) first. Returns (buffers, tri_a, tri_b)."""
    first_only = np.bool_(True)  # not a literal: the overload scan_frames compiles (see above _candidates)
    stack, leaves, tri, n_tri = _pair_triangles(ps, rp, frame.still, f, a, b, frame.margin[a] + frame.margin[b],
                                                static, frame.stamp, frame.world, first_only, near_a, near_b, scratch,
                                                buffers.stack, buffers.leaves, buffers.frame_pairs, counts)
    buffers = Buffers(stack, leaves, buffers.tri_pairs, tri)
    if n_tri == 0:
        return buffers, -1, -1
    return buffers, tri[0, 0], tri[0, 1]


@njit(cache=True)
def _probe_hit(ps, rp, key, a, b, static, frame, near_a, near_b, scratch, buffers, counts, max_leaf_pairs):
    """_descent_hit at poses rp (N, 3, 4), world vertices in frame (FrameTests) under stamp
    key ``key``, that gives up ((-1, -1)) after max_leaf_pairs leaf pairs without an
    intersecting triangle pair (discrete._pair_triangles' first-hit search, its own loop:
    the budget's check in the frame tests' loop made discrete scans 1.8 % slower at 1000
    bodies). Returns (buffers, tri_a, tri_b)."""
    stack, tri = buffers.stack, buffers.frame_pairs
    top = start_descent(ps, rp, rp, frame.still, a, b, scratch, stack)
    counts[COUNT_OBJECT_PAIRS] += 1
    guided = near_a >= 0
    if guided:
        _centroid(ps, a, near_a, scratch.toward[0])
        _centroid(ps, b, near_b, scratch.toward[1])
    obj_a = _placed(ps, rp, a, key, static, frame.stamp, frame.world)
    obj_b = _placed(ps, rp, b, key, static, frame.stamp, frame.world)
    lo, hi, first, count = ps.node_lo, ps.node_hi, ps.node_first, ps.node_count
    leaves = buffers.leaves
    n_tri = np.int64(0)
    tested = np.int64(0)
    while top > 0 and n_tri == 0 and tested < max_leaf_pairs:
        stack, top, leaves, n_leaves = overlapping_leaves(
            lo, hi, first, count, ps.leaf_box, ps.leaf_box_shift[ps.object_mesh[a]],
            ps.leaf_box_shift[ps.object_mesh[b]], scratch.pose, scratch.motion, RULE_POSE,
            frame.margin[a] + frame.margin[b], stack, top, leaves, NEAR_HIT_BATCH if guided else FIRST_HIT_BATCH,
            counts, scratch.toward, guided)
        tested += n_leaves
        if n_leaves > 0:
            tri = with_room(tri, np.int64(0), triangle_pair_count(leaves, n_leaves, count))
            n_tri = intersecting_triangles(leaves, n_leaves, first, count, ps.prim_ids, obj_a, obj_b, tri,
                                           np.int64(0), np.bool_(True), scratch.p, scratch.q, counts)
    buffers = Buffers(stack, leaves, buffers.tri_pairs, tri)
    if n_tri == 0:
        return buffers, -1, -1
    return buffers, tri[0, 0], tri[0, 1]


@njit(cache=True, inline="always")
def _leaf_hit(ps, rp, f, a, b, static, frame, scratch, leaves, n_leaves, buffers, counts):
    """_descent_hit from a swept descent's leaf pairs leaves[:n_leaves] instead of a
    descent of its own: they hold every leaf pair that overlaps at frame f, since boxes
    bounding a motion hold the boxes at its poses. The leaf pairs whose boxes overlap
    at frame f go to buffers.stack (free between descents); scratch: discrete.PairScratch
    (its triangles p and q). Returns (buffers, tri_a, tri_b)."""
    lo, hi = ps.node_lo, ps.node_hi
    rel = relative_pose(rp[a], rp[b])
    abs_r = abs_rotation(rel)
    margin = frame.margin[a] + frame.margin[b]
    near = with_room(buffers.stack, np.int64(0), n_leaves)
    n_near = np.int64(0)
    for k in range(n_leaves):
        counts[COUNT_NODE_PAIRS] += 1
        if oriented_boxes_overlap(node_box(lo, hi, leaves[k, 0]), node_box(lo, hi, leaves[k, 1]), rel, abs_r,
                                  margin):
            near[n_near, 0] = leaves[k, 0]
            near[n_near, 1] = leaves[k, 1]
            n_near += 1
    tri = with_room(buffers.frame_pairs, np.int64(0), triangle_pair_count(near, n_near, ps.node_count))
    n_tri = intersecting_triangles(near, n_near, ps.node_first, ps.node_count, ps.prim_ids,
                                   _placed(ps, rp, a, f, static, frame.stamp, frame.world),
                                   _placed(ps, rp, b, f, static, frame.stamp, frame.world),
                                   tri, np.int64(0), np.bool_(True), scratch.p, scratch.q, counts)
    buffers = Buffers(near, buffers.leaves, buffers.tri_pairs, tri)
    if n_tri == 0:
        return buffers, -1, -1
    return buffers, tri[0, 0], tri[0, 1]


@njit(cache=True, inline="always")
def _pair_window(ps, rp0, rp1, motion, margin, k, a, b, static, rule, time_tol, dist_tol, touch0, touch1,
                 find_touch1, one_sided_leaves, probed_faces, probe_leaf_pairs, state, buffers, counts):
    """Contact window (t_first, t_last, tri_a, tri_b) of objects a and b over step k
    (t_first = inf: no contact), whole or in sub-steps (motion.substeps). touch0,
    touch1: whether they touch at the step's first, last frame (then t_first = 0,
    t_last = 1: only the other end is searched). find_touch1: (not touch0) touch1 is
    not known yet; find it (state.frame), with a triangle pair (hit_a, hit_b) touching
    at frame k + 1, (-1, -1) if none. A pair touching at neither frame comes here only if its
    swept spheres meet (spheres_meet). state: Step. Returns (buffers, t_first, t_last,
    tri_a, tri_b, hit_a, hit_b). rule: the descent's broad rule (RULE_SWEPT_RIGID under screw
    motion, RULE_SWEPT under linear-vertex motion); sub-steps (screw motion only) are
    always rigid. one_sided_leaves: config.ONE_SIDED_LEAVES (_one_sided_window).
    probed_faces: config.PROBED_FACES (under screw motion without sub-steps, between big
    meshes (big_pair), a search for one end starts with probes, _probed_window, when both
    have leaf boxes (leaf_boxed_pair), else is best first, _best_first_window; and a
    pair apart at the step's start gets a frame test at k + 1 of its own first, giving up
    after probe_leaf_pairs leaf pairs: then its frame test comes from the swept leaf
    pairs)."""
    pair_margin = margin[a] + margin[b] + dist_tol
    hit_a = hit_b = -1
    n_sub = _pair_substeps(ps, rp0, motion, a, b)
    none = np.int64(-1)  # not a literal (see above _candidates)
    if n_sub == 1 and rule == RULE_SWEPT_RIGID and big_pair(ps, a, b, probed_faces):
        if find_touch1 and not touch0:  # whether a contact begins: a frame test of its own, on a budget
            buffers, hit_a, hit_b = _probe_hit(ps, rp1, k + 1, a, b, static, state.frame, none, none, state.pair,
                                               buffers, counts, probe_leaf_pairs)
            touch1 = hit_a >= 0
            find_touch1 = not touch1  # given up: still unknown (the swept leaf pairs below tell)
        if touch0 != touch1:
            if leaf_boxed_pair(ps, a, b):
                buffers, t, tri_a, tri_b = _probed_window(ps, rp0, rp1, motion, margin, k, a, b, static,
                                                          np.bool_(touch0), pair_margin, time_tol, dist_tol,
                                                          probe_leaf_pairs, state, buffers, counts)
            else:
                buffers, t, tri_a, tri_b = _best_first_window(ps, rp0, rp1, motion, k, a, b, static,
                                                              np.bool_(touch0), pair_margin, time_tol, dist_tol,
                                                              state, buffers, counts)
            if touch0:
                return buffers, 0.0, max(t, 0.0), tri_a, tri_b, hit_a, hit_b
            return buffers, min(t, 1.0), 1.0, tri_a, tri_b, hit_a, hit_b
    if n_sub > 1:
        if find_touch1:
            buffers, hit_a, hit_b = _descent_hit(ps, rp1, k + 1, a, b, static, state.frame, none, none, state.pair,
                                                 buffers, counts)
        buffers, t_first, t_last, tri_a, tri_b = _sub_stepped_window(
            ps, rp0, rp1, motion, margin, a, b, n_sub, pair_margin, time_tol, dist_tol, state.sub, state.pair,
            buffers, counts)
        return buffers, t_first, t_last, tri_a, tri_b, hit_a, hit_b
    stack, leaves, n_leaves = pair_leaves(ps, rp0, rp1, motion, a, b, rule, pair_margin, state.pair, buffers.stack,
                                          buffers.leaves, counts)
    if n_leaves == 0:
        return Buffers(stack, leaves, buffers.tri_pairs, buffers.frame_pairs), np.inf, -np.inf, -1, -1, -1, -1
    if n_leaves >= one_sided_leaves:  # a large search: if the pair touches at one end only, search the other
        buffers = Buffers(stack, leaves, buffers.tri_pairs, buffers.frame_pairs)
        if find_touch1:
            buffers, hit_a, hit_b = _leaf_hit(ps, rp1, k + 1, a, b, static, state.frame, state.pair, leaves,
                                              n_leaves, buffers, counts)
            touch1 = hit_a >= 0
        if touch0 != touch1:
            buffers, t, tri_a, tri_b = _one_sided_window(ps, rp0, rp1, motion, k, a, b, static, n_leaves,
                                                         np.bool_(touch0), -np.inf if touch0 else np.inf, none,
                                                         none, time_tol, dist_tol, state, buffers, counts)
            if touch0:
                return buffers, 0.0, max(t, 0.0), tri_a, tri_b, hit_a, hit_b
            return buffers, min(t, 1.0), 1.0, tri_a, tri_b, hit_a, hit_b
        find_touch1 = False  # touching at neither end: the plain search of both, the frame test done
        stack, leaves = buffers.stack, buffers.leaves
    place_pair_leaves(ps, rp0, rp1, k, a, b, static, leaves, n_leaves, state.stamp0, state.world0, state.stamp1,
                      state.world1)
    tri_pairs, n_candidates, windows = _candidates(ps, motion, state.world0, state.world1, a, b, n_leaves, leaves,
                                                   dist_tol, buffers.tri_pairs, counts, -np.inf, np.inf)
    buffers = Buffers(stack, leaves, tri_pairs, buffers.frame_pairs)
    # two triangles touching at the step's end would be candidates (their windows hold t = 1): with
    # none, the frame test at k + 1 has nothing to find
    if find_touch1 and n_candidates > 0:
        buffers, hit_a, hit_b = _leaf_hit(ps, rp1, k + 1, a, b, static, state.frame, state.pair, leaves, n_leaves,
                                          buffers, counts)
        touch1 = hit_a >= 0
    t_first, t_last, tri_a, tri_b = _search(ps, motion, state.world0, state.world1, a, b, tri_pairs, n_candidates,
                                            windows, time_tol, dist_tol, np.bool_(not touch0), np.bool_(not touch1),
                                            counts)
    if touch0:  # never reached with touch1 too (scan_intervals writes that row itself)
        t_first = 0.0
        t_last = max(t_last, 0.0)
    if touch1:
        t_first = min(t_first, 1.0)
        t_last = 1.0
    return buffers, t_first, t_last, tri_a, tri_b, hit_a, hit_b


#: Probes (frame tests at moments inside the step) that _probed_window spends on finding
#: a moment near a one-sided contact's unknown end: the end is then known to within
#: 2^-CONTACT_PROBES of the step.
CONTACT_PROBES = 5
#: A probe that looks near the pair the last one found gives up after this fraction of
#: config.PROBE_LEAF_PAIRS: where that contact goes on, the first few leaf pairs touch;
#: where it has ended, searching further afield costs more than the descent it could
#: shorten (lift scenes of benchmarks/bench_meshsize.py, kernel time against probes on
#: the full budget: 0.85-1.07x over four scenes).
NEAR_PROBE_SHARE = 8


@njit_borrowing
def big_pair(ps, a, b, probed_faces):
    """Whether both meshes of objects a and b have at least probed_faces triangles
    (config.PROBED_FACES): under screw motion without sub-steps, a search for one end of
    their contact then starts with probes (_probed_window) or is best first
    (_best_first_window; leaf_boxed_pair says which), and a frame test at a step's end
    for them apart at its start gives up after a budget of leaf pairs (_probe_hit)."""
    mesh_a = ps.object_mesh[a]
    mesh_b = ps.object_mesh[b]
    return min(ps.face_start[mesh_a + 1] - ps.face_start[mesh_a],
               ps.face_start[mesh_b + 1] - ps.face_start[mesh_b]) >= probed_faces


@njit_borrowing
def leaf_boxed_pair(ps, a, b):
    """Whether both meshes of objects a and b have oriented leaf boxes
    (config.LEAF_BOX_TRIANGLES): then a search for one end of their contact between big
    meshes starts with probes (_probed_window), else it runs best first
    (_best_first_window)."""
    return (ps.leaf_box_shift[ps.object_mesh[a]] != NO_LEAF_BOXES
            and ps.leaf_box_shift[ps.object_mesh[b]] != NO_LEAF_BOXES)


@njit_borrowing
def _pair_substeps(ps, rp0, motion, a, b):
    """motion.substeps of objects a and b over a step from poses rp0 (N, 3, 4)."""
    mesh_a = ps.object_mesh[a]
    mesh_b = ps.object_mesh[b]
    return substeps(motion[a], motion[b], _world_centre(ps.centre, mesh_a, rp0, a), ps.sphere_radius[mesh_a],
                    _world_centre(ps.centre, mesh_b, rp0, b), ps.sphere_radius[mesh_b])


@njit_borrowing
def _probe_key(k, t):
    """Stamp key (never a frame, -1 or -2) of the world vertices of step k at fraction t,
    a multiple of 2^-CONTACT_PROBES strictly inside the step."""
    scale = 1 << CONTACT_PROBES
    return -3 - (k * scale + np.int64(t * scale))


@njit(cache=True, inline="always")
def _poses_at(ps, rp0, rp1, motion, static, o, t, out):
    """Object o's pose at fraction t of the step into out (N, 3, 4) (motion.pose_at;
    a static object's pose unchanged, bit for bit)."""
    pose_at(motion[o], rp0[o], rp1[o], 0.0 if static[o] else t, out[o])


@njit(cache=True)  # a call of its own: rare, and kept out of scan_intervals' code
def _probed_window(ps, rp0, rp1, motion, margin, k, a, b, static, backwards, pair_margin, time_tol, dist_tol,
                   probe_leaf_pairs, state, buffers, counts):
    """_one_sided_window of objects a and b under screw motion (touching at the step's
    start, backwards, or only at its end), from a descent over only the part of the step
    where the answer can lie. CONTACT_PROBES frame tests at moments in between
    (bisection: each probes the moment halfway between the latest (earliest) one found
    touching and the first (last) one not found touching; a probe gives up after
    probe_leaf_pairs leaf pairs, config.PROBE_LEAF_PAIRS, or an eighth of that when it
    looks near a pair found before: NEAR_PROBE_SHARE) give a moment `known` at which
    they touch; the contact ends (begins) no earlier (later) than that, so the swept
    descent needs only cover [known, 1] ([0, known]): a screw motion of its own between
    the poses there (as a sub-step: the same path). Each probe looks first near the
    triangle pair the last one found; the first, in the descent's own order: what the
    probes find depends on the scene only, not on which pair the frame tests found, so
    neither chunks of steps nor --triangle-pairs change the answer. Returns
    _one_sided_window's (buffers, t, tri_a, tri_b)."""
    sub = state.sub
    probe = state.probe
    near_a = near_b = np.int64(-1)
    known = 0.0 if backwards else 1.0  # the objects touch then
    other = 1.0 - known                 # and do not then
    for _ in range(CONTACT_PROBES):
        mid = 0.5 * (known + other)
        for o in (a, b):
            _poses_at(ps, rp0, rp1, motion, static, o, mid, sub.pose0)
            probe.margin[o] = object_margin(ps, sub.pose0, sub.pose0, o)
        budget = probe_leaf_pairs // NEAR_PROBE_SHARE if near_a >= 0 else probe_leaf_pairs
        buffers, hit_a, hit_b = _probe_hit(ps, sub.pose0, _probe_key(k, mid), a, b, static, probe, near_a, near_b,
                                           state.pair, buffers, counts, budget)
        if hit_a >= 0:
            known = mid
            near_a = hit_a
            near_b = hit_b
        else:
            other = mid
    t0 = known if backwards else 0.0
    t1 = 1.0 if backwards else known
    for o in (a, b):
        _poses_at(ps, rp0, rp1, motion, static, o, t0, sub.pose0)
        _poses_at(ps, rp0, rp1, motion, static, o, t1, sub.pose1)
        screw_motion(sub.pose0[o], sub.pose1[o], margin[o], sub.motion[o])  # part of a turn below half
    rule = np.int64(RULE_SWEPT_RIGID)  # not a literal (see above _candidates)
    stack, leaves, n_leaves = pair_leaves(ps, sub.pose0, sub.pose1, sub.motion, a, b, rule, pair_margin, state.pair,
                                          buffers.stack, buffers.leaves, counts)
    buffers = Buffers(stack, leaves, buffers.tri_pairs, buffers.frame_pairs)
    if known == (0.0 if backwards else 1.0):  # no probe found a contact: the plain one-sided search
        known = -np.inf if backwards else np.inf
    return _one_sided_window(ps, rp0, rp1, motion, k, a, b, static, n_leaves, backwards, known, near_a, near_b,
                             time_tol, dist_tol, state, buffers, counts)


@njit(cache=True)
def _one_sided_window(ps, rp0, rp1, motion, k, a, b, static, n_leaves, backwards, known, known_a, known_b,
                      time_tol, dist_tol, state, buffers, counts):
    """The first contact of objects a and b during step k (backwards: the last), for a pair
    touching at the step's end (start), from the leaf pairs buffers.leaves[:n_leaves] of
    their swept descent: the answer of _search (narrow.candidates_contact_window with
    find_first xor find_last), value for value, without the triangle pairs it would not
    reach. That search tries the pairs in the order their windows open (backwards:
    close), smallest (tri_a, tri_b) first among equals, and stops at the first that
    cannot move the contact found. Here the leaf pairs are opened in that order of their
    own windows (broad.leaf_pair_windows, which hold their triangle pairs'), and a
    triangle pair is tried once no unopened leaf pair can hold one that comes before it:
    the same pairs are tried in the same order with the same limits. known: a moment the
    objects are known to touch (_probed_window; triangle pair (known_a, known_b)), or inf
    (backwards -inf) if none: the search starts from it, as if a triangle pair had been
    found touching then (only contacts before it, backwards after it, are searched for).
    Returns (buffers, t, tri_a, tri_b): t = inf (backwards -inf) and (-1, -1) when none
    touches; tri_a, tri_b forwards only."""
    leaves = buffers.leaves
    windows = leaf_pair_windows(ps.node_lo, ps.node_hi, rp0[a], rp1[a], rp0[b], rp1[b], motion[a], motion[b],
                                dist_tol, leaves, n_leaves)
    keys = np.empty(n_leaves)  # the order of the search: window start, backwards minus window end
    for i in range(n_leaves):
        if windows[i, 0] > windows[i, 1]:
            keys[i] = np.inf  # never near: nor are its triangle pairs
        else:
            keys[i] = -windows[i, 1] if backwards else windows[i, 0]
    # the leaf pairs by (key, index), that is in stable_order(keys), taken one at a time as they
    # are opened: a heap, since the search usually stops after a few (no full sort)
    unopened = pending_of_keys(keys, n_leaves)
    pending = new_pending()
    corners = np.empty((4, 3, 3))  # p0, p1, q0, q1
    work = ccd_work()
    face_a = ps.face_start[ps.object_mesh[a]]
    face_b = ps.face_start[ps.object_mesh[b]]
    # forwards, a pair found touching at `known` itself replaces (known_a, known_b) (comes_first)
    t = known if backwards else np.nextafter(known, np.inf)
    best_a = best_b = -1
    tri_pairs = buffers.tri_pairs
    while True:
        bound = -t if backwards else t  # keys beyond it cannot move the contact found
        leaf_key = pending_first_key(unopened) if pending_size(unopened) > 0 else np.inf
        if pending_size(pending) > 0 and pending_first_key(pending) < leaf_key:
            done, t, best_a, best_b = _try_next_triangle_pair(
                pending, bound, t, best_a, best_b, backwards, ps.faces, face_a, face_b, state.world0, state.world1,
                ps.world_start[a], ps.world_start[b], motion[a], motion[b], time_tol, dist_tol, corners, work, counts)
            if done:
                break
            continue
        if leaf_key > bound or leaf_key == np.inf or (backwards and t == 1.0):
            break  # nothing pending comes before it either
        _, leaf, _ = pending_pop(unopened)
        one = leaves[leaf:leaf + 1]
        n_one = np.int64(1)  # not a literal (see above _candidates)
        place_pair_leaves(ps, rp0, rp1, k, a, b, static, one, n_one, state.stamp0, state.world0, state.stamp1,
                          state.world1)
        # only the triangle pairs the search can still reach: backwards, windows ending at t or
        # later; forwards, starting at t or earlier (t only moves on, toward the step's start)
        tri_pairs, n, tri_windows = _candidates(ps, motion, state.world0, state.world1, a, b, n_one, one, dist_tol,
                                                tri_pairs, counts, t if backwards else -np.inf,
                                                np.inf if backwards else t)
        for r in range(n):
            pending = pending_push(pending, -tri_windows[r, 1] if backwards else tri_windows[r, 0], tri_pairs[r, 0],
                                   tri_pairs[r, 1])
    if not backwards and best_a < 0 and known < np.inf:
        t, best_a, best_b = known, known_a, known_b  # no certified search came earlier
    return Buffers(buffers.stack, leaves, tri_pairs, buffers.frame_pairs), t, best_a, best_b


@njit(cache=True, inline="always")
def _try_next_triangle_pair(pending, bound, t, best_a, best_b, backwards, faces, face_a, face_b, world0, world1,
                            world_a, world_b, motion_a, motion_b, time_tol, dist_tol, corners, work, counts):
    """One step of a one-sided search (_one_sided_window, _best_first_window): pops the
    pending triangle pair with the smallest key and searches it for its first contact
    (backwards: last) that can move the contact found so far, at t (pair best_a, best_b).
    Returns (done, t, best_a, best_b): done when that key lies beyond ``bound`` or,
    backwards, t is already the step's end (nothing left can move the answer)."""
    key, tri_a, tri_b = pending_pop(pending)
    if key > bound or (backwards and t == 1.0):
        return True, t, best_a, best_b
    found = candidate_contact(tri_a, tri_b, faces, face_a, face_b, world0, world1, world_a, world_b, motion_a,
                              motion_b, time_tol, dist_tol, t, backwards, corners, work, counts)
    if backwards:
        return False, max(t, found), best_a, best_b
    if comes_first(found, tri_a, tri_b, t, best_a, best_b):
        return False, found, tri_a, tri_b
    return False, t, best_a, best_b


@njit(cache=True)  # a call of its own: rare, and kept out of scan_intervals' code
def _best_first_window(ps, rp0, rp1, motion, k, a, b, static, backwards, pair_margin, time_tol, dist_tol, state,
                       buffers, counts):
    """The first contact of objects a and b during step k (backwards: the last) under screw
    motion without sub-steps, for a pair touching at the step's end (start), like
    _one_sided_window but from a best-first descent instead of a whole one (the answer is
    certified the same way: the two may differ by at most time_tol, and usually agree
    bit for bit). Node pairs wait in a heap keyed by their window
    (broad.rigid_pair_window: its start, backwards minus its end), triangle pairs in a
    second one keyed by theirs (narrow.swept_candidates), and the smaller key is taken
    next. A triangle pair is searched for its first (last) contact; a node pair is opened
    into child pairs (leaf pairs into their triangle pairs), keeping only those whose
    window reaches the contact found so far. Every contact of a node pair's triangles
    lies in its window, so once the smallest key lies beyond the contact found, nothing
    left can move it. Leaf pairs are not checked along their leaves' normals: pairs of
    meshes that both have oriented leaf boxes take _probed_window instead (_pair_window).
    Returns (buffers, t, tri_a, tri_b): t = inf (backwards -inf) and (-1, -1) when none
    touches; tri_a, tri_b forwards only."""
    lo, hi, first, count = ps.node_lo, ps.node_hi, ps.node_first, ps.node_count
    scratch = state.pair
    start_descent(ps, rp0, rp1, motion, a, b, scratch, buffers.stack)
    counts[COUNT_OBJECT_PAIRS] += 1
    pose = scratch.pose
    rp_a0, rp_a1 = relative_pose(pose[2], pose[0]), relative_pose(pose[3], pose[1])  # A's nodes in B's frame
    rp_b0, rp_b1 = relative_pose(pose[0], pose[2]), relative_pose(pose[1], pose[3])  # B's in A's
    placing_a = (rp_a0, rp_a1, rotation_magnitudes(rp_a0), rotation_magnitudes(rp_a1))
    placing_b = (rp_b0, rp_b1, rotation_magnitudes(rp_b0), rotation_magnitudes(rp_b1))
    dev_a, dev_b = rigid_deviations(lo, hi, pose, scratch.motion, buffers.stack, np.int64(1))
    margin_a = pair_margin + dev_a
    margin_b = pair_margin + dev_b
    nodes = new_pending()
    pending = new_pending()
    one = np.empty((1, 2), np.int64)
    n_one = np.int64(1)  # not a literal (see above _candidates)
    corners = np.empty((4, 3, 3))  # p0, p1, q0, q1
    work = ccd_work()
    face_a = ps.face_start[ps.object_mesh[a]]
    face_b = ps.face_start[ps.object_mesh[b]]
    # the arrays the loop reads, bound once (each read of a tuple's array field counts a reference)
    faces, prim_ids = ps.faces, ps.prim_ids
    world0, world1, stamp0, stamp1 = state.world0, state.world1, state.stamp0, state.stamp1
    motion_a, motion_b = motion[a], motion[b]
    world_a, world_b = ps.world_start[a], ps.world_start[b]
    found_pairs = np.empty((16, 2), np.int64)  # a leaf pair's triangle pairs (leaf_pair_candidates)
    found_windows = np.empty((16, 2))
    side_b = np.empty((4, SIDE_WIDTH))
    t = -np.inf if backwards else np.inf
    best_a = best_b = -1
    root_a = ps.root[ps.object_mesh[a]]
    root_b = ps.root[ps.object_mesh[b]]
    key = _node_pair_key(rigid_placed_node(lo, hi, root_a, placing_a), rigid_placed_node(lo, hi, root_b, placing_b),
                         margin_a, margin_b, backwards, t, counts)
    if key < np.inf:
        heap_insert(nodes, key, root_a, root_b)
    na = nb = np.int64(-1)  # the node pair in hand (none: the next comes from the heaps)
    while True:
        bound = -t if backwards else t  # keys beyond it cannot move the contact found
        if na < 0:
            node_key = pending_first_key(nodes) if pending_size(nodes) > 0 else np.inf
            if pending_size(pending) > 0 and pending_first_key(pending) < node_key:
                done, t, best_a, best_b = _try_next_triangle_pair(
                    pending, bound, t, best_a, best_b, backwards, faces, face_a, face_b, world0, world1, world_a,
                    world_b, motion_a, motion_b, time_tol, dist_tol, corners, work, counts)
                if done:
                    break
                continue
            if node_key > bound or node_key == np.inf or (backwards and t == 1.0):
                break  # nothing pending comes before it either
            _, na, nb = pending_pop(nodes)
        if count[na] == 0 or count[nb] == 0:
            if pending_lacks_room(nodes, 2):
                nodes = pending_with_room(nodes, 2)
            later = pending_first_key(pending) if pending_size(pending) > 0 else np.inf
            na, nb = _open_node_pair(nodes, lo, hi, first, count, na, nb, placing_a, placing_b, margin_a, margin_b,
                                     backwards, t, min(bound, later), counts)
            continue
        one[0, 0] = na
        one[0, 1] = nb
        na = nb = np.int64(-1)
        counts[COUNT_LEAF_PAIRS] += 1
        place_pair_leaves(ps, rp0, rp1, k, a, b, static, one, n_one, stamp0, world0, stamp1, world1)
        leaf_a, leaf_b = one[0, 0], one[0, 1]
        if count[leaf_a] * count[leaf_b] > found_pairs.shape[0] or count[leaf_b] > side_b.shape[0]:
            found_pairs = np.empty((count[leaf_a] * count[leaf_b], 2), np.int64)
            found_windows = np.empty((count[leaf_a] * count[leaf_b], 2))
            side_b = np.empty((count[leaf_b], SIDE_WIDTH))
        # only the triangle pairs the search can still reach (as _one_sided_window)
        n = leaf_pair_candidates(leaf_a, leaf_b, first, count, prim_ids, faces, face_a, face_b, world0, world1,
                                 world_a, world_b, motion_a, motion_b, dist_tol, t if backwards else -np.inf,
                                 np.inf if backwards else t, side_b, found_pairs, found_windows, np.int64(0), counts)
        if pending_lacks_room(pending, n):
            pending = pending_with_room(pending, n)
        for r in range(n):
            heap_insert(pending, -found_windows[r, 1] if backwards else found_windows[r, 0], found_pairs[r, 0],
                        found_pairs[r, 1])
    return buffers, t, best_a, best_b


@njit(cache=True, inline="always")
def _node_pair_key(node_a, node_b, margin_a, margin_b, backwards, t, counts, both=True):
    """_best_first_window's key of a node pair (broad.rigid_placed_node pairs): its
    window's start (backwards minus its end; broad.rigid_pair_window, seen from both
    sides when ``both``: leaf pairs), inf when the window is empty or does not reach
    contact time t (backwards: ends before t; forwards: starts after t)."""
    counts[COUNT_NODE_PAIRS] += 1
    t_lo, t_hi = rigid_pair_window(node_a, node_b, margin_a, margin_b, both)
    if t_lo > t_hi or (t_hi < t if backwards else t_lo > t):
        return np.inf
    return -t_hi if backwards else t_lo


@njit(cache=True, inline="always")
def _open_node_pair(nodes, lo, hi, first, count, na, nb, placing_a, placing_b, margin_a, margin_b, backwards, t,
                    limit, counts):
    """Open node pair (na, nb) (at least one inner node; broad.opens_a says which) into
    its two child pairs, keyed by _node_pair_key. The first of them (smaller key, then
    smaller ids) is returned to be opened next when its key is at most ``limit`` (the
    smallest key waiting elsewhere, and the search's bound), and the rest go into nodes
    (a narrow.Pending with room for two); returns (-1, -1) when none is returned."""
    if opens_a(count[na] > 0, count[nb] > 0, node_box(lo, hi, na), node_box(lo, hi, nb)):
        kept = rigid_placed_node(lo, hi, nb, placing_b)
        a0, b0, a1, b1 = first[na], nb, first[na] + 1, nb
        key0 = _node_pair_key(rigid_placed_node(lo, hi, a0, placing_a), kept, margin_a, margin_b, backwards, t, counts,
                              count[a0] > 0 and count[b0] > 0)
        key1 = _node_pair_key(rigid_placed_node(lo, hi, a1, placing_a), kept, margin_a, margin_b, backwards, t, counts,
                              count[a1] > 0 and count[b1] > 0)
    else:
        kept = rigid_placed_node(lo, hi, na, placing_a)
        a0, b0, a1, b1 = na, first[nb], na, first[nb] + 1
        key0 = _node_pair_key(kept, rigid_placed_node(lo, hi, b0, placing_b), margin_a, margin_b, backwards, t, counts,
                              count[a0] > 0 and count[b0] > 0)
        key1 = _node_pair_key(kept, rigid_placed_node(lo, hi, b1, placing_b), margin_a, margin_b, backwards, t, counts,
                              count[a1] > 0 and count[b1] > 0)
    if key1 < key0 or (key1 == key0 and (a1 < a0 or (a1 == a0 and b1 < b0))):
        key0, a0, b0, key1, a1, b1 = key1, a1, b1, key0, a0, b0
    if key1 < np.inf:
        heap_insert(nodes, key1, a1, b1)
    if key0 == np.inf:
        return np.int64(-1), np.int64(-1)
    if key0 <= limit and (pending_size(nodes) == 0 or key0 <= pending_first_key(nodes)):
        return a0, b0
    heap_insert(nodes, key0, a0, b0)
    return np.int64(-1), np.int64(-1)


@njit_borrowing
def step_pair_key(k, a, b, n_objects):
    """int64 key of object pair (a, b) at frame (or step) k, ordered by k, then a, then b."""
    return (k * n_objects + a) * n_objects + b


@njit(cache=True)
def _frame_contacts(touching, touching_tris, k, n_objects):
    """The frame-k rows of touching (sorted step_pair_key) and touching_tris (H, 2), as
    sorted keys a * N + b (discrete._frame_keys) and their triangle pairs."""
    start = np.searchsorted(touching, step_pair_key(k, 0, 0, n_objects))
    stop = np.searchsorted(touching, step_pair_key(k + 1, 0, 0, n_objects))
    return touching[start:stop] - step_pair_key(k, 0, 0, n_objects), touching_tris[start:stop]


class Step(NamedTuple):
    """Fixed-size buffers of one scan_intervals call (N objects, W world vertex rows)."""
    world0: np.ndarray  #: float64 (W, 3) world vertices at the step's start (rows of objects in use)
    world1: np.ndarray  #: float64 (W, 3) and end
    stamp0: np.ndarray  #: int64 the frame (-2: static) each row of world0 was computed for (narrow.new_stamps)
    stamp1: np.ndarray  #: int64 and of world1
    sub: SubStep
    pair: object        #: discrete.PairScratch
    frame: FrameTests
    probe: FrameTests   #: frame tests inside a step (_probed_window)


@njit(cache=True)
def _step_buffers(n_objects, n_world, find_frames):
    """scan_intervals' buffers for N objects and W world vertex rows: (Step, Buffers,
    counts int64 (COUNT_WIDTH,))."""
    state = Step(np.empty((n_world, 3)), np.empty((n_world, 3)), new_stamps(n_world), new_stamps(n_world),
                 _sub_step_buffers(n_objects, n_world),
                 pair_scratch(),
                 _frame_tests(n_objects, n_world if find_frames else 0), _frame_tests(n_objects, n_world))
    buffers = Buffers(np.empty((64, 2), np.int64), np.empty((256, 2), np.int64), np.empty((64, 2), np.int64),
                      np.empty((64, 2), np.int64))
    return state, buffers, np.zeros(COUNT_WIDTH, np.int64)


@njit_entry
def compile_contact_searches(ps, poses, static, time_tol, dist_tol):
    """Compiles (and caches) the three searches for a contact's moment that scan_intervals
    calls, _one_sided_window, _best_first_window and narrow.candidates_contact_window
    (with the CCD below them), with the argument types it calls them with, without
    running them: for collide.warmup, so that another process can compile them while
    scan_intervals compiles the rest. Takes scan_intervals' ps, poses, static, time_tol and dist_tol;
    returns nothing."""
    n_objects = poses.shape[1]
    state, buffers, counts = _step_buffers(n_objects, ps.world_start[n_objects], np.bool_(True))
    motion = np.empty((n_objects, MOTION_WIDTH))
    none = np.int64(-1)
    if n_objects >= 0:  # always: the calls below are compiled, never run
        return
    _one_sided_window(ps, poses[0], poses[0], motion, none, none, none, static, none, np.bool_(True), np.inf, none,
                      none, time_tol, dist_tol, state, buffers, counts)
    _best_first_window(ps, poses[0], poses[0], motion, none, none, none, static, np.bool_(True), time_tol, time_tol,
                       dist_tol, state, buffers, counts)
    _search(ps, motion, state.world0, state.world1, none, none, buffers.tri_pairs, none, state.sub.motion,
            time_tol, dist_tol, np.bool_(True), np.bool_(True), counts)


@njit_entry
def scan_intervals(ps, poses, static, pairs, touching, touching_tris, step_start, step_stop, find_frames,
                   interpolation, time_tol, dist_tol, one_sided_leaves, probed_faces, probe_leaf_pairs):
    """Continuous scan of motion steps k in [step_start, step_stop) (frame k -> k+1).

    ps: PackedScene; poses float64 (T, N, 3, 4); static bool (N,) (objects that never
    move); pairs: filters.PairFilter; touching: int64 sorted step_pair_key of the
    object pairs the frame tests found touching, touching_tris int64 (H, 2) a
    triangle pair of each (a pair touching at both frames of a step touches over the
    whole step: no search; at one frame: only the other end is searched);
    find_frames: touching is not read; the kernel runs the frame tests of frames
    step_start (when there are steps) to step_stop itself, each but the first with the
    step that ends there (a pair whose swept test finds nothing cannot touch at the step's last
    frame; one that needs a swept search gets its frame test from the swept leaf
    pairs, without a descent of its own); interpolation: a motion.INTERPOLATIONS code;
    time_tol in units of the step; dist_tol in length units; one_sided_leaves:
    config.ONE_SIDED_LEAVES (how large a search of one end of a contact reads its leaf
    pairs in time order; only affects speed); probed_faces: config.PROBED_FACES (how
    large both meshes of a pair whose search of one end starts with probes or runs best
    first; moves contact times by at most time_tol); probe_leaf_pairs:
    config.PROBE_LEAF_PAIRS (when a probe, or the frame test at a step's end of such a
    pair apart at its start, gives up; moves contact times by at most time_tol). Returns (hits int64 (H,
    HIT_WIDTH), the frame tests' hits (none without find_frames; the first pair
    found, but the smallest at frame 0 when step_start is 0: a contact that begins
    there reports it without a search of its own, HIT_SMALLEST),
    ids int64 (R, SWEPT_WIDTH), times float64 (R, TIMES_WIDTH), counts int64
    (COUNT_WIDTH,)), see the module docstring.
    """
    n_objects = poses.shape[1]
    n_world = ps.world_start[n_objects]
    state, buffers, counts = _step_buffers(n_objects, n_world, find_frames)
    margin = np.empty(n_objects)
    motion = np.empty((n_objects, MOTION_WIDTH))
    hits = np.empty((16, HIT_WIDTH), np.int64)
    n_hits = np.int64(0)
    hit = np.empty(HIT_WIDTH, np.int64)
    ids = np.empty((16, SWEPT_WIDTH), np.int64)
    times = np.empty((16, TIMES_WIDTH))
    n_rows = np.int64(0)
    id_row = np.empty(SWEPT_WIDTH, np.int64)
    time_row = np.empty(TIMES_WIDTH)
    rule = RULE_SWEPT_RIGID if interpolation == SCREW else RULE_SWEPT
    sweep_order = np.arange(n_objects)  # sweep_and_prune's, carried from step to step
    boxed = boxed_meshes(ps)
    if find_frames and step_stop > step_start:  # frame step_start's test; the others come with their steps
        stack, leaves, frame_pairs = buffers.stack, buffers.leaves, buffers.frame_pairs
        hits, n_hits, _, _, stack, leaves, frame_pairs = frame_test(
            ps, poses[step_start], step_start, static, pairs, state.frame.margin, state.frame.still, state.frame.stamp,
            state.frame.world, sweep_order, np.zeros(0, np.int64), np.zeros((0, 2), np.int64), np.bool_(False),
            np.bool_(True), np.bool_(step_start == 0), state.pair, stack, leaves, frame_pairs, hit, hits, n_hits,
            np.empty(PAIR_WIDTH, np.int64), np.empty((0, PAIR_WIDTH), np.int64), np.int64(0), counts)
        buffers = Buffers(stack, leaves, buffers.tri_pairs, frame_pairs)
        # (at frame 0 the smallest pairs: a row of a pair touching from the step's start
        # names one, sorted after the frame hit that starts the same contact)
        keys0, tris0 = _frame_keys(hits, 0, n_hits, n_objects)
    else:
        keys0, tris0 = _frame_contacts(touching, touching_tris, step_start, n_objects)
    keys1, tris1 = keys0, tris0
    for k in range(step_start, step_stop):
        rp0 = poses[k]
        rp1 = poses[k + 1]
        object_margins(ps, rp0, rp1, margin)
        step_motions(interpolation, rp0, rp1, margin, motion)
        lo, hi = object_world_boxes(ps, rp0, rp1, motion, dist_tol, margin)
        candidates = sweep_and_prune(lo, hi, sweep_order)
        meet = spheres_meet(ps, rp0, rp1, motion, margin, dist_tol, candidates)
        step_hits = n_hits
        if find_frames:
            object_margins(ps, rp1, rp1, state.frame.margin)
        else:
            keys1, tris1 = _frame_contacts(touching, touching_tris, k + 1, n_objects)
        for c in range(candidates.shape[0]):
            a = candidates[c, 0]
            b = candidates[c, 1]
            if not pair_selected(pairs, a, b):
                continue
            key = a * n_objects + b
            row0 = key_row(keys0, key)
            touch0 = row0 >= 0
            hit_a = hit_b = -1  # a triangle pair touching at frame k + 1 found here (find_frames)
            if not find_frames:
                touch1 = key_row(keys1, key) >= 0
            elif touch0:  # as discrete.scan_frames: the pair that touched at frame k first
                near_a, near_b = tris0[row0, 0], tris0[row0, 1]
                if _still_touching(ps, rp1, k + 1, a, b, static, state.frame.stamp, state.frame.world, near_a,
                                   near_b, state.pair, buffers.frame_pairs, counts):
                    hit_a, hit_b = near_a, near_b
                else:
                    buffers, hit_a, hit_b = _descent_hit(ps, rp1, k + 1, a, b, static, state.frame, near_a, near_b,
                                                         state.pair, buffers, counts)
                touch1 = hit_a >= 0
            else:
                touch1 = False
            if touch0 and touch1:  # the whole step
                t_first, t_last, tri_a, tri_b = 0.0, 1.0, tris0[row0, 0], tris0[row0, 1]
            elif not (touch0 or touch1) and (not meet[c] or apart_along_axes(ps, boxed, rp0, rp1, motion, margin,
                                                                                 dist_tol, a, b)):
                continue  # apart all along, so at the step's last frame too
            else:
                buffers, t_first, t_last, tri_a, tri_b, found_a, found_b = _pair_window(
                    ps, rp0, rp1, motion, margin, k, a, b, static, rule, time_tol, dist_tol, np.bool_(touch0),
                    np.bool_(touch1), np.bool_(find_frames and not touch0), one_sided_leaves, probed_faces,
                    probe_leaf_pairs, state, buffers, counts)
                if not touch0:
                    hit_a, hit_b = found_a, found_b
                elif t_first < np.inf:
                    tri_a, tri_b = tris0[row0, 0], tris0[row0, 1]
            if hit_a >= 0:
                hits, n_hits = append_hit(hits, n_hits, hit, k + 1, a, b, np.int64(1), hit_a, hit_b, np.bool_(False))
            if t_first == np.inf:
                continue
            id_row[SWEPT_STEP] = k
            id_row[SWEPT_A] = a
            id_row[SWEPT_B] = b
            id_row[SWEPT_TRI_A] = tri_a
            id_row[SWEPT_TRI_B] = tri_b
            time_row[T_BEGIN] = t_first
            time_row[T_END] = t_last
            ids, _ = append_row(ids, n_rows, id_row)
            times, n_rows = append_row(times, n_rows, time_row)
        if find_frames:
            keys1, tris1 = _frame_keys(hits, step_hits, n_hits, n_objects)
        keys0, tris0 = keys1, tris1
        # frame k + 1 ends this step and starts the next: its world vertices move over
        # (swapping the buffers and their stamps), so no frame is transformed twice
        state = Step(state.world1, state.world0, state.stamp1, state.stamp0, state.sub, state.pair, state.frame,
                     state.probe)
    return hits[:n_hits].copy(), ids[:n_rows].copy(), times[:n_rows].copy(), counts
