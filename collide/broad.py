"""Broad phase: which objects, and which BVH leaves of two objects, may touch.

Two levels:

1. Between objects, per frame: world boxes of whole objects, then
   ``sweep_and_prune`` (sort box starts along one axis, sweep) so that N
   objects never cost N² box tests.
2. Between two objects: ``overlapping_leaves`` descends both BVHs in tandem
   with an explicit stack and collects the leaf pairs whose boxes overlap under
   one of two rules:

   - ``RULE_POSE``: the objects at one pose. B's node boxes become oriented
     boxes in A's body frame, tested against A's axis-aligned node boxes with
     the separating-axis theorem (15 axes); a leaf pair also along both leaves'
     normals (leaves_apart_along_normals_at), as under RULE_SWEPT_RIGID below.
   - ``RULE_SWEPT``: the objects moving from pose 0 to pose 1 over one step.
     Each point's chord (straight path between its two end positions) stays
     inside the union of its world boxes at both ends, and its real path
     within the deviation bound of the motion (motion.py) of that chord: the
     union widened by the bound holds the node over the whole step. One bound
     per object serves its whole descent: that of the node it starts from
     (every node below lies in its box). Bounds per node would be tighter
     (the bound is theta^2 / 8 times the distance to the screw axis, theta the
     step's turn), but on the benchmark scenes they saved under 1 % of the
     node pairs and cost a quarter of the descent's time.
   - ``RULE_SWEPT_RIGID``: the same step when both objects move rigidly (screw
     motion; not linear-vertex motion, under which they deform). Each node's box
     is placed in the other object's body frame, at both ends of the step, and the
     union of the two placements, widened by how far a point's path seen from
     the other object can stray from its chord (rigid_frame_deviation), must
     overlap the other node's own box, in both frames. Boxes in world axes are
     loose for objects turned to them; here only one box of each test is turned.
     On the benchmark scenes: 27 % (4 bodies) and 68 % (100 bodies) fewer node
     pairs than RULE_SWEPT, 16 % and 73 % fewer leaf pairs. A leaf pair must
     also overlap along both leaves' normals, with their oriented boxes
     (leaves_apart_along_normals): a leaf is mostly a nearly flat patch, and
     patches facing each other across a gap have overlapping axis-aligned boxes.

Poses are passed as ``pose`` float64 (4, 3, 4): rows [R | p] of A at pose 0,
A at pose 1, B at pose 0, B at pose 1 (world x = R @ body x + p); RULE_POSE
reads only rows 0 and 2. ``motion`` float64 (2, MOTION_WIDTH): the motion rows
(motion.py) of A and B over the step; only RULE_SWEPT reads it.

Every box test is widened by ``margin`` (scene length units) so that rounding
never drops a pair the exact narrow phase would report.
"""
import math

import numpy as np

from .jit import njit, njit_borrowing
from .motion import (
    M_ETA,
    M_THETA,
    box_deviation,
    box_deviation_of,
    centre_and_half,
    chord_interval,
    motion_tuple,
    placed_interval,
    pose_tuple,
    rotation_magnitudes,
    sphere_deviation,
)
from .packed import LEAF_AXES, LEAF_NORMAL_HI, LEAF_NORMAL_LO, LEAF_SIZE, NO_LEAF_BOXES, extent_along
from .rows import COUNT_LEAF_PAIRS, COUNT_NODE_PAIRS
from .windows import box_window

RULE_POSE = 0
RULE_SWEPT = 1
RULE_SWEPT_RIGID = 2

#: added to |R| entries of the SAT test so that near-parallel edge axes
#: (cross products close to zero) cannot cause a false separation
_ABS_R_EPS = 1e-12


# --- level 1: object pairs ----------------------------------------------------------

@njit(cache=True)
def sweep_and_prune(lo, hi, order):
    """Pairs (a, b), a < b, of overlapping closed boxes.

    lo, hi float64 (N, 3) -> int64 (K, 2), sorted by (a, b).
    Sorts box starts along the axis of largest spread and sweeps, so the cost
    is O(N log N + K) for boxes that are not all stacked along that axis.
    order: int64 (N,) a permutation of range(N), kept by the caller from one call to the
    next (np.arange(N) before the first): the boxes' sweep order, sorted here in place
    starting from the last call's. Objects move little between frames, so it is nearly
    sorted already and the sort nearly linear (sort_nearly_sorted).
    """
    n = lo.shape[0]
    axis = _widest_axis(lo)
    starts = np.empty(n)
    for i in range(n):
        starts[i] = lo[i, axis]
    sort_nearly_sorted(starts, order)
    # the boxes in sweep order, the sweep axis first: the inner loop reads memory in order
    box = np.empty((n, 6))
    for s in range(n):
        for c in range(3):
            box[s, c] = lo[order[s], (axis + c) % 3]
            box[s, 3 + c] = hi[order[s], (axis + c) % 3]
    pairs = np.empty((max(n, 4), 2), np.int64)
    k = 0
    for s in range(n):
        s_lo0, s_lo1, s_lo2, s_hi0, s_hi1, s_hi2 = box[s, 0], box[s, 1], box[s, 2], box[s, 3], box[s, 4], box[s, 5]
        end = s + 1  # boxes s + 1 .. end - 1 start within box s along the sweep axis
        while end < n and not box[end, 0] > s_hi0:
            end += 1
        if pairs.shape[0] < k + end - s:  # rebound only when it grows (see with_room)
            pairs = with_room(pairs, k, k + end - s)
        for r in range(s + 1, end):
            # without a branch: every candidate is written, and kept (k + 1) when the boxes
            # also meet along the other axes. Most do not, unpredictably: branching on that
            # cost 0.49 ms per call at 1000 bodies, this 0.30 ms
            apart = (s_lo0 > box[r, 3]) | (box[r, 1] > s_hi1) | (s_lo1 > box[r, 4]) | (box[r, 2] > s_hi2) \
                | (s_lo2 > box[r, 5])
            pairs[k, 0] = s
            pairs[k, 1] = r
            k += 1 - np.int64(apart)
    for i in range(k):  # sweep positions -> box indices, smaller first
        a = order[pairs[i, 0]]
        b = order[pairs[i, 1]]
        pairs[i, 0] = min(a, b)
        pairs[i, 1] = max(a, b)
    return pairs_by_a_b(pairs, k, n)


