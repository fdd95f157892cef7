"""Certified continuous collision detection (CCD) of linearly moving primitives.

Two queries over one time step in which every vertex moves on a straight line
from its position at t = 0 to its position at t = 1 (``x(t) = x_t0 + t (x_t1 - x_t0)``):

- vertex-face: the point ``v`` against the closed triangle ``f0 f1 f2``;
- edge-edge: the closed segment ``ea0 ea1`` against the closed segment ``eb0 eb1``.

Both return a conservative earliest time of contact ``toi`` in [0, 1], or inf.

Guarantees. Call the primitives "within d" at time t when some point of one and some
point of the other differ by at most d on every axis (x, y, z). Let delta be the
rounding bound derived below (128 * 2^-53 ~ 1.4e-14 times the largest |coordinate|
of the query, per axis).

- No false negative: if the primitives are within ``dist_tol`` (in particular, if
  they touch) at some first time t*, then ``toi <= t*``.
- False positives only within the tolerances: if ``toi`` is finite, the primitives
  are within ``dist_tol + 3 delta`` at some time t_c with
  ``toi <= t_c <= toi + time_tol`` (up to one rounding of t). Hence also
  ``toi >= t* - time_tol`` when t* is the first time they are within that distance.
- The one exception: a query that exhausts the work caps (``MAX_CHECKS`` box checks,
  ``HEAP_SIZE`` live boxes, or boxes too narrow to split) returns the start of the
  earliest box it could not rule out: still never later than t*, but with no
  near-contact certificate. This does not happen on the benchmark queries nor on
  random ordinary ones; it does on a few percent of queries whose triangle is
  exactly degenerate (collinear corners) or whose edges are exactly parallel, and
  there the answer measured within about 3e-8 of the step before the contact.

Method: an inclusion-based root finder in the spirit of Tight-Inclusion (Wang et al.
2021). Contact means F(t, u, v) = 0 for some (t, u, v) in the domain, with

    vertex-face: F = v(t) - [(1 - u - v) f0(t) + u f1(t) + v f2(t)]
                   = (v - f0) - u (f1 - f0) - v (f2 - f0),   t, u, v >= 0, u + v <= 1, t <= 1
    edge-edge:   F = ea0(t) + u (ea1(t) - ea0(t)) - eb0(t) - v (eb1(t) - eb0(t))
                   = (ea0 - eb0) + u (ea1 - ea0) - v (eb1 - eb0),   t, u, v in [0, 1]

F is affine in each of t, u, v separately (multilinear), so over a box of (t, u, v)
each coordinate of F, and any fixed linear combination n . F of them, lies between
the smallest and largest of its values at the 8 corners of the box. Boxes wait in a
min-heap ordered by their start time (deeper boxes first on ties). Taking the first:

- excluded, dropped: on some axis all 8 corner values are > dist_tol + delta, or all
  are < -(dist_tol + delta); or the same holds for d . F along one of three
  directions computed at the box's middle time -- n, the cross product of the two
  edge vectors (the face normal for vertex-face), and n x e for each of the two edge
  vectors e -- with the bound sum_i |d_i| (dist_tol + delta_i) (derivation below).
  The exact F then stays beyond dist_tol on that axis (or direction) all over the
  box: no contact. (n . F does not change with u or v, n x e . F not with e's own
  parameter: these separate thin triangles and nearly parallel edges, which the axis
  tests alone only do after splitting the box very finely.)
- coplanarity, dropped: contact needs the 4 points within dist_tol of coplanar. With
  a, b the two edge vectors and c the offset vector (f1 - f0, f2 - f0, v - f0, or
  ea1 - ea0, eb1 - eb0, eb0 - ea0), F = +-c + a combination of a and b, so for
  n = a x b, |n . F| = |det(a, b, c)| =: |g(t)|, whatever u and v; and where F is within dist_tol on
  every axis, |g(t)| <= dist_tol sum_i |n_i(t)|. Each vector is affine in t, so g is a
  cubic, and over the box's time range [t0, t1] its Bernstein coefficients are the
  averages of det(a, b, c) over the ways to take k of the 3 vectors at t1 and the rest
  at t0 (k = 0..3; det is linear in each vector); g stays within their range. When
  all 4 are beyond dist_tol * N + the rounding bound with the same sign (N bounds
  sum_i |n_i| from the vectors' largest coordinates at t0 and t1, as |n_x| <=
  |a_y| |b_z| + |a_z| |b_y|), no moment of the range has contact, for any (u, v).
  This catches the long time ranges before and after a contact, which the fixed
  directions below, taken at one moment, cannot. Rounding: each vector coordinate
  on axis i is within 12.1 u m_i of exact (steps 1-4 below) and at most 2.01 m_i; a
  3 x 3 determinant of such values, one factor per axis in each of its 6 products,
  is then within about 1300 u m_x m_y m_z; the bound used is 4096 u m_x m_y m_z (the
  sums of 3 determinants are compared with 3 times it) plus 2^-1000 for products
  that underflow. The same test over the whole step [0, t_max] rules out a query
  before any box is made.
- shrinking: F is affine along each dimension of the box, so along dimension d each
  of the 4 edges of the box parallel to d carries F linearly between its two corner
  values, and the slice of the box at fraction s of its width along d has every
  F_axis within the range of the 4 edges' values at s. Where, on some axis, all 4
  are beyond tol_out (= dist_tol + delta) on one side, that whole slice is beyond
  dist_tol: no contact in it. When such slices cover an end of the box (s from 0,
  or up to 1), that end is cut off; if some dimension shrinks to half its width or
  less, the smaller box goes back on the heap to be checked afresh, since its
  corners are new. The cut stays 2^-40 (relative) short of the computed crossing
  of each edge, then one ulp, so rounding in the crossings and in the new bounds
  never cuts off a slice the test did not rule out. This ends the long runs of
  halvings toward an edge or a moment that a primitive passes within rounding of.
- certify: a regularised Gauss-Newton step on the corner values, refined by
  up to NEWTON_ITERATIONS steps on the exact F (while they at least halve the
  largest |F_axis| / tol_in and it is above 1), proposes a point (t_c, u_c, v_c) of the box
  and of the domain -- with t_c the box's start, then anywhere in the box, then (for
  a box at most time_tol long) its end. F is computed there afresh; if every axis is
  within dist_tol + 2 delta, the exact F is within dist_tol + 3 delta: a certified
  near contact at t_c. The earliest such time is kept as t_near. (The guess may be
  poor; only the check of the fresh values matters.)
- otherwise the box is split in two: in time when it is longer than time_tol and its
  start is excluded (this keeps boxes along a line or area of contact -- parallel
  edges, coplanar sliding, a thick dist_tol -- from multiplying), else along the
  dimension whose halving brings a half nearest to exclusion by one of the tests
  (looking at F on the splitting plane; ``_lookahead_dimension``).

Once a near contact is certified at t_near, only an earlier contact could change the
answer: every box taken is cut to end at t_cut = max(t_near - time_tol / 2, 0), so the search
never spends work after it. The search returns ``min(start, t_cut)`` as soon as the
first box's start reaches ``t_near - time_tol``; t_cut when no box is left after a
certification (no contact before t_cut, a near contact at t_near <= t_cut + time_tol);
and inf when no box is left and nothing was certified. Why this is never late: every
point of the domain before t_cut where the exact F is within dist_tol lies in a box
that is never dropped, and every box that starts earlier than the one taken was
dropped or split (it is the heap's minimum), so no such point exists before the taken
box's start.
Excluding needs dist_tol + delta and certifying allows dist_tol + 2 delta, so a small
enough box is always dropped or certified, and the search ends.

Rounding bound (per axis). Let m be the largest |coordinate| on that axis over the 8
input points, u = 2^-53 the unit roundoff, and fl(a o b) = (a o b)(1 + e), |e| <= u.
t, u, v are floats in [0, 1] (the parameter u is written w below). F is computed in
exactly this order (``_f_axis``):

1. d = fl(x_t1 - x_t0):          |error| <= u |x_t1 - x_t0| <= 2 u m;  |d| <= 2 m (1 + u)
2. p = fl(t * d):                |error vs t (x_t1 - x_t0)| <= 2 u m + u |t d| <= 4.01 u m
3. x = fl(x_t0 + p):             the exact x(t) is a convex combination, |x(t)| <= m;
                                 |error| <= 4.01 u m + u (m + 4.01 u m) <= 5.01 u m
4. D = fl(x_a - x_b):            |exact| <= 2 m;  |error| <= 2 (5.01 u m) + u (2.01 m) <= 12.1 u m
5. P = fl(w * D), w in [0, 1]:   |error| <= 12.1 u m + u (2.01 m) <= 14.2 u m;  |P| <= 2.01 m
6. fl(fl(D0 -+ P1) - P2):        first |error| <= 12.1 + 14.2 + 4.02 = 30.4 u m (|sum| <= 4.02 m),
                                 then <= 30.4 + 14.2 + 6.05 = 50.7 u m (|sum| <= 6.05 m)

(vertex-face boxes may have corners with u + v up to 2; each term above already
allows |w| <= 1). So every computed value is within 51 u m of the exact one. We use
delta = 128 u m + 2^-1060 per axis: 2.5 times the bound (the O(u^2) terms dropped
above are far below the slack), plus an absolute term for gradual underflow with
tiny coordinates. A fused multiply-add only removes a rounding, so the bound holds
with or without contraction. Never compile this module with fastmath: it allows
reassociation, which breaks the derivation. Inputs must be finite and well below
1e150 (the public wrappers check both).

Test directions: for any float vector n, the computed
fl(fl(fl(n0 F0) + fl(n1 F1)) + fl(n2 F2)) of computed F values is within
gamma_3 sum |n_i| |F_i| <= 3.01 u sum |n_i| 6.06 m_i (rounding of the dot product)
plus sum |n_i| 50.7 u m_i (of the F values), i.e. within sum |n_i| 69 u m_i, of the
exact n . F; and where the exact F is within dist_tol on every axis,
|n . F| <= sum |n_i| dist_tol. The bound used, fl(sum |n_i| (dist_tol + delta_i))
times (1 + 2^-50) plus 2^-1060, covers both (its own rounding is at most 6 u
relative). n is computed once per box, so the 8 corners use the same n; a test
whose products overflow (inf or nan) is skipped: it never excludes.

Domain: the certified point of a vertex-face box satisfies fl(u_c + v_c) <= 1, so
u_c + v_c <= 1 + 2^-53; moving it into the triangle changes F by at most 4 u m,
covered by the slack between 2 delta + 51 u m and 3 delta.
"""
from typing import NamedTuple

import numpy as np

from .jit import njit, njit_borrowing, prange
from .predicates import triangles_intersect
from .rows import COUNT_BOX_CHECKS, COUNT_CCD_PAIRS, COUNT_CCD_QUERIES, COUNT_WIDTH

VERTEX_FACE = 0
EDGE_EDGE = 1

_UNIT_ROUNDOFF = 2.0 ** -53
#: rounding bound per axis as a multiple of unit roundoff * max |coordinate| (derivation above)
ROUNDING_FACTOR = 128.0
#: absolute part of the rounding bound (gradual underflow of tiny coordinates)
_UNDERFLOW = 2.0 ** -1060
#: Gauss-Newton steps when looking for a certified near contact in a box
NEWTON_ITERATIONS = 8
#: box checks per query before giving the conservative answer
MAX_CHECKS = 50_000
#: live boxes per query before giving the conservative answer
HEAP_SIZE = 1024
#: boxes this narrow (in t, u or v) are not split further along that dimension
_MIN_WIDTH = 2.0 ** -60
#: rounding bound of the coplanarity determinants, as a multiple of u * m_x * m_y * m_z
#: (module docstring, "coplanarity")
_COPLANARITY_ROUNDING = 4096.0
#: its absolute part (products that underflow)
_COPLANARITY_UNDERFLOW = 2.0 ** -1000
#: relative margin by which the ends cut off a box stay short of the computed crossings
#: (module docstring, "shrinking")
_SHRINK_MARGIN = 2.0 ** -40
#: coordinates must stay below this (no overflow in F; overflowing direction tests are skipped)
MAX_COORDINATE = 1e150

# A box is a heap row: t_lo, t_hi, u_lo, u_hi, v_lo, v_hi, depth. Corner c of a box
# has t = t_hi if bit 0 of c is set (else t_lo), u = u_hi if bit 1, v = v_hi if bit 2.
_ROW = 7


#: sub-steps the screw-motion search (motion._first_on_path) keeps at most
PATH_STACK = 128


class CCDWork(NamedTuple):
    """Scratch buffers of the CCD queries, made once (ccd_work) and reused by every query
    of a caller: a query then allocates nothing."""
    x0: np.ndarray       #: float64 (4, 3): a query's rows at t = 0
    x1: np.ndarray       #: float64 (4, 3): and at t = 1
    heap: np.ndarray     #: float64 (HEAP_SIZE, _ROW): live boxes
    box: np.ndarray      #: float64 (_ROW,): the box being checked
    corners: np.ndarray  #: float64 (8, 3): F at its corners
    scratch: np.ndarray  #: float64 (8, 3)
    clipped: np.ndarray  #: float64 (10, 3): F at the corners of its part inside the triangle
    dirs: np.ndarray     #: float64 (6, 3): separating directions
    bounds: np.ndarray   #: float64 (6,)
    proj: np.ndarray     #: float64 (6, 8)
    counts: np.ndarray   #: int64 (COUNT_WIDTH,): counters for callers that keep none
    path: np.ndarray     #: float64 (4, 3, 3): the sub-step search's triangles (motion._first_on_path)
    path_stack: np.ndarray  #: float64 (PATH_STACK, 2): its sub-steps still to search


@njit(cache=True)
def ccd_work():
    """A fresh CCDWork."""
    return CCDWork(np.empty((4, 3)), np.empty((4, 3)), np.empty((HEAP_SIZE, _ROW)), np.empty(_ROW),
                   np.empty((8, 3)), np.empty((8, 3)), np.empty((10, 3)), np.empty((6, 3)), np.empty(6),
                   np.empty((6, 8)), np.zeros(COUNT_WIDTH, np.int64), np.empty((4, 3, 3)), np.empty((PATH_STACK, 2)))


# --- F and its rounding bound -----------------------------------------------------------------

@njit_borrowing
def _lerp(x_t0, x_t1, row, axis, t):
    """Coordinate axis of input point row at time t (length units)."""
    return x_t0[row, axis] + t * (x_t1[row, axis] - x_t0[row, axis])


@njit_borrowing
def _f_axis(kind, x_t0, x_t1, t, u, v, axis):
    """One coordinate of F at (t, u, v), in exactly the order the rounding bound assumes.

    x_t0, x_t1: float64 (4, 3); t, u, v: floats in [0, 1]; returns length units.
    """
    # rows as np.int64, not literals: _lerp is compiled once, not once per row
    p0 = _lerp(x_t0, x_t1, np.int64(0), axis, t)
    p1 = _lerp(x_t0, x_t1, np.int64(1), axis, t)
    p2 = _lerp(x_t0, x_t1, np.int64(2), axis, t)
    p3 = _lerp(x_t0, x_t1, np.int64(3), axis, t)
    if kind == VERTEX_FACE:  # v_t, f0_t, f1_t, f2_t
        return ((p0 - p1) - u * (p2 - p1)) - v * (p3 - p1)
    # ea0_t, ea1_t, eb0_t, eb1_t
    return ((p0 - p2) + u * (p1 - p0)) - v * (p3 - p2)