@njit(cache=True)
def sort_nearly_sorted(keys, order):
    """Sort order (int64 (N,), a permutation) in place so that keys[order] ascends: by
    insertion, which costs one step per position an element moves, so little on an
    order that is nearly sorted already; once the moves exceed a few per element (the
    keys changed a lot, or the sweep axis did), a merge sort of keys instead. Ties may
    end up in either order."""
    n = order.shape[0]
    budget = 8 * n + 64
    moves = 0
    for i in range(1, n):
        j = order[i]
        key = keys[j]
        p = i - 1
        while p >= 0 and keys[order[p]] > key:
            order[p + 1] = order[p]
            p -= 1
        order[p + 1] = j
        moves += i - 1 - p
        if moves > budget:
            order[:] = np.argsort(keys, kind="mergesort")
            return


@njit(cache=True)
def pairs_by_a_b(pairs, k, n):
    """Rows pairs[:k] (a, b), 0 <= a, b < n, sorted by (a, b): int64 (k, 2), a new array.
    Two counting-sort passes (by b, then stably by a): O(k + n), against a merge sort of
    keys a * n + b that took most of sweep_and_prune's sorting time at 1000 bodies."""
    start = np.empty(n + 1, np.int64)
    by_b = np.empty((k, 2), np.int64)
    _counting_pass(pairs, k, 1, start, by_b)
    out = np.empty((k, 2), np.int64)
    _counting_pass(by_b, k, 0, start, out)
    return out