@njit_borrowing
def _largest_coordinates(x_t0, x_t1):
    """m per axis (a 3-tuple, length units): the largest |coordinate| over the 8 input points."""
    m0 = 0.0
    m1 = 0.0
    m2 = 0.0
    for r in range(4):
        m0 = max(m0, abs(x_t0[r, 0]), abs(x_t1[r, 0]))
        m1 = max(m1, abs(x_t0[r, 1]), abs(x_t1[r, 1]))
        m2 = max(m2, abs(x_t0[r, 2]), abs(x_t1[r, 2]))
    return (m0, m1, m2)


@njit_borrowing
def _rounding_bound(m):
    """delta per axis (a 3-tuple, length units): bounds |computed F - exact F| (module doc);
    m: _largest_coordinates."""
    scale = ROUNDING_FACTOR * _UNIT_ROUNDOFF
    return (scale * m[0] + _UNDERFLOW, scale * m[1] + _UNDERFLOW, scale * m[2] + _UNDERFLOW)


@njit_borrowing
def _root_excluded(kind, x_t0, x_t1, tol_out):
    """The whole domain [0, 1]^3 is excluded on some axis (decided without allocating)."""
    for axis in range(3):
        lo = np.inf
        hi = -np.inf
        for c in range(8):
            value = _f_axis(kind, x_t0, x_t1, float(c & 1), float((c >> 1) & 1),
                            float((c >> 2) & 1), axis)
            lo = min(lo, value)
            hi = max(hi, value)
        if lo > tol_out[axis] or hi < -tol_out[axis]:
            return True
    return False


# --- exclusion --------------------------------------------------------------------------------

@njit_borrowing
def _plane_vectors(kind, x_t0, x_t1, t, out, first):
    """Rows first, first + 1, first + 2 of out (float64 (>= first + 3, 3)): the two edge
    vectors and the offset vector of the query at time t, in the order of F (module
    docstring): f1 - f0, f2 - f0, v - f0 (vertex-face) or ea1 - ea0, eb1 - eb0,
    eb0 - ea0 (edge-edge). Their determinant is zero whenever the 4 points are coplanar."""
    for axis in range(3):
        p0 = _lerp(x_t0, x_t1, np.int64(0), axis, t)
        p1 = _lerp(x_t0, x_t1, np.int64(1), axis, t)
        p2 = _lerp(x_t0, x_t1, np.int64(2), axis, t)
        p3 = _lerp(x_t0, x_t1, np.int64(3), axis, t)
        if kind == VERTEX_FACE:  # v, f0, f1, f2
            out[first, axis] = p2 - p1
            out[first + 1, axis] = p3 - p1
            out[first + 2, axis] = p0 - p1
        else:  # ea0, ea1, eb0, eb1
            out[first, axis] = p1 - p0
            out[first + 1, axis] = p3 - p2
            out[first + 2, axis] = p2 - p0


@njit_borrowing
def _det(a, b, c):
    """Determinant of the 3 x 3 matrix with rows a, b, c (3,). (Rows, not a matrix and
    row numbers: constant row numbers would compile one copy per combination.)"""
    return (a[0] * (b[1] * c[2] - b[2] * c[1])
            - a[1] * (b[0] * c[2] - b[2] * c[0])
            + a[2] * (b[0] * c[1] - b[1] * c[0]))


@njit_borrowing
def _edge_bounds(start, end, m):
    """Bounds (3-tuple) on the |exact coordinates| of a vector over the time range whose
    computed ends are start and end (3,) (_plane_vectors): the larger computed end plus
    their rounding (12.1 u m, module docstring)."""
    slack = 16.0 * _UNIT_ROUNDOFF
    return (max(abs(start[0]), abs(end[0])) + slack * m[0], max(abs(start[1]), abs(end[1])) + slack * m[1],
            max(abs(start[2]), abs(end[2])) + slack * m[2])


@njit_borrowing
def _coplanarity_cubic(kind, x_t0, x_t1, t_lo, t_hi, dist_tol, m, vectors):
    """Bernstein coefficients of g = det(a, b, c) over [t_lo, t_hi] (module docstring,
    "coplanarity"): (b0, 3 b1, 3 b2, b3, bound), with bound the rounding bound plus
    dist_tol * N (inf or nan when it overflows). vectors: (6, 3) scratch."""
    _plane_vectors(kind, x_t0, x_t1, t_lo, vectors, np.int64(0))
    _plane_vectors(kind, x_t0, x_t1, t_hi, vectors, np.int64(3))
    a_lo, b_lo, c_lo, a_hi, b_hi, c_hi = vectors[0], vectors[1], vectors[2], vectors[3], vectors[4], vectors[5]
    b0 = _det(a_lo, b_lo, c_lo)
    b3 = _det(a_hi, b_hi, c_hi)
    s1 = _det(a_hi, b_lo, c_lo) + _det(a_lo, b_hi, c_lo) + _det(a_lo, b_lo, c_hi)
    s2 = _det(a_lo, b_hi, c_hi) + _det(a_hi, b_lo, c_hi) + _det(a_hi, b_hi, c_lo)
    bound = _COPLANARITY_ROUNDING * _UNIT_ROUNDOFF * (m[0] * m[1] * m[2]) + _COPLANARITY_UNDERFLOW
    if dist_tol > 0.0:
        ea0, ea1, ea2 = _edge_bounds(a_lo, a_hi, m)  # bounds on |a| and |b|, per axis
        eb0, eb1, eb2 = _edge_bounds(b_lo, b_hi, m)
        normal = (ea1 * eb2 + ea2 * eb1) + (ea0 * eb2 + ea2 * eb0) + (ea0 * eb1 + ea1 * eb0)
        bound += normal * dist_tol * (1.0 + 2.0 ** -48)  # covers the roundings of normal and bound
    return b0, s1, s2, b3, bound


@njit_borrowing
def _cubic_beyond(cubic):
    """All Bernstein coefficients of a _coplanarity_cubic beyond its bound, with one sign."""
    b0, s1, s2, b3, bound = cubic
    if not bound < np.inf:
        return False
    if b0 > bound and b3 > bound and s1 > 3.0 * bound and s2 > 3.0 * bound:
        return True
    return b0 < -bound and b3 < -bound and s1 < -3.0 * bound and s2 < -3.0 * bound


@njit_borrowing
def _coplanarity_excluded(kind, x_t0, x_t1, t_lo, t_hi, dist_tol, m, vectors):
    """The 4 points stay farther than dist_tol from coplanar over all of [t_lo, t_hi]
    (module docstring, "coplanarity"): then no (u, v) gives contact in that time range.
    m: _largest_coordinates; vectors: (6, 3) scratch."""
    return _cubic_beyond(_coplanarity_cubic(kind, x_t0, x_t1, t_lo, t_hi, dist_tol, m, vectors))


@njit_borrowing
def _bernstein_value(cubic, s):
    """The cubic g at s in [0, 1] of its time range, as its sign relative to the first
    coefficient's: > 0 on the same side as g(t_lo), beyond the bound."""
    b0, s1, s2, b3, bound = cubic
    r = 1.0 - s
    value = b0 * r * r * r + s1 * s * r * r + s2 * s * s * r + b3 * s * s * s
    return value * np.sign(b0) - bound


@njit_borrowing
def _time_before_coplanar(cubic, t_lo, t_hi, time_tol):
    """A time in (t_lo, t_hi) shortly (about time_tol / 4) before g first comes within its
    bound of zero, judged from the floating-point cubic; -1.0 when g starts within the
    bound, never gets there, or gets there too soon to be worth a split. A heuristic:
    only where to split; the part before it is then tested by _coplanarity_excluded."""
    b0, s1, s2, b3, bound = cubic
    if not (abs(b0) > bound and bound < np.inf):
        return -1.0
    lo = 0.0
    hi = -1.0
    for k in range(1, 9):  # the first of 8 samples where g is within the bound
        if not _bernstein_value(cubic, k / 8.0) > 0.0:
            hi = k / 8.0
            break
        lo = k / 8.0
    if hi < 0.0:
        return -1.0
    width = t_hi - t_lo
    while (hi - lo) * width > 0.125 * time_tol:  # bisect: lo stays before it
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if _bernstein_value(cubic, mid) > 0.0:
            lo = mid
        else:
            hi = mid
    t = t_lo + lo * width - 0.25 * time_tol
    return t if t_lo + 0.25 * time_tol < t < t_hi else -1.0


@njit_borrowing
def _box_corners(kind, x_t0, x_t1, box, corners):
    """Fill corners (8, 3) with F at the 8 corners of box (a heap row)."""
    for c in range(8):
        t = box[1] if c & 1 else box[0]
        u = box[3] if c & 2 else box[2]
        v = box[5] if c & 4 else box[4]
        for axis in range(3):
            corners[c, axis] = _f_axis(kind, x_t0, x_t1, t, u, v, axis)


@njit_borrowing
def _excluded(corners, tol_out):
    """On some axis all the values (rows of corners) lie beyond tol_out on the same side."""
    for axis in range(3):
        lo = np.inf
        hi = -np.inf
        for c in range(corners.shape[0]):
            lo = min(lo, corners[c, axis])
            hi = max(hi, corners[c, axis])
        if lo > tol_out[axis] or hi < -tol_out[axis]:
            return True
    return False


@njit_borrowing
def _edge_vector(kind, x_t0, x_t1, t, which, axis):
    """Coordinate axis at time t of edge which (0, 1): f1 - f0 and f2 - f0 for
    vertex-face, ea1 - ea0 and eb1 - eb0 for edge-edge."""
    if kind == VERTEX_FACE:
        return _lerp(x_t0, x_t1, 2 + which, axis, t) - _lerp(x_t0, x_t1, np.int64(1), axis, t)
    return _lerp(x_t0, x_t1, 2 * which + 1, axis, t) - _lerp(x_t0, x_t1, 2 * which, axis, t)


@njit_borrowing
def _set_directions(kind, x_t0, x_t1, t, dist_tol, delta, dirs, bounds):
    """Fill the test directions and their bounds (module docstring, "Test directions").

    dirs (6, 3): rows 0-2 the x, y, z axes, row 3 n = e0 x e1 (the cross product of
    the two edge vectors at time t: the face normal for vertex-face, ea x eb for
    edge-edge), row 4 n x e0, row 5 n x e1. bounds (6,): rows 0-2 dist_tol + delta
    per axis, rows 3-5 the rounding-safe bound of d . F (module docstring). Any
    float vectors would do for rigour; these separate thin and nearly coplanar
    configurations best: n . F does not depend on u or v at time t, n x e0 . F not
    on the parameter of e0, n x e1 . F not on that of e1.
    """
    zero, one, two = np.int64(0), np.int64(1), np.int64(2)  # not literals: one compiled _edge_vector
    a0 = _edge_vector(kind, x_t0, x_t1, t, zero, zero)
    a1 = _edge_vector(kind, x_t0, x_t1, t, zero, one)
    a2 = _edge_vector(kind, x_t0, x_t1, t, zero, two)
    b0 = _edge_vector(kind, x_t0, x_t1, t, one, zero)
    b1 = _edge_vector(kind, x_t0, x_t1, t, one, one)
    b2 = _edge_vector(kind, x_t0, x_t1, t, one, two)
    n0 = a1 * b2 - a2 * b1
    n1 = a2 * b0 - a0 * b2
    n2 = a0 * b1 - a1 * b0
    for k in range(3):
        for axis in range(3):
            dirs[k, axis] = 1.0 if k == axis else 0.0
        bounds[k] = dist_tol + delta[k]
    dirs[3, 0], dirs[3, 1], dirs[3, 2] = n0, n1, n2
    dirs[4, 0], dirs[4, 1], dirs[4, 2] = n1 * a2 - n2 * a1, n2 * a0 - n0 * a2, n0 * a1 - n1 * a0
    dirs[5, 0], dirs[5, 1], dirs[5, 2] = n1 * b2 - n2 * b1, n2 * b0 - n0 * b2, n0 * b1 - n1 * b0
    for k in range(3, 6):
        bounds[k] = (abs(dirs[k, 0]) * (dist_tol + delta[0]) + abs(dirs[k, 1]) * (dist_tol + delta[1])
                     + abs(dirs[k, 2]) * (dist_tol + delta[2])) * (1.0 + 2.0 ** -50) + _UNDERFLOW


@njit_borrowing
def _projected_range(dirs, k, values, n_values):
    """(lo, hi) of dirs[k] . values[c] over the first n_values rows; (nan, nan) when a
    product overflows (such a test must not exclude anything)."""
    lo = np.inf
    hi = -np.inf
    for c in range(n_values):
        g = dirs[k, 0] * values[c, 0] + dirs[k, 1] * values[c, 1] + dirs[k, 2] * values[c, 2]
        if not abs(g) < np.inf:
            return np.nan, np.nan
        lo = min(lo, g)
        hi = max(hi, g)
    return lo, hi


@njit_borrowing
def _directions_excluded(dirs, bounds, values, n_values):
    """For one of the directions 3-5, d . F keeps one sign beyond bounds[k] at all the
    values (rows of values) that bound F over a box."""
    for k in range(3, 6):
        lo, hi = _projected_range(dirs, k, values, n_values)
        if lo > bounds[k] or hi < -bounds[k]:
            return True
    return False


@njit_borrowing
def _clipped_excluded(kind, x_t0, x_t1, box, tol_out, dirs, bounds, values):
    """For a vertex-face box that straddles the triangle's edge u + v = 1: the exclusion
    tests over the part of the box inside the triangle only.

    For fixed t, the vertex-face F is affine in (u, v), so over (time interval) x
    (polygon) it lies within the hull of its values at the polygon's vertices at both
    times. The polygon is the box's (u, v) rectangle cut by u + v <= 1 (the caller
    ensures u_lo + v_lo <= 1 < u_hi + v_hi), enlarged by 2^-52 along the cut so that
    rounding 1 - u can only make it larger. Its vertices: (u_lo, v_lo); where the cut
    meets the bottom and left sides (or those sides' far corners); where it meets
    the right and top sides, if it does (else repeats of the previous two).
    values: (10, 3) scratch.
    """
    u_lo, u_hi, v_lo, v_hi = box[2], box[3], box[4], box[5]
    slack = 2.0 ** -52
    bottom = (min(u_hi, (1.0 - v_lo) + slack), v_lo)
    left = (u_lo, min(v_hi, (1.0 - u_lo) + slack))
    # the cut meets the right (top) side iff the bottom (left) point reached the corner;
    # decided on the same enlarged values, so rounding cannot leave a vertex out
    right = (u_hi, min(v_hi, (1.0 - u_hi) + slack)) if bottom[0] == u_hi else bottom
    top = (min(u_hi, (1.0 - v_hi) + slack), v_hi) if left[1] == v_hi else left
    polygon = ((u_lo, v_lo), bottom, left, right, top)
    k = 0
    for face in range(2):
        for corner in polygon:
            u = max(corner[0], u_lo)
            v = max(corner[1], v_lo)
            for axis in range(3):
                values[k, axis] = _f_axis(kind, x_t0, x_t1, box[face], u, v, axis)
            k += 1
    return _excluded(values, tol_out) or _directions_excluded(dirs, bounds, values, np.int64(10))


# --- certification of a near contact ----------------------------------------------------------

@njit_borrowing
def _det3(g, k, r):
    """Determinant of the 3 x 3 matrix g (4, 3 scratch rows 0-2) with column k replaced by r
    (k = -1: none)."""
    m00 = r[0] if k == 0 else g[0, 0]
    m10 = r[1] if k == 0 else g[1, 0]
    m20 = r[2] if k == 0 else g[2, 0]
    m01 = r[0] if k == 1 else g[0, 1]
    m11 = r[1] if k == 1 else g[1, 1]
    m21 = r[2] if k == 1 else g[2, 1]
    m02 = r[0] if k == 2 else g[0, 2]
    m12 = r[1] if k == 2 else g[1, 2]
    m22 = r[2] if k == 2 else g[2, 2]
    return (m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)
            + m02 * (m10 * m21 - m11 * m20))