@njit_borrowing
def _counting_pass(rows, k, column, start, out):
    """Stable counting sort of rows[:k] by rows[:, column] (values in [0, n)) into out;
    start: int64 (n + 1,) scratch."""
    n = start.shape[0] - 1
    start[:] = 0
    for r in range(k):
        start[rows[r, column] + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    for r in range(k):
        v = rows[r, column]
        out[start[v], 0] = rows[r, 0]
        out[start[v], 1] = rows[r, 1]
        start[v] += 1


@njit_borrowing
def _widest_axis(lo):
    """The axis (0, 1 or 2) along which the rows of lo (N, 3) spread most (0 if N == 0)."""
    axis = 0
    widest = -1.0
    for a in range(3):
        low = np.inf
        high = -np.inf
        for i in range(lo.shape[0]):
            low = min(low, lo[i, a])
            high = max(high, lo[i, a])
        if high - low > widest:
            axis = a
            widest = high - low
    return axis


# --- level 2: tandem descent --------------------------------------------------------

@njit_borrowing
def relative_pose(rp_a, rp_b):
    """[R | t] mapping B's body frame into A's body frame, from poses rp_a, rp_b (3, 4):
    a 12-tuple, row by row (r00, r01, r02, t0, r10, ...). A tuple, not an array: it is
    passed to the node-pair test of every step of a descent, and a tuple costs no
    reference counting."""
    return (_rotated(rp_a, rp_b, 0, 0), _rotated(rp_a, rp_b, 0, 1), _rotated(rp_a, rp_b, 0, 2),
            _shifted(rp_a, rp_b, 0),
            _rotated(rp_a, rp_b, 1, 0), _rotated(rp_a, rp_b, 1, 1), _rotated(rp_a, rp_b, 1, 2),
            _shifted(rp_a, rp_b, 1),
            _rotated(rp_a, rp_b, 2, 0), _rotated(rp_a, rp_b, 2, 1), _rotated(rp_a, rp_b, 2, 2),
            _shifted(rp_a, rp_b, 2))


@njit_borrowing
def _rotated(rp_a, rp_b, i, j):
    """Entry (i, j) of R_a^T R_b."""
    s = 0.0
    for k in range(3):
        s += rp_a[k, i] * rp_b[k, j]
    return s


@njit_borrowing
def _shifted(rp_a, rp_b, i):
    """Entry i of R_a^T (p_b - p_a)."""
    s = 0.0
    for k in range(3):
        s += rp_a[k, i] * (rp_b[k, 3] - rp_a[k, 3])
    return s


@njit_borrowing
def abs_rotation(rel):
    """|R| + a small epsilon of rel = [R | t] (relative_pose): a 9-tuple, row by row, for
    oriented_boxes_overlap."""
    e = _ABS_R_EPS
    return (abs(rel[0]) + e, abs(rel[1]) + e, abs(rel[2]) + e, abs(rel[4]) + e, abs(rel[5]) + e,
            abs(rel[6]) + e, abs(rel[8]) + e, abs(rel[9]) + e, abs(rel[10]) + e)


@njit_borrowing
def node_box(lo, hi, n):
    """Box n of node arrays lo, hi (n, 3) as a 6-tuple (lo x, y, z, hi x, y, z)."""
    return lo[n, 0], lo[n, 1], lo[n, 2], hi[n, 0], hi[n, 1], hi[n, 2]


@njit_borrowing
def oriented_boxes_overlap(box_a, box_b, rel, abs_r, margin):
    """Boxes box_a (axis-aligned in A's frame) and box_b (in B's frame, placed in A's frame
    by rel = [R | t]), 6-tuples (node_box), overlap by the separating-axis test (15
    axes); margin (length units) widens the test.

    rel: relative_pose 12-tuple; abs_r: |R| + a small epsilon (abs_rotation), computed
    once per descent. Tuples and scalars only: this is the hottest test of a descent,
    and array arguments would cost reference counting on every call.
    """
    ea0 = 0.5 * (box_a[3] - box_a[0])
    ea1 = 0.5 * (box_a[4] - box_a[1])
    ea2 = 0.5 * (box_a[5] - box_a[2])
    eb0 = 0.5 * (box_b[3] - box_b[0])
    eb1 = 0.5 * (box_b[4] - box_b[1])
    eb2 = 0.5 * (box_b[5] - box_b[2])
    cb0 = 0.5 * (box_b[0] + box_b[3])
    cb1 = 0.5 * (box_b[1] + box_b[4])
    cb2 = 0.5 * (box_b[2] + box_b[5])
    # centre of B minus centre of A, in A's frame
    t0 = rel[3] + rel[0] * cb0 + rel[1] * cb1 + rel[2] * cb2 - 0.5 * (box_a[0] + box_a[3])
    t1 = rel[7] + rel[4] * cb0 + rel[5] * cb1 + rel[6] * cb2 - 0.5 * (box_a[1] + box_a[4])
    t2 = rel[11] + rel[8] * cb0 + rel[9] * cb1 + rel[10] * cb2 - 0.5 * (box_a[2] + box_a[5])
    ea = (ea0, ea1, ea2)
    eb = (eb0, eb1, eb2)
    t = (t0, t1, t2)
    # axes of A
    for i in range(3):
        rb = eb0 * abs_r[3 * i] + eb1 * abs_r[3 * i + 1] + eb2 * abs_r[3 * i + 2]
        if abs(t[i]) > ea[i] + rb + margin:
            return False
    # axes of B
    for j in range(3):
        ra = ea0 * abs_r[j] + ea1 * abs_r[3 + j] + ea2 * abs_r[6 + j]
        tj = t0 * rel[j] + t1 * rel[4 + j] + t2 * rel[8 + j]
        if abs(tj) > ra + eb[j] + margin:
            return False
    # cross products of A's axis i with B's axis j
    for i in range(3):
        i1 = (i + 1) % 3
        i2 = (i + 2) % 3
        for j in range(3):
            j1 = (j + 1) % 3
            j2 = (j + 2) % 3
            ra = ea[i1] * abs_r[3 * i2 + j] + ea[i2] * abs_r[3 * i1 + j]
            rb = eb[j1] * abs_r[3 * i + j2] + eb[j2] * abs_r[3 * i + j1]
            d = t[i2] * rel[4 * i1 + j] - t[i1] * rel[4 * i2 + j]
            if abs(d) > ra + rb + margin:
                return False
    return True


@njit_borrowing
def descent_deviations(lo, hi, pose, motion, stack, top):
    """Deviation bounds (motion.box_deviation, length units) of A's and B's nodes under
    stack rows [0, top) (the node pairs a descent starts from): the largest of those
    nodes' own bounds, which hold for every node below them."""
    dev_a = 0.0
    dev_b = 0.0
    for row in range(top):
        dev_a = max(dev_a, box_deviation(motion[0], lo[stack[row, 0]], hi[stack[row, 0]], pose[0]))
        dev_b = max(dev_b, box_deviation(motion[1], lo[stack[row, 1]], hi[stack[row, 1]], pose[2]))
    return dev_a, dev_b


@njit_borrowing
def rigid_frame_deviation(lo, hi, node_b, pose, motion, a, b):
    """How far (length units) any point of node_b's box (object B, body frame), seen in
    A's body frame, can stray from its chord between its two placements there over the
    step, when A and B move rigidly by the screw motions motion[a], motion[b]
    (pose rows: pose[2 a], pose[2 a + 1] A's poses at both ends, likewise B's).

    A point's position in A's frame is y(t) = Q(t) u(t), with Q(t) = R_A(t)^T and
    u(t) = w(t) - p_A(t) its world offset from A's origin. Against the chord y0 + t (y1 -
    y0): |u - ubar| <= dev_w + dev_p (the screws' deviation bounds of the point and of
    A's origin); Q turns at a constant rate theta_A about a fixed axis, so |(Q(t) -
    Qbar(t)) v| <= theta_A^2 / 8 |v|; and Qbar ubar - (1 - t) Q0 u0 - t Q1 u1 = t (1 - t)
    (Q0 - Q1)(u1 - u0), at most theta_A / 4 |u1 - u0|. With c the box's centre and r its
    half diagonal: |u| <= |c - p_A| + r, |u1 - u0| <= |c1 - c0| + theta_B r + |p_A1 -
    p_A0|. Rounding margins of both motions included."""
    m_a = motion[a]
    m_b = motion[b]
    pa0, pa1, pb0, pb1 = pose[2 * a], pose[2 * a + 1], pose[2 * b], pose[2 * b + 1]
    r = 0.0
    for i in range(3):
        r += (0.5 * (hi[node_b, i] - lo[node_b, i])) ** 2
    r = math.sqrt(r)
    c0 = _placed_centre(lo, hi, node_b, pb0)
    c1 = _placed_centre(lo, hi, node_b, pb1)
    d0 = d1 = c_step = p_step = 0.0
    for i in range(3):
        d0 += (c0[i] - pa0[i, 3]) ** 2
        d1 += (c1[i] - pa1[i, 3]) ** 2
        c_step += (c1[i] - c0[i]) ** 2
        p_step += (pa1[i, 3] - pa0[i, 3]) ** 2
    u_max = max(math.sqrt(d0), math.sqrt(d1)) + r
    u_step = math.sqrt(c_step) + m_b[M_THETA] * r + math.sqrt(p_step)
    theta = m_a[M_THETA]
    bound = (box_deviation(m_b, lo[node_b], hi[node_b], pb0) + sphere_deviation(m_a, pa0[:, 3]) + m_a[M_ETA]
             + 0.125 * theta * theta * u_max + 0.25 * theta * u_step)
    return bound * (1.0 + 2.0 ** -40)


@njit_borrowing
def _placed_centre(lo, hi, node, rp):
    """World centre (3-tuple) of node's box placed by pose rp (3, 4)."""
    b0 = 0.5 * (lo[node, 0] + hi[node, 0])
    b1 = 0.5 * (lo[node, 1] + hi[node, 1])
    b2 = 0.5 * (lo[node, 2] + hi[node, 2])
    return (rp[0, 3] + rp[0, 0] * b0 + rp[0, 1] * b1 + rp[0, 2] * b2,
            rp[1, 3] + rp[1, 0] * b0 + rp[1, 1] * b1 + rp[1, 2] * b2,
            rp[2, 3] + rp[2, 0] * b0 + rp[2, 1] * b1 + rp[2, 2] * b2)


@njit_borrowing
def _swept_boxes_overlap(lo, hi, na, nb, pose, margin_a, margin_b):
    """World boxes of nodes na (object A) and nb (object B) over the step overlap: each
    node's chord box widened by margin_a, margin_b (its deviation bound and the
    rounding margin)."""
    for i in range(3):
        lo_a, hi_a = chord_interval(lo[na], hi[na], pose[0], pose[1], i)
        lo_b, hi_b = chord_interval(lo[nb], hi[nb], pose[2], pose[3], i)
        if lo_a - margin_a > hi_b + margin_b or lo_b - margin_b > hi_a + margin_a:
            return False
    return True


@njit_borrowing
def half_area(box):
    """Half the surface area of a box 6-tuple (node_box)."""
    dx = box[3] - box[0]
    dy = box[4] - box[1]
    dz = box[5] - box[2]
    return dx * dy + dy * dz + dz * dx


@njit_borrowing
def opens_a(leaf_a, leaf_b, box_a, box_b):
    """Which node of a pair to open: A when B is a leaf, or when both are inner nodes and
    A's box (6-tuple) is the larger (by half area)."""
    return leaf_b or (not leaf_a and half_area(box_a) >= half_area(box_b))


@njit(cache=True)
def overlapping_leaves(lo, hi, first, count, leaf_box, box_shift_a, box_shift_b, pose, motion, rule, margin, stack,
                       top, out, max_out, counts, toward, guided):
    """Leaf pairs of two BVHs whose boxes overlap under ``rule``, found by a tandem
    descent that can stop and resume.

    lo, hi, first, count: node arrays holding both trees (see bvh.py; ``first``
    of inner nodes indexes these same arrays). pose float64 (4, 3, 4) and motion
    float64 (2, MOTION_WIDTH): see module docstring. stack: int64 (cap, 2) node pairs
    still to open, the first ``top`` rows live; start a descent with the two roots as
    its only row (top = 1). out: int64 (cap, 2) buffer of (leaf_a, leaf_b) rows. The
    descent stops once max_out rows are found (or the stack is empty), so a caller
    that needs only some can test them and resume with the returned stack. Buffers
    grow when full. counts: int64 rows.COUNT_* counters. Returns (stack, top, out, k),
    rows out[:k]. Node pairs are visited in a fixed order: results are deterministic.
    Under RULE_POSE a leaf pair is also checked along both leaves' normals
    (leaves_apart_along_normals_at), when both meshes have leaf boxes (leaf_box,
    rows node + box_shift_a (A's nodes) or box_shift_b; packed.NO_LEAF_BOXES: none).

    toward: float64 (2, 3) a point in A's and one in B's body frame, read when ``guided``.
    Of the two children of an opened node, the one whose box lies nearer its tree's point
    is then visited first (the set of leaf pairs is the same, only their order changes): a
    caller that stops at the first leaf pair that touches finds one near the points
    sooner when the touching region is there.
    """
    rel = relative_pose(pose[0], pose[2])
    abs_r = abs_rotation(rel)
    rel_ab = relative_pose(pose[2], pose[0])  # A's nodes in B's frame
    boxes = rule == RULE_POSE and box_shift_a != NO_LEAF_BOXES and box_shift_b != NO_LEAF_BOXES
    margin_a = margin_b = margin
    if rule == RULE_SWEPT:
        dev_a, dev_b = descent_deviations(lo, hi, pose, motion, stack, top)
        margin_a += dev_a
        margin_b += dev_b
    k = np.int64(0)
    while top > 0 and k < max_out:
        if stack.shape[0] < top + DESCENT_BATCH + 1:  # rebound only when they grow (see DESCENT_BATCH)
            stack = with_room(stack, top, top + DESCENT_BATCH + 1)
        if out.shape[0] < k + DESCENT_BATCH:
            out = with_room(out, k, k + DESCENT_BATCH)
        for _ in range(DESCENT_BATCH):  # no buffer is rebound in here (see DESCENT_BATCH)
            if top == 0 or k >= max_out:
                break
            top -= 1
            na = stack[top, 0]
            nb = stack[top, 1]
            counts[COUNT_NODE_PAIRS] += 1
            box_a = node_box(lo, hi, na)
            box_b = node_box(lo, hi, nb)
            if rule == RULE_POSE:
                if not oriented_boxes_overlap(box_a, box_b, rel, abs_r, margin):
                    continue
            elif not _swept_boxes_overlap(lo, hi, na, nb, pose, margin_a, margin_b):
                continue
            leaf_a = count[na] > 0
            leaf_b = count[nb] > 0
            if leaf_a and leaf_b:
                if not (boxes and leaves_apart_along_normals_at(leaf_box, na + box_shift_a, nb + box_shift_b, rel_ab,
                                                                rel, margin)):
                    k = _put_pair(out, k, na, nb)
                continue
            open_a = opens_a(leaf_a, leaf_b, box_a, box_b)
            _open(first, na, nb, open_a, stack, top)
            if guided:
                _nearer_child_on_top(lo, hi, toward, open_a, stack, top)
            top += 2
    counts[COUNT_LEAF_PAIRS] += k
    return stack, top, out, k


@njit_borrowing
def _put_pair(out, k, na, nb):
    """Write leaf pair (na, nb) as row k of out (int64 (cap, 2), which has room). Returns k + 1."""
    out[k, 0] = na
    out[k, 1] = nb
    return k + 1


@njit_borrowing
def _box_distance2(lo, hi, node, points, row):
    """Squared distance from points[row] (points (2, 3)) to node's box (0 inside)."""
    d2 = 0.0
    for i in range(3):
        d = max(lo[node, i] - points[row, i], points[row, i] - hi[node, i], 0.0)
        d2 += d * d
    return d2


@njit_borrowing
def _nearer_child_on_top(lo, hi, toward, open_a, stack, top):
    """Swap the two child pairs _open just wrote to stack rows top and top + 1 when the
    child in row top (visited second) lies nearer the opened tree's point of toward
    (2, 3) (row 0: A's, row 1: B's, body frames)."""
    col = 0 if open_a else 1
    if _box_distance2(lo, hi, stack[top, col], toward, col) < _box_distance2(lo, hi, stack[top + 1, col], toward,
                                                                             col):
        for j in range(2):
            stack[top, j], stack[top + 1, j] = stack[top + 1, j], stack[top, j]


@njit_borrowing
def _open(first, na, nb, open_a, stack, top):
    """Replace node pair (na, nb) by the pairs of the children of na (open_a) or of nb
    (opens_a) in stack rows top and top + 1 (room for both must exist). Returns open_a."""
    if open_a:
        child = first[na]
        stack[top, 0] = child + 1
        stack[top, 1] = nb
        stack[top + 1, 0] = child
        stack[top + 1, 1] = nb
        return True
    child = first[nb]
    stack[top, 0] = na
    stack[top, 1] = child + 1
    stack[top + 1, 0] = na
    stack[top + 1, 1] = child
    return False


# --- level 2 under motion: boxes computed once per node, not once per node pair -----------

#: columns of a swept descent's ``held`` rows: the world box of the node of its stack row
#: that the row's parent pair did not open, and which side that node is on
_HELD_SIDE = 6
_HELD_NONE = 0.0
_HELD_A = 1.0
_HELD_B = 2.0


@njit_borrowing
def _swept_node_box(box, rp0, rp1, abs0, abs1, d):
    """World box (lo x, y, z, hi x, y, z) holding a node's box (node_box 6-tuple) over the
    step: its chord box (motion.chord_interval_of between pose tuples rp0 and rp1, whose
    rotations' absolute values are the 9-tuples abs0, abs1: motion.rotation_magnitudes)
    widened by d (its deviation bound and the rounding margin); the boxes of
    _swept_boxes_overlap. The same arithmetic as chord_interval_of, with the box's
    centre and half extents and the |R| computed once per box, not once per axis and
    pose. Tuples only (no reference counting per node)."""
    c, h = centre_and_half(box)
    x0, x1 = _chord_interval(c, h, rp0, rp1, abs0, abs1, 0)
    y0, y1 = _chord_interval(c, h, rp0, rp1, abs0, abs1, 1)
    z0, z1 = _chord_interval(c, h, rp0, rp1, abs0, abs1, 2)
    return x0 - d, y0 - d, z0 - d, x1 + d, y1 + d, z1 + d


@njit(cache=True, inline="always")
def _chord_interval(c, h, rp0, rp1, abs0, abs1, i):
    """motion.chord_interval_of for a box of centre c and half extents h (3-tuples)."""
    lo0, hi0 = placed_interval(c, h, rp0, abs0, i)
    lo1, hi1 = placed_interval(c, h, rp1, abs1, i)
    return min(lo0, lo1), max(hi0, hi1)


@njit_borrowing
def _held_box(held, row):
    return held[row, 0], held[row, 1], held[row, 2], held[row, 3], held[row, 4], held[row, 5]


@njit_borrowing
def _hold(held, row, box, side):
    for i in range(6):
        held[row, i] = box[i]
    held[row, _HELD_SIDE] = side


@njit_borrowing
def rigid_deviations(lo, hi, pose, motion, stack, top):
    """rigid_frame_deviation of A's nodes seen in B's frame and of B's nodes seen in A's,
    for the nodes under stack rows [0, top) (the node pairs a descent starts from)."""
    dev_a = 0.0
    dev_b = 0.0
    for row in range(top):
        dev_a = max(dev_a, rigid_frame_deviation(lo, hi, stack[row, 0], pose, motion, 1, 0))
        dev_b = max(dev_b, rigid_frame_deviation(lo, hi, stack[row, 1], pose, motion, 0, 1))
    return dev_a, dev_b


@njit_borrowing
def _apart(box_a, box_b):
    """Boxes (6-tuples) do not overlap."""
    return (box_a[0] > box_b[3] or box_b[0] > box_a[3] or box_a[1] > box_b[4] or box_b[1] > box_a[4]
            or box_a[2] > box_b[5] or box_b[2] > box_a[5])


@njit(cache=True)
def swept_leaves(lo, hi, first, count, leaf_box, box_shift_a, box_shift_b, pose, motion, rigid, margin, stack, top, out,
                 counts):
    """Overlapping leaf pairs over a step, run to the end: under RULE_SWEPT
    (overlapping_leaves' leaf pairs in the same order, the same node pairs tested) or,
    when ``rigid``, under RULE_SWEPT_RIGID. Each stacked node pair carries the placed box
    of the node its parent pair did not open (in the world, or in the other object's
    frame), so that a node's box is computed once when it is paired with the children
    of another, not once for each of those pairs. Returns (stack, top = 0, out, k),
    rows out[:k]."""
    held = np.empty((stack.shape[0], 7))
    for row in range(top):
        held[row, _HELD_SIDE] = _HELD_NONE
    if rigid:  # A's nodes placed in B's frame, B's in A's
        rp_a0, rp_a1 = relative_pose(pose[2], pose[0]), relative_pose(pose[3], pose[1])
        rp_b0, rp_b1 = relative_pose(pose[0], pose[2]), relative_pose(pose[1], pose[3])
        dev_a, dev_b = rigid_deviations(lo, hi, pose, motion, stack, top)
    else:
        rp_a0, rp_a1 = pose_tuple(pose[0]), pose_tuple(pose[1])
        rp_b0, rp_b1 = pose_tuple(pose[2]), pose_tuple(pose[3])
        dev_a, dev_b = descent_deviations(lo, hi, pose, motion, stack, top)
    margin_a = margin + dev_a
    margin_b = margin + dev_b
    abs_a0, abs_a1 = rotation_magnitudes(rp_a0), rotation_magnitudes(rp_a1)
    abs_b0, abs_b1 = rotation_magnitudes(rp_b0), rotation_magnitudes(rp_b1)
    boxes = rigid and box_shift_a != NO_LEAF_BOXES and box_shift_b != NO_LEAF_BOXES
    k = np.int64(0)
    while top > 0:
        if stack.shape[0] < top + DESCENT_BATCH + 1:  # rebound only when they grow (see DESCENT_BATCH)
            stack = with_room(stack, top, top + DESCENT_BATCH + 1)
        if held.shape[0] < stack.shape[0]:
            held = with_room(held, top, stack.shape[0])
        if out.shape[0] < k + DESCENT_BATCH:
            out = with_room(out, k, k + DESCENT_BATCH)
        for _ in range(DESCENT_BATCH):  # no buffer is rebound in here (see DESCENT_BATCH)
            if top == 0:
                break
            top -= 1
            na = stack[top, 0]
            nb = stack[top, 1]
            counts[COUNT_NODE_PAIRS] += 1
            side = held[top, _HELD_SIDE]
            own_a = node_box(lo, hi, na)
            own_b = node_box(lo, hi, nb)
            if side == _HELD_B:
                box_b = _held_box(held, top)
            else:
                box_b = _swept_node_box(own_b, rp_b0, rp_b1, abs_b0, abs_b1, margin_b)
            if rigid and _apart(own_a, box_b):
                continue  # box_a not needed
            if side == _HELD_A:
                box_a = _held_box(held, top)
            else:
                box_a = _swept_node_box(own_a, rp_a0, rp_a1, abs_a0, abs_a1, margin_a)
            if _apart(own_b, box_a) if rigid else _apart(box_a, box_b):
                continue
            leaf_a = count[na] > 0
            leaf_b = count[nb] > 0
            if leaf_a and leaf_b:
                if not (boxes and leaves_apart_along_normals(leaf_box, na + box_shift_a, nb + box_shift_b, rp_a0,
                                                             rp_a1, rp_b0, rp_b1, margin_a, margin_b)):
                    k = _put_pair(out, k, na, nb)
                continue
            if _open(first, na, nb, opens_a(leaf_a, leaf_b, own_a, own_b), stack, top):
                _hold(held, top, box_b, _HELD_B)
                _hold(held, top + 1, box_b, _HELD_B)
            else:
                _hold(held, top, box_a, _HELD_A)
                _hold(held, top + 1, box_a, _HELD_A)
            top += 2
    counts[COUNT_LEAF_PAIRS] += k
    return stack, top, out, k


@njit_borrowing
def leaves_apart_along_normals(leaf_box, row_a, row_b, rp_a0, rp_a1, rp_b0, rp_b1, margin_a, margin_b):
    """Under RULE_SWEPT_RIGID (swept_leaves' placements: rp_a0, rp_a1 place A's nodes in
    B's frame at both ends of the step, rp_b0, rp_b1 B's in A's; margins margin_a,
    margin_b), whether a leaf of A and a leaf of B (rows row_a, row_b of leaf_box:
    packed.oriented_leaf_boxes) stay apart all along the step along A's leaf normal (in
    A's frame) or B's (in B's frame). A leaf is usually a nearly flat patch, thin along
    its normal where its axis-aligned box is not, so two patches facing each other across
    a gap are told apart here rather than triangle pair by triangle pair. The moving
    leaf's extent along the normal is the blend of its extents at both ends, so apart at
    both ends, on the same side, is apart throughout."""
    side = _side_along_normal(leaf_box, row_a, row_b, rp_b0, margin_b)
    if side != 0 and side == _side_along_normal(leaf_box, row_a, row_b, rp_b1, margin_b):
        return True
    side = _side_along_normal(leaf_box, row_b, row_a, rp_a0, margin_a)
    return side != 0 and side == _side_along_normal(leaf_box, row_b, row_a, rp_a1, margin_a)


@njit_borrowing
def leaves_apart_along_normals_at(leaf_box, row_a, row_b, rp_a, rp_b, margin):
    """leaves_apart_along_normals at one pose (RULE_POSE): rp_a places A's leaf in B's
    frame, rp_b B's in A's."""
    return (_side_along_normal(leaf_box, row_a, row_b, rp_b, margin) != 0
            or _side_along_normal(leaf_box, row_b, row_a, rp_a, margin) != 0)


@njit_borrowing
def _side_along_normal(leaf_box, still, moving, rp, margin):
    """Leaf ``still`` rests in its own body frame; leaf ``moving`` is placed in that frame by
    pose tuple rp, each of its points taken within margin of where rp puts it. Along
    still's normal (its box's first axis), by more than margin allowing for rounding: 1
    when moving lies above still, -1 below, 0 neither."""
    u0, u1, u2 = leaf_box[still, LEAF_AXES], leaf_box[still, LEAF_AXES + 1], leaf_box[still, LEAF_AXES + 2]
    lo, hi, size = leaf_box[still, LEAF_NORMAL_LO], leaf_box[still, LEAF_NORMAL_HI], leaf_box[still, LEAF_SIZE]
    lo_m, hi_m, size_m = extent_along(leaf_box, moving, rp, u0, u1, u2)
    m = margin + _NORMAL_ULPS * (size + size_m)
    if lo_m - m > hi:
        return 1
    if hi_m + m < lo:
        return -1
    return 0


#: rounding allowance of _side_along_normal, relative to the size of the numbers it adds
_NORMAL_ULPS = 64.0 * 2.0 ** -52


#: node pairs a descent tests between checks of its buffers' room: each pops one pair, pushes
#: at most two and appends at most one leaf pair, so room for a batch is made before it and
#: no buffer is rebound inside (a rebound array costs reference counting at every step)
DESCENT_BATCH = 64


@njit(cache=True)
def leaf_pair_windows(lo, hi, rp0_a, rp1_a, rp0_b, rp1_b, motion_a, motion_b, dist_tol, leaves, n_leaves):
    """When, within the step, the leaves of each of the leaf pairs leaves[:n_leaves] can
    come within dist_tol: float64 (n_leaves, 2) rows (t_lo, t_hi), fractions of the step,
    t_lo > t_hi when never. Each leaf's box is placed in the world at both ends of the step
    (A by poses rp0_a, rp1_a (3, 4), B by rp0_b, rp1_b); at fraction t each of its points
    lies in the blend (1 - t) start box + t end box, up to how far its path strays from
    its chord (box_deviation under motion rows motion_a, motion_b, and their rounding
    margins): windows.box_window of the two blended boxes. The margin is at least that
    of narrow.swept_candidates for any triangle pair of the two leaves, plus rounding, so
    a leaf pair's window holds each of its triangle pairs' windows."""
    windows = np.empty((n_leaves, 2))
    # poses as tuples, and their |R|, once per call, not once per leaf pair
    p0_a, p1_a, p0_b, p1_b = pose_tuple(rp0_a), pose_tuple(rp1_a), pose_tuple(rp0_b), pose_tuple(rp1_b)
    abs0_a, abs1_a = rotation_magnitudes(p0_a), rotation_magnitudes(p1_a)
    abs0_b, abs1_b = rotation_magnitudes(p0_b), rotation_magnitudes(p1_b)
    m_a, m_b = motion_tuple(motion_a), motion_tuple(motion_b)
    for k in range(n_leaves):
        leaf_a = node_box(lo, hi, leaves[k, 0])
        leaf_b = node_box(lo, hi, leaves[k, 1])
        box_a = _moving_node_box(leaf_a, p0_a, p1_a, abs0_a, abs1_a)
        box_b = _moving_node_box(leaf_b, p0_b, p1_b, abs0_b, abs1_b)
        largest = max(box_a[12], box_a[13], box_a[14], box_b[12], box_b[13], box_b[14])
        margin = (dist_tol + (box_deviation_of(m_a, leaf_a, p0_a) + box_deviation_of(m_b, leaf_b, p0_b))
                  + (m_a[M_ETA] + m_b[M_ETA])) + _NESTED_ULPS * largest
        windows[k, 0], windows[k, 1] = box_window(box_a, box_b, margin)
    return windows


#: rounding allowance (relative to the largest |coordinate|) that keeps a leaf pair's window
#: (leaf_pair_windows: boxes placed by world_interval_of) around those of its triangle pairs
#: (corners placed by packed.to_world): both place the same points, each within a few ulps
_NESTED_ULPS = 64.0 * 2.0 ** -52


@njit_borrowing
def _moving_node_box(box, rp0, rp1, abs0, abs1):
    """A node's box (node_box 6-tuple) placed by pose tuples rp0 and rp1 (whose |R| are
    abs0 and abs1: motion.rotation_magnitudes) at both ends of the step, in windows.moving_box's
    layout (15-tuple: for axis c, lo and hi at the start, lo and hi at the end, at 4 c to
    4 c + 3; the largest |coordinate| at 12 + c). The arithmetic of
    motion.world_interval_of, with the box's centre and half extents computed once."""
    c, h = centre_and_half(box)
    x0, x1 = placed_interval(c, h, rp0, abs0, 0)
    x2, x3 = placed_interval(c, h, rp1, abs1, 0)
    y0, y1 = placed_interval(c, h, rp0, abs0, 1)
    y2, y3 = placed_interval(c, h, rp1, abs1, 1)
    z0, z1 = placed_interval(c, h, rp0, abs0, 2)
    z2, z3 = placed_interval(c, h, rp1, abs1, 2)
    return (x0, x1, x2, x3, y0, y1, y2, y3, z0, z1, z2, z3, max(abs(x0), abs(x1), abs(x2), abs(x3)),
            max(abs(y0), abs(y1), abs(y2), abs(y3)), max(abs(z0), abs(z1), abs(z2), abs(z3)))


@njit(cache=True, inline="always")
def rigid_placed_node(lo, hi, node, placing):
    """A node's box as rigid_pair_window reads it: (its own box (node_box 6-tuple), and
    that box placed in the other object's frame at both ends of the step
    (_moving_node_box 15-tuple)). placing = (rp0, rp1, abs0, abs1): the pose tuples
    placing the node's object in the other's frame at both ends and their |R|."""
    own = node_box(lo, hi, node)
    return own, _moving_node_box(own, placing[0], placing[1], placing[2], placing[3])


@njit(cache=True, inline="always")
def rigid_pair_window(node_a, node_b, margin_a, margin_b, both=True):
    """When, within the step, a node of A and a node of B (rigid_placed_node pairs) can
    meet under RULE_SWEPT_RIGID's placements (swept_leaves'): (t_lo, t_hi), fractions of
    the step, t_lo > t_hi when never. In B's frame, each point of A's node at fraction t
    lies within margin_a (its deviation bound, rigid_frame_deviation, and the rounding
    margin) of the blend (1 - t) start box + t end box, and B's node stays put:
    windows.box_window of the two. With ``both``, the same seen from A (margin_b),
    intersected: then, where swept_leaves finds two nodes apart, their window is empty.
    Without, the looser window seen from B alone (for inner node pairs, whose second
    half costs more than it saves: swept._best_first_window)."""
    t_lo, t_hi = box_window(node_a[1], _still_node_box(node_b[0]), margin_a)
    if t_lo > t_hi or not both:
        return t_lo, t_hi
    u_lo, u_hi = box_window(node_b[1], _still_node_box(node_a[0]), margin_b)
    return max(t_lo, u_lo), min(t_hi, u_hi)


@njit(cache=True, inline="always")
def _still_node_box(box):
    """A node's box (node_box 6-tuple) that does not move, in windows.moving_box's layout."""
    return (box[0], box[3], box[0], box[3], box[1], box[4], box[1], box[4], box[2], box[5], box[2], box[5],
            max(abs(box[0]), abs(box[3])), max(abs(box[1]), abs(box[4])), max(abs(box[2]), abs(box[5])))


@njit(cache=True)
def with_room(rows, n, need):
    """rows (cap, w), grown (grown_rows, first n rows kept) until it has at least ``need`` rows.
    Rebinding a buffer to the result costs reference counting even when nothing grows, so
    loops run per node pair or per box call it only when ``rows.shape[0] < need``."""
    while rows.shape[0] < need:
        rows = grown_rows(rows, n)
    return rows


@njit(cache=True)
def grown_rows(rows, n):
    """A buffer twice the size of rows (cap, w), at least 16 rows, holding its first n
    rows (copied element by element: no slice assignment, whose error path costs
    compile time)."""
    grown = np.empty((max(2 * rows.shape[0], 16), rows.shape[1]), rows.dtype)
    for i in range(n):
        for j in range(rows.shape[1]):
            grown[i, j] = rows[i, j]
    return grown


@njit(cache=True)
def reorder_rows(rows, order):
    """In place: row r of rows (cap, w) becomes its old row order[r], r < len(order)."""
    old = rows[:order.shape[0]].copy()
    for r in range(order.shape[0]):
        for c in range(rows.shape[1]):
            rows[r, c] = old[order[r], c]