@njit_borrowing
def _newton_step(corners, face, scratch):
    """Regularised Gauss-Newton step toward F = 0 from the box's centre (face = -1), or
    from the centre of its start (face = 0) or end (face = 1) time face with t kept
    there, in box units (3-tuple, each in [-1/2, 1/2] once clamped).

    F is multilinear, so its value at such a centre is the mean of the corner values
    there, and its change across the box along a dimension is the mean change over
    the corner pairs differing in that dimension. Solves (A^T A + lambda I) x = -A^T f,
    which also copes with the rank-deficient A of parallel or coplanar motions. Only a
    guess: the caller verifies the point it leads to.
    """
    f = scratch[3]
    a = scratch[4:7]  # a[d] = change of F across the box along dimension d
    f[:] = 0.0
    a[:] = 0.0
    weight = 0.125 if face < 0 else 0.25
    for c in range(8):
        if face >= 0 and (c & 1) != face:
            continue
        for axis in range(3):
            value = corners[c, axis]
            f[axis] += weight * value
            for d in range(0 if face < 0 else 1, 3):
                a[d, axis] += 2.0 * weight * value if c & (1 << d) else -2.0 * weight * value
    return _regularised_solve(a.T, f, scratch[0:3], scratch[7], 1e-9)


@njit_borrowing
def _regularised_solve(jac, f, gram, rhs, lam):
    """x (3-tuple) solving (J^T J + lambda I) x = -J^T f for jac J (3, 3), with the
    system scaled to trace 1 and lambda = lam (copes with the rank-deficient J of
    parallel or coplanar motions); (0, 0, 0) when J is zero or not finite.
    gram (3, 3) and rhs (3,): scratch."""
    for i in range(3):
        for j in range(3):
            gram[i, j] = jac[0, i] * jac[0, j] + jac[1, i] * jac[1, j] + jac[2, i] * jac[2, j]
        rhs[i] = -(jac[0, i] * f[0] + jac[1, i] * f[1] + jac[2, i] * f[2])
    trace = gram[0, 0] + gram[1, 1] + gram[2, 2]
    if not 0.0 < trace < np.inf:
        return (0.0, 0.0, 0.0)  # F does not change over the box (or overflowed)
    for i in range(3):  # scale to trace 1 (the solution does not change), add lambda
        rhs[i] /= trace
        for j in range(3):
            gram[i, j] /= trace
        gram[i, i] += lam
    det = _det3(gram, -1, rhs)
    if not det > 0.0:  # gram is symmetric positive definite: only rounding can get here
        return (0.0, 0.0, 0.0)
    return (_det3(gram, 0, rhs) / det, _det3(gram, 1, rhs) / det, _det3(gram, 2, rhs) / det)


@njit_borrowing
def _in_box(box, d, step):
    """Centre of the box along dimension d moved by step box widths, kept in the box."""
    lo = box[2 * d]
    hi = box[2 * d + 1]
    step = min(max(step, -0.5), 0.5) if np.isfinite(step) else 0.0
    return min(max(0.5 * (lo + hi) + step * (hi - lo), lo), hi)


@njit_borrowing
def _gauss_newton(kind, x_t0, x_t1, box, t, u, v, fix_t, tol_in, work):
    """Refine the guess (t, u, v) toward F = 0 by regularised Gauss-Newton steps on the
    exact F (analytic derivatives), each kept in the box; t stays fixed when fix_t.
    Stops once every |F_axis| is within tol_in, when a step fails to halve the
    largest |F_axis| / tol_in (no quick convergence in this box), or after
    NEWTON_ITERATIONS steps. work: (8, 3) scratch. Only a guess: the caller checks
    the point it leads to."""
    jac = work[0:3]  # jac[axis, d]: change of F_axis across the box along dimension d
    gram = work[3:6]
    f = work[6]
    rhs = work[7]
    sign_u = -1.0 if kind == VERTEX_FACE else 1.0  # F = ... -+ u e0 - v e1 (module docstring)
    fix_u = False  # u (v) reached a side of the box: keep it there, solve for the rest
    fix_v = False
    residual = np.inf
    for _ in range(NEWTON_ITERATIONS):
        last = residual
        residual = 0.0
        for axis in range(3):
            f[axis] = _f_axis(kind, x_t0, x_t1, t, u, v, axis)
            residual = max(residual, abs(f[axis]) / tol_in[axis])
        if residual <= 1.0 or not residual < 0.5 * last:
            break
        for axis in range(3):
            # F is affine in t for fixed (u, v): its t-derivative is F(1) - F(0)
            jac[axis, 0] = 0.0 if fix_t else (_f_axis(kind, x_t0, x_t1, 1.0, u, v, axis)
                                              - _f_axis(kind, x_t0, x_t1, 0.0, u, v, axis))
            jac[axis, 1] = 0.0 if fix_u else sign_u * _edge_vector(kind, x_t0, x_t1, t, np.int64(0), axis)
            jac[axis, 2] = 0.0 if fix_v else -_edge_vector(kind, x_t0, x_t1, t, np.int64(1), axis)
            for d in range(3):
                jac[axis, d] *= box[2 * d + 1] - box[2 * d]
        step = _regularised_solve(jac, f, gram, rhs, 1e-12)  # small: the steps must reach ~1e-14
        if not fix_t:
            t = _clamp(t + step[0] * (box[1] - box[0]), box[0], box[1])
        u_free = u + step[1] * (box[3] - box[2])
        v_free = v + step[2] * (box[5] - box[4])
        u = _clamp(u_free, box[2], box[3])
        v = _clamp(v_free, box[4], box[5])
        if u != u_free or v != v_free:  # a new side reached: the next step may not halve F
            fix_u = fix_u or u != u_free
            fix_v = fix_v or v != v_free
            residual = np.inf
    return t, u, v


@njit_borrowing
def _clamp(x, lo, hi):
    return min(max(x, lo), hi) if np.isfinite(x) else lo


@njit_borrowing
def _near_contact_at(kind, x_t0, x_t1, box, corners, face, t_fixed, tol_in, scratch):
    """Time t_c of the candidate point from _newton_step(face) and _gauss_newton if F
    there, computed afresh, is within tol_in on every axis and the point is in the
    domain; else -1.0. With face >= 0, t stays at t_fixed (a time of the box; the
    face's time, or near it)."""
    x = _newton_step(corners, face, scratch)
    t = _in_box(box, 0, x[0]) if face < 0 else t_fixed
    u = _in_box(box, 1, x[1])
    v = _in_box(box, 2, x[2])
    t, u, v = _gauss_newton(kind, x_t0, x_t1, box, t, u, v, face >= 0, tol_in, scratch)
    if kind == VERTEX_FACE and u + v > 1.0:  # pull it back into the triangle
        excess = 0.5 * (u + v - 1.0)
        u = max(u - excess, box[2])
        v = max(v - excess, box[4])
        if u + v > 1.0:
            return -1.0
    for axis in range(3):
        if abs(_f_axis(kind, x_t0, x_t1, t, u, v, axis)) > tol_in[axis]:
            return -1.0
    return t


@njit_borrowing
def _certify(kind, x_t0, x_t1, box, corners, time_tol, tol_in, scratch):
    """Earliest time of the box found to hold a certified near contact, -1.0 if none.

    Tries, in order: the box's start time (which ends the search at once), a point
    anywhere in the box, and for a box at most time_tol long its end time. When the
    point anywhere lies over time_tol after the start, half of time_tol after the start
    is tried too: a contact that lasts (edges sliding along each other) then ends the
    search at once instead of halving the box toward its start.
    """
    start = np.int64(0)
    t_c = _near_contact_at(kind, x_t0, x_t1, box, corners, start, box[0], tol_in, scratch)
    if t_c >= 0.0:
        return t_c
    t_c = _near_contact_at(kind, x_t0, x_t1, box, corners, np.int64(-1), -1.0, tol_in, scratch)
    if t_c - box[0] > time_tol:
        early = _near_contact_at(kind, x_t0, x_t1, box, corners, start, box[0] + 0.5 * time_tol, tol_in, scratch)
        if early >= 0.0:
            return early
    if t_c < 0.0 and box[1] - box[0] <= time_tol:
        t_c = _near_contact_at(kind, x_t0, x_t1, box, corners, np.int64(1), box[1], tol_in, scratch)
    return t_c


# --- shrinking --------------------------------------------------------------------------------

@njit_borrowing
def _excluded_ends(corners, dim, tol_out):
    """(s_lo, s_hi), fractions of the box's width along dim: over the slices of the box at
    fractions s < s_lo and s > s_hi, the exact F is beyond dist_tol on some axis (module
    docstring, "shrinking"); s_lo >= s_hi when that covers the whole box."""
    bit = 1 << dim
    s_lo = 0.0
    s_hi = 1.0
    for axis in range(3):
        for sign in (1.0, -1.0):
            a = 0.0  # the slices beyond on this axis and side: s in (a, b) on all 4 lines
            b = 1.0
            for c in range(8):
                if c & bit:
                    continue
                f0 = sign * corners[c, axis] - tol_out[axis]
                f1 = sign * corners[c | bit, axis] - tol_out[axis]
                if f0 > 0.0 and f1 > 0.0:
                    continue
                if not (f0 > 0.0 or f1 > 0.0):  # never beyond on this line (or nan)
                    a = 1.0
                    b = 0.0
                    break
                crossing = f0 / (f0 - f1)  # where this line leaves (f0 > 0) or enters the beyond side
                if f0 > 0.0:
                    b = min(b, crossing * (1.0 - _SHRINK_MARGIN))
                else:
                    a = max(a, crossing * (1.0 + _SHRINK_MARGIN))
            if a < b:
                if a <= 0.0:
                    s_lo = max(s_lo, b)
                if b >= 1.0:
                    s_hi = min(s_hi, a)
    return s_lo, s_hi


@njit_borrowing
def _shrink(corners, box, tol_out):
    """Cut off the ends of the box (a heap row, changed in place) that the axis tests rule
    out slice by slice: -1 when that is all of it, 1 when some dimension shrank to about
    half its width or less (the box is then changed and must be checked afresh), else 0
    (box unchanged)."""
    shrunk = 0
    for dim in range(3):
        s_lo, s_hi = _excluded_ends(corners, dim, tol_out)
        if not s_lo < s_hi:
            return -1
        if s_hi - s_lo > 0.5:
            continue
        lo = box[2 * dim]
        hi = box[2 * dim + 1]
        width = hi - lo
        new_lo = max(lo, np.nextafter(lo + s_lo * width * (1.0 - _SHRINK_MARGIN), -np.inf))
        new_hi = min(hi, np.nextafter(hi - (1.0 - s_hi) * width * (1.0 - _SHRINK_MARGIN), np.inf))
        if new_lo < new_hi and new_hi - new_lo <= 0.75 * width:  # progress, also for widths of a few ulps
            box[2 * dim] = new_lo
            box[2 * dim + 1] = new_hi
            shrunk = 1
    return shrunk


# --- splitting --------------------------------------------------------------------------------

@njit_borrowing
def _start_excluded(corners, tol_out):
    """At the box's start time (the 4 even corners) some axis is beyond tol_out."""
    for axis in range(3):
        lo = min(corners[0, axis], corners[2, axis], corners[4, axis], corners[6, axis])
        hi = max(corners[0, axis], corners[2, axis], corners[4, axis], corners[6, axis])
        if lo > tol_out[axis] or hi < -tol_out[axis]:
            return True
    return False


@njit_borrowing
def _splittable(box, dim):
    """The box can be halved along dim: wider than _MIN_WIDTH, and its midpoint falls
    strictly inside (not so near an endpoint that it rounds onto it)."""
    lo = box[2 * dim]
    hi = box[2 * dim + 1]
    mid = 0.5 * (lo + hi)
    return hi - lo > _MIN_WIDTH and lo < mid < hi


@njit_borrowing
def _largest_change_dimension(corners, box):
    """Dimension (0 t, 1 u, 2 v) along which F changes the most, among those still
    wider than _MIN_WIDTH; -1 if none can be split."""
    best = -1
    best_change = -1.0
    for dim in range(3):
        if not _splittable(box, dim):
            continue
        bit = 1 << dim
        change = 0.0
        for c in range(8):
            if c & bit:
                continue
            for axis in range(3):
                change = max(change, abs(corners[c | bit, axis] - corners[c, axis]))
        if change > best_change:
            best_change = change
            best = dim
    return best


@njit_borrowing
def _lookahead_dimension(kind, x_t0, x_t1, box, corners, dirs, bounds, mid, proj):
    """Dimension (0 t, 1 u, 2 v) to split the box along: the one whose halving brings
    a half nearest to exclusion by one of the 6 tests (dirs, bounds; see
    _set_directions), or when no test varies over the box the one along which F
    changes most; -1 if none can be split. A heuristic only: the halves are tested
    properly when taken.

    For a test with range [lo, hi] over a half and bound b, the score
    max(hi - b, -b - lo) / (hi - lo) exceeds 1 exactly when the test excludes the
    half. Scratch: mid (4, 3) for F on the splitting plane, proj (6, 8) for the
    tests' values at the corners.
    """
    for test in range(6):
        for c in range(8):
            proj[test, c] = dirs[test, 0] * corners[c, 0] + dirs[test, 1] * corners[c, 1] + \
                dirs[test, 2] * corners[c, 2]
    best = -1
    best_score = -np.inf
    for dim in range(3):
        if not _splittable(box, dim):
            continue
        bit = 1 << dim
        half = 0.5 * (box[2 * dim] + box[2 * dim + 1])
        if kind == VERTEX_FACE and dim > 0 and half + box[6 - 2 * dim] > 1.0:
            return dim  # the upper half lies outside the triangle u + v <= 1: dropped at once
        k = 0
        for c in range(8):  # F on the splitting plane: the 4 corners shared by both halves
            if c & bit:
                continue
            t = half if dim == 0 else (box[1] if c & 1 else box[0])
            u = half if dim == 1 else (box[3] if c & 2 else box[2])
            v = half if dim == 2 else (box[5] if c & 4 else box[4])
            for axis in range(3):
                mid[k, axis] = _f_axis(kind, x_t0, x_t1, t, u, v, axis)
            k += 1
        score = -np.inf
        for test in range(6):
            mid_lo, mid_hi = _projected_range(dirs, test, mid, np.int64(4))
            for side in range(2):
                lo = mid_lo
                hi = mid_hi
                for c in range(8):
                    if ((c & bit) != 0) == (side == 1):
                        lo = min(lo, proj[test, c])
                        hi = max(hi, proj[test, c])
                if hi > lo:  # false for nan (overflow) and for a constant test
                    score = max(score, max(hi - bounds[test], -bounds[test] - lo) / (hi - lo))
        if score > best_score:
            best_score = score
            best = dim
    if best < 0:
        return _largest_change_dimension(corners, box)
    return best


# --- a min-heap of boxes keyed by (t_lo, -depth) ----------------------------------------------

@njit_borrowing
def _before(heap, i, j):
    """Box i comes before box j: it starts earlier, or as early and is deeper."""
    return heap[i, 0] < heap[j, 0] or (heap[i, 0] == heap[j, 0] and heap[i, 6] > heap[j, 6])


@njit_borrowing
def _swap(heap, i, j):
    for c in range(_ROW):
        heap[i, c], heap[j, c] = heap[j, c], heap[i, c]


@njit_borrowing
def _heap_push_half(heap, n, box, dim, upper):
    """Push the lower (upper=False) or upper half of box along dim; returns the new size."""
    return _heap_push_part(heap, n, box, dim, 0.5 * (box[2 * dim] + box[2 * dim + 1]), upper)


@njit_borrowing
def _heap_push_part(heap, n, box, dim, at, upper):
    """Push the part of box below (upper=False) or above the value at along dim; returns
    the new size."""
    for c in range(_ROW):
        heap[n, c] = box[c]
    heap[n, 2 * dim + (0 if upper else 1)] = at
    heap[n, 6] = box[6] + 1.0
    i = n
    while i > 0:
        parent = (i - 1) // 2
        if not _before(heap, i, parent):
            break
        _swap(heap, i, parent)
        i = parent
    return n + 1


@njit_borrowing
def _heap_pop(heap, n, out):
    """Move the first box into out (7,); returns the new size."""
    for c in range(_ROW):
        out[c] = heap[0, c]
    n -= 1
    for c in range(_ROW):
        heap[0, c] = heap[n, c]
    i = 0
    while True:
        child = 2 * i + 1
        if child >= n:
            break
        if child + 1 < n and _before(heap, child + 1, child):
            child += 1
        if not _before(heap, child, i):
            break
        _swap(heap, i, child)
        i = child
    return n


# --- the search -------------------------------------------------------------------------------

@njit_borrowing
def _search(kind, x_t0, x_t1, time_tol, dist_tol, m, delta, tol_out, tol_in, t_max, work, counts):
    """Best-first box search (module docstring); returns the conservative toi, or inf
    when there is no contact at all or none before t_max. work: CCDWork (its search
    buffers); counts: rows.COUNT_* (int64)."""
    heap = work.heap
    corners = work.corners
    scratch = work.scratch
    clipped = work.clipped
    dirs = work.dirs
    bounds = work.bounds
    proj = work.proj
    box = work.box
    for c in range(3):  # the root box: t, u and v in [0, 1], at depth 0
        heap[0, 2 * c] = 0.0
        heap[0, 2 * c + 1] = 1.0
    heap[0, 6] = 0.0
    n = np.int64(1)
    checks = 0
    t_near = np.inf  # earliest certified near-contact time so far
    t_cut = np.inf  # max(t_near - time_tol / 2, 0): only a contact before it could change the answer
    while n > 0:
        n = _heap_pop(heap, n, box)
        if box[0] >= t_near - time_tol:
            return min(box[0], t_cut)
        if box[0] > t_max:
            return np.inf  # every box left starts after t_max
        box[1] = min(box[1], t_cut)
        checks += 1
        counts[COUNT_BOX_CHECKS] += 1
        if checks > MAX_CHECKS:
            return box[0]  # the earliest box still alive
        if kind == VERTEX_FACE and box[2] + box[4] > 1.0:
            continue  # wholly outside the triangle u + v <= 1
        _box_corners(kind, x_t0, x_t1, box, corners)
        if _excluded(corners, tol_out):
            continue
        cubic = _coplanarity_cubic(kind, x_t0, x_t1, box[0], box[1], dist_tol, m, scratch)
        if _cubic_beyond(cubic):
            continue
        shrunk = _shrink(corners, box, tol_out)
        if shrunk < 0:
            continue
        if shrunk > 0:  # check the smaller box afresh
            n = _heap_push_part(heap, n, box, np.int64(0), box[1], np.bool_(False))
            continue
        _set_directions(kind, x_t0, x_t1, 0.5 * (box[0] + box[1]), dist_tol, delta, dirs, bounds)
        if _directions_excluded(dirs, bounds, corners, np.int64(8)):
            continue
        if kind == VERTEX_FACE and box[3] + box[5] > 1.0 and _clipped_excluded(
                kind, x_t0, x_t1, box, tol_out, dirs, bounds, clipped):
            continue
        t_c = _certify(kind, x_t0, x_t1, box, corners, time_tol, tol_in, scratch)
        if t_c >= 0.0:
            t_near = min(t_near, t_c)
            t_cut = max(t_near - 0.5 * time_tol, 0.0)
            if box[0] >= t_near - time_tol:
                return min(box[0], t_cut)
        if n + 2 > HEAP_SIZE:
            return box[0]  # cannot store more: the earliest live box's start
        t_split = _time_before_coplanar(cubic, box[0], box[1], time_tol) if box[1] - box[0] > time_tol else -1.0
        if t_split > 0.0:  # cut off the time before the 4 points can first be coplanar
            n = _heap_push_part(heap, n, box, np.int64(0), t_split, np.bool_(False))
            n = _heap_push_part(heap, n, box, np.int64(0), t_split, np.bool_(True))
            continue
        if box[1] - box[0] > time_tol and _splittable(box, 0) and _start_excluded(corners, tol_out):
            dim = 0
        else:
            dim = _lookahead_dimension(kind, x_t0, x_t1, box, corners, dirs, bounds, scratch, proj)
        if dim < 0:
            return box[0]  # cannot split: the earliest live box's start
        n = _heap_push_half(heap, n, box, dim, np.bool_(False))
        n = _heap_push_half(heap, n, box, dim, np.bool_(True))
    return t_cut  # no contact before it; inf when nothing was certified


@njit_borrowing
def toi_before(kind, x_t0, x_t1, time_tol, dist_tol, t_max, work, counts):
    """Conservative earliest contact time of one query (kind VERTEX_FACE or EDGE_EDGE),
    as vertex_face_toi_kernel / edge_edge_toi_kernel, except that inf may also mean
    "no contact at or before t_max" (for callers that only need a minimum: a triangle
    pair's first contact over its 15 queries). work: CCDWork scratch (x_t0 and x_t1
    may be its x0 and x1); counts: int64 rows.COUNT_* counters."""
    if query_excluded(kind, x_t0, x_t1, dist_tol, t_max, work.scratch):
        return np.inf
    return searched_toi(kind, x_t0, x_t1, time_tol, dist_tol, t_max, work, counts)


@njit_borrowing
def query_excluded(kind, x_t0, x_t1, dist_tol, t_max, scratch):
    """The cheap exclusions of toi_before: no contact at all, or none before t_max, is
    certain without a search (most queries of a triangle pair). scratch: float64 (8, 3).
    A function of its own taking just these arrays: a call costs reference counting
    for every array it is passed, and CCDWork holds eleven."""
    m = _largest_coordinates(x_t0, x_t1)
    delta = _rounding_bound(m)
    if _root_excluded(kind, x_t0, x_t1, (dist_tol + delta[0], dist_tol + delta[1], dist_tol + delta[2])):
        return True  # the common case
    return _coplanarity_excluded(kind, x_t0, x_t1, 0.0, min(1.0, t_max), dist_tol, m, scratch)


@njit_borrowing
def searched_toi(kind, x_t0, x_t1, time_tol, dist_tol, t_max, work, counts):
    """toi_before of a query that query_excluded did not exclude: the box search."""
    m = _largest_coordinates(x_t0, x_t1)
    delta = _rounding_bound(m)
    counts[COUNT_CCD_QUERIES] += 1
    tol_out = (dist_tol + delta[0], dist_tol + delta[1], dist_tol + delta[2])
    tol_in = (tol_out[0] + delta[0], tol_out[1] + delta[1], tol_out[2] + delta[2])
    return _search(kind, x_t0, x_t1, time_tol, dist_tol, m, delta, tol_out, tol_in, t_max, work, counts)


@njit(cache=True)
def _toi(kind, x_t0, x_t1, time_tol, dist_tol):
    """Conservative earliest contact time of one query (kind VERTEX_FACE or EDGE_EDGE)."""
    work = ccd_work()
    return toi_before(kind, x_t0, x_t1, time_tol, dist_tol, np.inf, work, work.counts)


@njit(cache=True)
def vertex_face_toi_kernel(x_t0, x_t1, time_tol, dist_tol):
    """Conservative earliest contact time of a moving point and triangle, inf if none.

    x_t0, x_t1: float64 (4, 3) C-contiguous, rows v, f0, f1, f2 at t = 0 and t = 1
    (length units, finite, |x| < MAX_COORDINATE; not checked here). time_tol: fraction
    of the step (>= 0); dist_tol: length units (>= 0), per axis. Returns a float in
    [0, 1] or inf, with the guarantees of the module docstring. Never raises.
    """
    return _toi(np.int64(VERTEX_FACE), x_t0, x_t1, time_tol, dist_tol)


@njit(cache=True)
def edge_edge_toi_kernel(x_t0, x_t1, time_tol, dist_tol):
    """Conservative earliest contact time of two moving segments, inf if none.

    x_t0, x_t1: float64 (4, 3) C-contiguous, rows ea0, ea1, eb0, eb1 at t = 0 and
    t = 1. Otherwise as vertex_face_toi_kernel.
    """
    return _toi(np.int64(EDGE_EDGE), x_t0, x_t1, time_tol, dist_tol)


# --- a pair of moving triangles -------------------------------------------------------------

@njit_borrowing
def triangle_pair_toi(p0, p1, q0, q1, time_tol, dist_tol, t_max, work, counts):
    """Earliest time in [0, 1] at which moving triangles p and q touch, inf if never.

    p0, p1, q0, q1: (3, 3) vertex positions at t = 0 and t = 1 (linear motion).
    The first contact of two disjoint triangles is a vertex touching a face or
    an edge touching an edge: the minimum over the 6 vertex-face and 9
    edge-edge certified CCD queries (conservative: never later than the true
    time, at most time_tol earlier); each query only searches up to the best
    time found so far, and never beyond t_max: an answer after t_max may come
    back as inf (for callers that only need a minimum). Triangles already
    intersecting at t = 0 (decided exactly) give 0. work: CCDWork scratch; counts:
    int64 rows.COUNT_* counters.
    """
    if triangles_intersect(p0, q0):
        counts[COUNT_CCD_PAIRS] += 1
        return 0.0
    return disjoint_pair_toi(p0, p1, q0, q1, time_tol, dist_tol, t_max, work, counts)


@njit_borrowing
def disjoint_pair_toi(p0, p1, q0, q1, time_tol, dist_tol, t_max, work, counts):
    """triangle_pair_toi of triangles known not to intersect at t = 0 (the caller has just
    decided it exactly): the 15 queries without that test."""
    counts[COUNT_CCD_PAIRS] += 1
    x0 = work.x0
    x1 = work.x1
    scratch = work.scratch
    # np.int64: the query code is compiled once for both kinds, not once per literal kind
    vertex_face = np.int64(VERTEX_FACE)
    edge_edge = np.int64(EDGE_EDGE)
    best = np.inf
    for tri0, tri1, other0, other1 in ((p0, p1, q0, q1), (q0, q1, p0, p1)):
        for v in range(3):  # vertex of one triangle against the other's face
            for c in range(3):
                x0[0, c] = tri0[v, c]
                x1[0, c] = tri1[v, c]
                for r in range(3):
                    x0[r + 1, c] = other0[r, c]
                    x1[r + 1, c] = other1[r, c]
            limit = min(best, t_max)
            if not query_excluded(vertex_face, x0, x1, dist_tol, limit, scratch):
                best = min(best, searched_toi(vertex_face, x0, x1, time_tol, dist_tol, limit, work, counts))
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
            limit = min(best, t_max)
            if not query_excluded(edge_edge, x0, x1, dist_tol, limit, scratch):
                best = min(best, searched_toi(edge_edge, x0, x1, time_tol, dist_tol, limit, work, counts))
            if best == 0.0:
                return 0.0
    return best


# --- batched public API -----------------------------------------------------------------------

@njit(cache=True, parallel=True)
def _toi_batch(kind, x_t0, x_t1, time_tol, dist_tol):
    """float64 (n,) times of the n queries x_t0[i], x_t1[i] (each (4, 3)), in blocks that
    share one CCDWork."""
    n = x_t0.shape[0]
    out = np.empty(n)
    n_blocks = (n + _BATCH_BLOCK - 1) // _BATCH_BLOCK
    for block in prange(n_blocks):
        work = ccd_work()
        for i in range(block * _BATCH_BLOCK, min(n, (block + 1) * _BATCH_BLOCK)):
            out[i] = toi_before(kind, x_t0[i], x_t1[i], time_tol, dist_tol, np.inf, work, work.counts)
    return out


#: queries per block of the batched API (one scratch allocation per block)
_BATCH_BLOCK = 256


def _as_queries(x, name):
    """x as a C-contiguous float64 (n, 4, 3) array (a single (4, 3) query becomes n = 1)."""
    try:
        array = np.asarray(x)
    except (TypeError, ValueError) as error:  # ragged nested lists and the like
        raise ValueError(f"{name}: expected an array of shape (n, 4, 3): {error}") from None
    if array.dtype == np.bool_ or not (np.issubdtype(array.dtype, np.floating)
                                       or np.issubdtype(array.dtype, np.integer)):
        raise ValueError(f"{name}: expected real numbers, got dtype {array.dtype}")
    if array.shape == (4, 3):
        array = array[None]
    if array.ndim != 3 or array.shape[1:] != (4, 3):
        raise ValueError(f"{name}: expected shape (n, 4, 3) or (4, 3), got {array.shape}")
    array = np.ascontiguousarray(array, dtype=np.float64)
    if not np.isfinite(array).all():
        raise ValueError(f"{name}: coordinates must be finite")
    if array.size and np.abs(array).max() >= MAX_COORDINATE:
        raise ValueError(f"{name}: coordinates must be below {MAX_COORDINATE:g} in magnitude")
    return array


def _batch(kind, x_t0, x_t1, time_tol, dist_tol):
    """Validate and convert the inputs, then run the parallel kernel."""
    x_t0 = _as_queries(x_t0, "x_t0")
    x_t1 = _as_queries(x_t1, "x_t1")
    if x_t0.shape != x_t1.shape:
        raise ValueError(f"x_t0 and x_t1 differ in shape: {x_t0.shape} and {x_t1.shape}")
    time_tol = float(time_tol)
    dist_tol = float(dist_tol)
    if not 0.0 <= time_tol < np.inf:
        raise ValueError(f"time_tol must be finite and >= 0, got {time_tol}")
    if not 0.0 <= dist_tol < np.inf:
        raise ValueError(f"dist_tol must be finite and >= 0, got {dist_tol}")
    return _toi_batch(kind, x_t0, x_t1, time_tol, dist_tol)


def vertex_face_toi(x_t0, x_t1, time_tol=1e-6, dist_tol=0.0):
    """Conservative earliest times of contact of moving points and triangles (SPEC §5).

    x_t0, x_t1: array-like (n, 4, 3), or a single (4, 3) query (then n = 1), converted
    to C-contiguous float64: rows v, f0, f1, f2 at t = 0 and t = 1 (length units);
    every vertex moves linearly in between. time_tol: fraction of the step (>= 0);
    dist_tol: length units (>= 0), applied per axis.

    Returns float64 (n,): for each query a time in [0, 1] never later than the first
    time the point is within dist_tol of the closed triangle (touching counts), and
    at most time_tol before a time at which it is within dist_tol plus a certified
    rounding bound (~1.4e-14 x the largest coordinate) of it; inf when it never
    comes within dist_tol. Raises ValueError for bad shapes, non-numeric,
    non-finite or huge (>= 1e150) input, or bad tolerances.
    """
    return _batch(VERTEX_FACE, x_t0, x_t1, time_tol, dist_tol)


def edge_edge_toi(x_t0, x_t1, time_tol=1e-6, dist_tol=0.0):
    """Conservative earliest times of contact of moving segments (SPEC §5).

    x_t0, x_t1: array-like (n, 4, 3), or a single (4, 3) query: rows ea0, ea1, eb0,
    eb1 at t = 0 and t = 1, for the closed segments ea0 ea1 and eb0 eb1 (length
    units). Returns float64 (n,) times in [0, 1] or inf, with the guarantees and
    errors of vertex_face_toi.
    """
    return _batch(EDGE_EDGE, x_t0, x_t1, time_tol, dist_tol)
