"""How objects move between two frames: the one place that knows (SPEC: ``--interpolation``).

Between frames k and k+1 (a *step*, time fraction t in [0, 1]) each object moves in one
of two ways:

- ``linear-vertex``: every world-space vertex moves on the straight line (the *chord*)
  from its position at frame k to its position at frame k+1. This is the motion of the
  continuous-collision literature and of simulators that step vertices.
- ``screw`` (the default): the object moves rigidly by the constant world-space twist
  taking its pose at frame k to its pose at frame k+1, ``T(t) = exp(t log(T1 T0^-1)) T0``:
  a rotation by ``t theta`` about a fixed axis (direction ``omega`` through a point
  ``c``) combined with a translation ``t d`` along that axis. It is exact for a part
  turning about a fixed joint and for pure translation, and does not depend on where
  the body frame's origin is.

Everything else in the engine sees a motion through the functions of this module: the
world position at a fraction of a step (``points_at``), swept bounds of a body box
(``swept_box``, ``box_deviation``), the deviation bound of a point
(``point_deviation``), and the certified first/last contact of a triangle pair
(``triangle_pair_contact``).

Screw parameters of one step (a row of ``MOTION_WIDTH`` floats, all zero for
linear-vertex motion and for pure translation, so those take exactly the linear code
path): with ``dR = R1 R0^T`` and ``dp = p1 - dR p0`` (a world point x at t = 0 goes to
``dR x + dp`` at t = 1), ``theta`` in [0, pi) and ``omega`` from ``dR``, ``d = omega . dp``
and ``w = dp - d omega`` (the displacement across the axis). A world point x at t = 0
then moves to

    S(t, x) = Rot(omega, t theta) x + s(t) Rot(omega, (t - 1) theta / 2) w + t d omega,
    s(t) = sin(t theta / 2) / sin(theta / 2)

(the axis point c = w / 2 + cot(theta / 2) / 2 omega x w never appears, so the formula
stays accurate for tiny angles). Pose matrices are only rigid to within the input
tolerance, so S(1, x) may differ slightly from the frame's x1; the declared path adds
the linear blend that closes the gap, ``x(t) = S(t, x) + t (x1 - S(1, x))``: it ends
exactly at both frame positions, and being linear in t it changes nothing below.

Deviation bound (why chords can stand in for arcs). The path x(t) is C^2 and its
second derivative is that of the rotation: |x''(t)| = theta^2 rho, rho the point's
distance from the screw axis (the same at every t). The chord L(t) through x(0) and
x(1) is x's linear interpolant, and the interpolation error of a C^2 function obeys
|x(t) - L(t)| <= t (1 - t) / 2 max |x''| <= rho theta^2 / 8 (for vectors too: the
error is an integral of x'' against a non-negative kernel of mass t (1 - t) / 2). On
a sub-step of length h the same argument gives rho theta^2 h^2 / 8. A point of a
triangle is a fixed convex combination of its corners, and the motion is affine at
each t, so at every t the screw-moved triangle lies within max over its corners of
that bound (its *deviation*) of the chord-moved triangle. Hence two triangles that
touch under the screw motion have chord triangles within dev_a + dev_b, and the
certified linear CCD (ccd.py) run with its distance tolerance widened by that much
misses no contact of the screw motion. ``theta rho`` is evaluated as
``|theta x_perp - A|`` with ``A = theta c`` (both perpendicular to omega), and
rounding in evaluating positions and bounds is covered by a margin ``eta`` per object
(config.BOX_MARGIN_REL of the magnitudes involved: thousands of times the rounding
error of the few dozen operations).

Sub-step refinement (``_first_on_path``). A widened tolerance alone would report pairs
that only come within dev_a + dev_b. So a sub-step [a, b] of the step is searched with
the linear CCD at tolerance ``dist_tol / 2 + dev h^2 + eta`` (h = b - a, chords
through the path's positions at a and b); no answer means no contact in [a, b]. An
answer tau means no contact before tau; once ``dev h^2 <= dist_tol / 4`` the answer is
final: never after the first contact, at most ``time_tol`` (of the step) before a time
at which the screw-moved triangles are within dist_tol + 2 eta + the CCD's rounding
bound. Otherwise [tau, b] is searched in two parts, the one next to tau first: a piece
of length ``SUB_STEP_PIECE h`` (dev h^2 cut by 16; or the length at which the answer is
final, if that is longer), then the rest (at most 3/4 h: cut by at least 1.7). Only
sub-steps that still report something are refined. (Halving [tau, b] instead took half
as many searches again at 1000 bodies: the contact is usually close to tau.)
Before its search, a sub-step's chords are checked against their moving-box window
(windows.swept_window: boxes and both triangles' normals, margin tol): a sub-step with
no window holds no contact, and one whose window covers at most SHRINK_WINDOW of it is
replaced by that part (shorter, so with a smaller dev h^2). A search with a limit (only
contacts up to it are wanted) starts on [0, limit] rather than the whole step.
The same search runs backwards in time for the last contact.
"""
import math

import numpy as np

from . import config
from .ccd import disjoint_pair_toi, triangle_pair_toi
from .jit import njit, njit_borrowing
from .predicates import triangles_intersect
from .rows import COUNT_SPLITS
from .windows import swept_window

#: interpolation name -> code used by the kernels
INTERPOLATIONS = {"screw": 1, "linear-vertex": 0}
LINEAR_VERTEX = 0
SCREW = 1

# one step's motion of one object: a row of MOTION_WIDTH floats (module docstring)
M_THETA = 0   #: rotation angle, radians in [0, pi)
M_AXIS = 1    #: rows 1-3: unit axis direction omega
M_W = 4       #: rows 4-6: displacement across the axis (length units)
M_D = 7       #: displacement along the axis (length units)
M_A = 8       #: rows 8-10: theta times the axis point c (length units)
M_ETA = 11    #: rounding margin of positions and bounds (length units)
MOTION_WIDTH = 12

#: an object pair's step is cut into at most this many sub-steps (``substeps``)
MAX_PAIR_SUBSTEPS = 64
#: sub-steps shorter than this (fraction of a step) are not split further
MIN_SUBSTEP = 2.0 ** -40
#: time tolerance (fraction of the sub-step) of the searches before the final one, whose
#: answers only trim the sub-step: a coarse one ends the root finder's search early
COARSE_TIME_TOL = 0.5
#: a sub-step whose moving-box window (windows.swept_window) covers at most this fraction of
#: it is replaced by that window (a quarter shorter at least: the search makes progress)
SHRINK_WINDOW = 0.75
#: a triangle-pair search splits at most this many sub-steps before giving its
#: conservative answer (never reached in practice: each split cuts the bound by at least 1.7)
MAX_SUBSTEPS = 4096
#: after a search of a sub-step of length h answers tau, the rest of it is searched as a
#: piece of SUB_STEP_PIECE h next to tau, then what is left (module docstring)
SUB_STEP_PIECE = 0.25


# --- screw parameters -----------------------------------------------------------------------------

@njit_borrowing
def _turn_entry(rp0, rp1, i, j):
    """Entry (i, j) of the rotation dR = R1 R0^T taking pose rp0's rotation to rp1's."""
    return rp1[i, 0] * rp0[j, 0] + rp1[i, 1] * rp0[j, 1] + rp1[i, 2] * rp0[j, 2]


@njit_borrowing
def _moved_offset(rp0, rp1, i):
    """Component i of dp = p1 - dR p0 (dR: _turn_entry)."""
    return rp1[i, 3] - (_turn_entry(rp0, rp1, i, 0) * rp0[0, 3] + _turn_entry(rp0, rp1, i, 1) * rp0[1, 3]
                        + _turn_entry(rp0, rp1, i, 2) * rp0[2, 3])


@njit_borrowing
def screw_motion(rp0, rp1, eta, out):
    """Fill out (MOTION_WIDTH,) with the screw taking pose rp0 to rp1 ((3, 4) [R | p] each).

    eta: rounding margin of the object (length units), stored when the object turns.
    Returns False when the rotation is a half turn within rounding (axis ambiguous),
    True otherwise. A rotation of exactly zero leaves the row all zeros (pure
    translation: the linear path).
    """
    out[:] = 0.0
    v0 = _turn_entry(rp0, rp1, 2, 1) - _turn_entry(rp0, rp1, 1, 2)
    v1 = _turn_entry(rp0, rp1, 0, 2) - _turn_entry(rp0, rp1, 2, 0)
    v2 = _turn_entry(rp0, rp1, 1, 0) - _turn_entry(rp0, rp1, 0, 1)
    sin2 = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)  # 2 sin(theta)
    cos2 = _turn_entry(rp0, rp1, 0, 0) + _turn_entry(rp0, rp1, 1, 1) + _turn_entry(rp0, rp1, 2, 2) - 1.0  # 2 cos(theta)
    if sin2 == 0.0 and cos2 > 0.0:
        return True  # no rotation
    if sin2 <= config.SCREW_HALF_TURN_SIN * 2.0 and cos2 < 0.0:
        return False
    theta = math.atan2(sin2, cos2)
    if cos2 >= 0.0:
        w0, w1, w2 = v0 / sin2, v1 / sin2, v2 / sin2
    else:  # near a half turn: the axis from the symmetric part, oriented by v
        cos_t = 0.5 * cos2
        k = 0
        for i in range(1, 3):
            if _turn_entry(rp0, rp1, i, i) > _turn_entry(rp0, rp1, k, k):
                k = i
        s0 = 0.5 * (_turn_entry(rp0, rp1, 0, k) + _turn_entry(rp0, rp1, k, 0)) - (cos_t if k == 0 else 0.0)
        s1 = 0.5 * (_turn_entry(rp0, rp1, 1, k) + _turn_entry(rp0, rp1, k, 1)) - (cos_t if k == 1 else 0.0)
        s2 = 0.5 * (_turn_entry(rp0, rp1, 2, k) + _turn_entry(rp0, rp1, k, 2)) - (cos_t if k == 2 else 0.0)
        norm = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        if s0 * v0 + s1 * v1 + s2 * v2 < 0.0:
            norm = -norm
        w0, w1, w2 = s0 / norm, s1 / norm, s2 / norm
    # dp = p1 - dR p0, split along and across the axis
    dp0, dp1, dp2 = _moved_offset(rp0, rp1, 0), _moved_offset(rp0, rp1, 1), _moved_offset(rp0, rp1, 2)
    d = w0 * dp0 + w1 * dp1 + w2 * dp2
    out[M_THETA] = theta
    out[M_AXIS], out[M_AXIS + 1], out[M_AXIS + 2] = w0, w1, w2
    out[M_W], out[M_W + 1], out[M_W + 2] = dp0 - d * w0, dp1 - d * w1, dp2 - d * w2
    out[M_D] = d
    # A = theta c = theta w / 2 + (theta cot(theta / 2) / 2) omega x w
    half_cot = 0.5 * theta * math.cos(0.5 * theta) / math.sin(0.5 * theta)
    x0, x1, x2 = out[M_W], out[M_W + 1], out[M_W + 2]
    out[M_A] = 0.5 * theta * x0 + half_cot * (w1 * x2 - w2 * x1)
    out[M_A + 1] = 0.5 * theta * x1 + half_cot * (w2 * x0 - w0 * x2)
    out[M_A + 2] = 0.5 * theta * x2 + half_cot * (w0 * x1 - w1 * x0)
    out[M_ETA] = eta + config.BOX_MARGIN_REL * (abs(x0) + abs(x1) + abs(x2) + abs(d))
    return True


@njit_borrowing
def step_motions(interpolation, rp0, rp1, margins, out):
    """Motion rows out (N, MOTION_WIDTH) of N objects from poses rp0 to rp1 (N, 3, 4).

    margins (N,): each object's rounding margin (length units). Returns the index of
    an object whose screw is ambiguous (a half turn), or -1. Linear-vertex motion:
    all rows zero.
    """
    out[:] = 0.0
    bad = -1
    if interpolation == LINEAR_VERTEX:
        return bad
    for o in range(rp0.shape[0]):
        if not screw_motion(rp0[o], rp1[o], margins[o], out[o]) and bad < 0:
            bad = o
    return bad


@njit(cache=True)
def motion_summary(poses, centres, radii, out):
    """Per step k and object o of poses (T, N, 3, 4): out[k, o, 0] the screw's rotation
    angle (radians; -1 for an ambiguous half turn) and out[k, o, 1] the largest
    distance between any point's chord and its screw path (length units; a bound from
    the object's bounding sphere: body centres (N, 3), radii (N,)). out: (T-1, N, 2)."""
    row = np.empty(MOTION_WIDTH)
    c = np.empty(3)
    for k in range(poses.shape[0] - 1):
        for o in range(poses.shape[1]):
            rp0 = poses[k, o]
            if not screw_motion(rp0, poses[k + 1, o], 0.0, row):
                out[k, o, 0] = -1.0
                out[k, o, 1] = np.inf
                continue
            for i in range(3):
                c[i] = rp0[i, 3] + rp0[i, 0] * centres[o, 0] + rp0[i, 1] * centres[o, 1] \
                    + rp0[i, 2] * centres[o, 2]
            out[k, o, 0] = row[M_THETA]
            out[k, o, 1] = _bound(row, _theta_rho(row, c[0], c[1], c[2]) + row[M_THETA] * radii[o])


# --- positions --------------------------------------------------------------------------------

@njit_borrowing
def _turn(phi):
    """(cos phi, sin phi, 1 - cos phi) of a rotation by phi, the last as 2 sin^2(phi / 2)
    (accurate for small angles): computed once for all the points a rotation moves."""
    h = math.sin(0.5 * phi)
    return math.cos(phi), math.sin(phi), 2.0 * h * h


@njit_borrowing
def _rotate_by(m, x0, x1, x2, turn):
    """Rot(omega, phi) applied to (x0, x1, x2), omega = m[M_AXIS:M_AXIS + 3] (Rodrigues),
    turn = _turn(phi)."""
    w0 = m[M_AXIS]
    w1 = m[M_AXIS + 1]
    w2 = m[M_AXIS + 2]
    c, s, one_minus_c = turn
    dot = (w0 * x0 + w1 * x1 + w2 * x2) * one_minus_c
    return (x0 * c + (w1 * x2 - w2 * x1) * s + w0 * dot,
            x1 * c + (w2 * x0 - w0 * x2) * s + w1 * dot,
            x2 * c + (w0 * x1 - w1 * x0) * s + w2 * dot)


@njit_borrowing
def _screw_at(m, t):
    """What S(t, x) of the module docstring shares over all points x, for fraction t:
    (turn by t theta, s(t), Rot(omega, (t - 1) theta / 2) w as 3 floats, t d)."""
    theta = m[M_THETA]
    s = math.sin(0.5 * t * theta) / math.sin(0.5 * theta)
    u0, u1, u2 = _rotate_by(m, m[M_W], m[M_W + 1], m[M_W + 2], _turn(0.5 * (t - 1.0) * theta))
    return _turn(t * theta), s, u0, u1, u2, t * m[M_D]


@njit_borrowing
def _screw_point(m, x0, x1, x2, at):
    """S(t, x) of the module docstring for the world point (x0, x1, x2) at t = 0, with
    at = _screw_at(m, t)."""
    turn, s, u0, u1, u2, d = at
    r0, r1, r2 = _rotate_by(m, x0, x1, x2, turn)
    return (r0 + s * u0 + d * m[M_AXIS], r1 + s * u1 + d * m[M_AXIS + 1],
            r2 + s * u2 + d * m[M_AXIS + 2])


@njit_borrowing
def points_at(m, x_t0, x_t1, t, out):
    """World positions out (n, 3) at fraction t of the step of points at x_t0 (t = 0)
    and x_t1 (t = 1) (each (n, 3)), under the motion row m. Exact at t = 0 and 1.
    The sines and cosines of the motion at t are computed once, not once per point."""
    if t == 0.0 or t == 1.0:
        src = x_t0 if t == 0.0 else x_t1
        for i in range(x_t0.shape[0]):
            for c in range(3):
                out[i, c] = src[i, c]
    elif m[M_THETA] == 0.0:  # the chord
        for i in range(x_t0.shape[0]):
            for c in range(3):
                out[i, c] = x_t0[i, c] + t * (x_t1[i, c] - x_t0[i, c])
    else:  # x(t) = S(t, x0) + t (x1 - S(1, x0))
        at_t = _screw_at(m, t)
        at_1 = _screw_at(m, 1.0)
        for i in range(x_t0.shape[0]):
            a0, a1, a2 = _screw_point(m, x_t0[i, 0], x_t0[i, 1], x_t0[i, 2], at_t)
            e0, e1, e2 = _screw_point(m, x_t0[i, 0], x_t0[i, 1], x_t0[i, 2], at_1)
            out[i, 0] = a0 + t * (x_t1[i, 0] - e0)
            out[i, 1] = a1 + t * (x_t1[i, 1] - e1)
            out[i, 2] = a2 + t * (x_t1[i, 2] - e2)


@njit_borrowing
def pose_at(m, rp0, rp1, t, out):
    """The affine map out (3, 4) [A | b] taking body points to their world positions at
    fraction t of the step from pose rp0 to rp1 ((3, 4) each) under motion row m:
    A b + p equals points_at's position of every body point. Exact at t = 0 and 1;
    rigid up to the input's own departure from rigidity."""
    if t == 0.0 or t == 1.0:
        end = rp0 if t == 0.0 else rp1
        for i in range(3):
            for j in range(4):
                out[i, j] = end[i, j]
        return
    if m[M_THETA] == 0.0:
        for i in range(3):
            for j in range(4):
                out[i, j] = rp0[i, j] + t * (rp1[i, j] - rp0[i, j])
        return
    # x(t) = Rot(t theta) x0 + c(t) + t (x1 - Rot(theta) x0 - c(1)), x0 = R0 b + p0, x1 = R1 b + p1
    turn_t = _turn(t * m[M_THETA])
    turn_1 = _turn(m[M_THETA])
    for j in range(3):  # columns of R(t): Rot(t theta) R0 + t (R1 - Rot(theta) R0)
        a0, a1, a2 = _rotate_by(m, rp0[0, j], rp0[1, j], rp0[2, j], turn_t)
        e0, e1, e2 = _rotate_by(m, rp0[0, j], rp0[1, j], rp0[2, j], turn_1)
        out[0, j] = a0 + t * (rp1[0, j] - e0)
        out[1, j] = a1 + t * (rp1[1, j] - e1)
        out[2, j] = a2 + t * (rp1[2, j] - e2)
    a0, a1, a2 = _screw_point(m, rp0[0, 3], rp0[1, 3], rp0[2, 3], _screw_at(m, t))
    e0, e1, e2 = _screw_point(m, rp0[0, 3], rp0[1, 3], rp0[2, 3], _screw_at(m, 1.0))
    out[0, 3] = a0 + t * (rp1[0, 3] - e0)
    out[1, 3] = a1 + t * (rp1[1, 3] - e1)
    out[2, 3] = a2 + t * (rp1[2, 3] - e2)


@njit_borrowing
def substeps(m_a, m_b, centre_a, radius_a, centre_b, radius_b):
    """Number of equal sub-steps (a power of 2, at most MAX_PAIR_SUBSTEPS) into which a pair of
    objects' step is cut so that, on each, the two objects' paths stay within
    config.SUBSTEP_DEVIATION_REL of the pair's size of their chords: then boxes bounding a
    sub-step's motion are tight and few triangle pairs come near enough to need a search.
    centre_*: world centres (3,) at t = 0 of the objects' bounding spheres, radius_* their
    radii. 1 for linear-vertex motion and for slow turns."""
    dev = 0.0
    for m, c, r in ((m_a, centre_a, radius_a), (m_b, centre_b, radius_b)):
        if m[M_THETA] > 0.0:
            dev += _bound(m, _theta_rho(m, c[0], c[1], c[2]) + m[M_THETA] * r)
    target = config.SUBSTEP_DEVIATION_REL * 2.0 * (radius_a + radius_b)
    n = 1
    while dev > target * n * n and n < MAX_PAIR_SUBSTEPS:
        n *= 2
    return n


# --- deviation bounds -----------------------------------------------------------------------------

@njit_borrowing
def _theta_rho(m, x0, x1, x2):
    """theta times the distance of the world point (x0, x1, x2) from the screw axis."""
    theta = m[M_THETA]
    along = m[M_AXIS] * x0 + m[M_AXIS + 1] * x1 + m[M_AXIS + 2] * x2
    g0 = theta * (x0 - along * m[M_AXIS]) - m[M_A]
    g1 = theta * (x1 - along * m[M_AXIS + 1]) - m[M_A + 1]
    g2 = theta * (x2 - along * m[M_AXIS + 2]) - m[M_A + 2]
    return math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)


@njit_borrowing
def _bound(m, theta_rho):
    """theta^2 rho / 8 from theta rho, rounded up (a relative 2^-40 covers its rounding)."""
    return 0.125 * m[M_THETA] * theta_rho * (1.0 + 2.0 ** -40)


@njit_borrowing
def point_deviation(m, points):
    """Largest distance (length units) between the path of any of the points (n, 3)
    (world positions at t = 0) and its chord over the whole step: rho theta^2 / 8.
    Excludes the rounding margin m[M_ETA]. 0 for linear-vertex motion."""
    if m[M_THETA] == 0.0:
        return 0.0
    worst = 0.0
    for i in range(points.shape[0]):
        worst = max(worst, _theta_rho(m, points[i, 0], points[i, 1], points[i, 2]))
    return _bound(m, worst)


@njit_borrowing
def corners_deviation(m, corners):
    """point_deviation of a triangle's three corners given as a 9-tuple, row by row."""
    if m[M_THETA] == 0.0:
        return 0.0
    worst = 0.0
    for i in range(3):
        worst = max(worst, _theta_rho(m, corners[3 * i], corners[3 * i + 1], corners[3 * i + 2]))
    return _bound(m, worst)


@njit_borrowing
def sphere_deviation(m, centre):
    """Deviation bound of the path of a world point centre (3,) at t = 0 (no margin)."""
    if m[M_THETA] == 0.0:
        return 0.0
    return _bound(m, _theta_rho(m, centre[0], centre[1], centre[2]))


@njit_borrowing
def box_deviation(m, lo, hi, rp0):
    """Deviation bound (length units) of any point of the body box [lo, hi] (3,) placed
    by pose rp0 (3, 4) at t = 0, plus the rounding margin; 0 for linear motion."""
    return box_deviation_of(m, (lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]), pose_tuple(rp0))


@njit_borrowing
def pose_tuple(rp):
    """Pose [R | p] (3, 4) as a 12-tuple, row by row. Per-node helpers of a descent take
    tuples: array views and array arguments would cost reference counting per node."""
    return (rp[0, 0], rp[0, 1], rp[0, 2], rp[0, 3], rp[1, 0], rp[1, 1], rp[1, 2], rp[1, 3],
            rp[2, 0], rp[2, 1], rp[2, 2], rp[2, 3])


@njit_borrowing
def motion_tuple(m):
    """Motion row m (MOTION_WIDTH,) as a tuple (see pose_tuple)."""
    return (m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11])


if MOTION_WIDTH != 12:
    raise ImportError("motion.motion_tuple spells out a motion row's elements: update it with MOTION_WIDTH")


@njit_borrowing
def box_deviation_of(m, box, rp0):
    """box_deviation of a box 6-tuple (lo x, y, z, hi x, y, z) placed by pose rp0
    (pose_tuple) at t = 0; m: a motion row or motion_tuple."""
    if m[M_THETA] == 0.0:
        return 0.0
    half = 0.0
    for i in range(3):
        half += (0.5 * (box[3 + i] - box[i])) ** 2
    # the box's centre at t = 0
    b0 = 0.5 * (box[0] + box[3])
    b1 = 0.5 * (box[1] + box[4])
    b2 = 0.5 * (box[2] + box[5])
    c0 = rp0[3] + rp0[0] * b0 + rp0[1] * b1 + rp0[2] * b2
    c1 = rp0[7] + rp0[4] * b0 + rp0[5] * b1 + rp0[6] * b2
    c2 = rp0[11] + rp0[8] * b0 + rp0[9] * b1 + rp0[10] * b2
    return ball_deviation(m, (c0, c1, c2), math.sqrt(half))


@njit_borrowing
def ball_deviation(m, centre, radius):
    """Deviation bound (length units) of any point of the ball of the given radius around
    the world point centre (3-tuple) at t = 0, plus the rounding margin m[M_ETA]: the
    centre's theta rho grown by theta radius; 0 for linear motion. m: a motion row or
    motion_tuple."""
    if m[M_THETA] == 0.0:
        return 0.0
    theta_rho = _theta_rho(m, centre[0], centre[1], centre[2]) + m[M_THETA] * radius
    return _bound(m, theta_rho) + m[M_ETA]


# --- swept bounds ---------------------------------------------------------------------------------

@njit_borrowing
def world_interval(lo, hi, rp, i):
    """Range of world coordinate i over the body box [lo, hi] (3,) under rp = [R | p] (3, 4)."""
    return world_interval_of((lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]), pose_tuple(rp), i)


@njit_borrowing
def world_interval_of(box, rp, i):
    """world_interval of a box 6-tuple under a pose_tuple rp."""
    centre, half = centre_and_half(box)
    return placed_interval(centre, half, rp, rotation_magnitudes(rp), i)


@njit(cache=True, inline="always")
def centre_and_half(box):
    """Centre and half extents (3-tuples) of a box 6-tuple (lo x, y, z, hi x, y, z)."""
    return ((0.5 * (box[0] + box[3]), 0.5 * (box[1] + box[4]), 0.5 * (box[2] + box[5])),
            (0.5 * (box[3] - box[0]), 0.5 * (box[4] - box[1]), 0.5 * (box[5] - box[2])))


@njit(cache=True, inline="always")
def placed_interval(centre, half, rp, abs_r, i):
    """World coordinate i's range of a box of centre and half extents (3-tuples, body
    frame) placed by pose tuple rp, whose |R| is abs_r (rotation_magnitudes): callers
    placing many boxes by one pose compute abs_r once."""
    c = rp[4 * i + 3]
    e = 0.0
    for j in range(3):
        c += rp[4 * i + j] * centre[j]
        e += abs_r[3 * i + j] * half[j]
    return c - e, c + e


@njit_borrowing
def rotation_magnitudes(rp):
    """|R| of a pose tuple rp = [R | t] (12-tuple): a 9-tuple, row by row."""
    return (abs(rp[0]), abs(rp[1]), abs(rp[2]), abs(rp[4]), abs(rp[5]), abs(rp[6]), abs(rp[8]), abs(rp[9]),
            abs(rp[10]))


@njit_borrowing
def chord_interval(lo, hi, rp0, rp1, i):
    """World coordinate i's range of body box [lo, hi] at both poses rp0, rp1: it holds
    the box's chords (each point's straight path between the two poses)."""
    return chord_interval_of((lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]), pose_tuple(rp0), pose_tuple(rp1), i)


@njit_borrowing
def chord_interval_of(box, rp0, rp1, i):
    """chord_interval of a box 6-tuple between pose_tuples rp0 and rp1."""
    lo0, hi0 = world_interval_of(box, rp0, i)
    lo1, hi1 = world_interval_of(box, rp1, i)
    return min(lo0, lo1), max(hi0, hi1)


@njit_borrowing
def swept_box(lo, hi, rp0, rp1, m, w_lo, w_hi, widen):
    """Write into w_lo, w_hi (3,) the world AABB of the body box [lo, hi] over the step
    from pose rp0 to rp1 ((3, 4) each) under motion row m: its chord box widened by its
    deviation plus ``widen`` (length units). Pass the same pose twice (and a zero row)
    for a still box. Writes in place: one call per object and frame, no allocation."""
    dev = box_deviation(m, lo, hi, rp0)
    for i in range(3):
        a, b = chord_interval(lo, hi, rp0, rp1, i)
        w_lo[i] = (a - dev) - widen
        w_hi[i] = (b + dev) + widen


# --- triangle pairs: certified first and last contact ---------------------------------------------

@njit_borrowing
def triangle_pair_contact(m_p, m_q, p0, p1, q0, q1, dev, eta, time_tol, dist_tol, limit, backwards, work,
                          counts):
    """Conservative first contact time in [0, 1] of triangles p and q over one step, or
    (backwards) their last contact time; inf (backwards: -inf) if they never touch.

    Only contacts up to ``limit`` (backwards: from ``limit`` on) are looked for: an
    answer beyond it may come back as inf (-inf), never as a value on the wrong side
    of the true one. p0, p1, q0, q1: (3, 3) world corners at t = 0 and t = 1; m_p,
    m_q their motion rows; dev: the sum of both triangles' deviation bounds over the
    whole step (length units, point_deviation), eta the sum of their rounding margins.
    time_tol: fraction of the step; dist_tol: length units. work: ccd.CCDWork scratch.
    With dev == 0 and eta == 0 (linear-vertex motion or pure translation) this is one
    linear CCD of the step. counts: int64 rows.COUNT_* counters.
    """
    if dev == 0.0 and eta == 0.0:
        if backwards:
            return 1.0 - triangle_pair_toi(p1, p0, q1, q0, time_tol, dist_tol, 1.0 - limit, work, counts)
        return triangle_pair_toi(p0, p1, q0, q1, time_tol, dist_tol, limit, work, counts)
    t = _first_on_path(m_p, m_q, p0, p1, q0, q1, dev, eta, time_tol, dist_tol, limit, backwards, work, counts)
    return -np.inf if backwards and t == np.inf else t


@njit_borrowing
def _next_piece(h, dev, dist_tol):
    """Length (fraction of the step) of the piece searched next after a sub-step of length h
    answered (dev: the pair's deviation bound over the whole step, dev > 0): SUB_STEP_PIECE h,
    or, if longer, about the longest piece whose answer is final (dev piece^2 <= dist_tol / 4)."""
    return max(SUB_STEP_PIECE * h, math.sqrt(0.25 * dist_tol / dev) * (1.0 - 2.0 ** -20))


@njit_borrowing
def _first_on_path(m_p, m_q, p0, p1, q0, q1, dev, eta, time_tol, dist_tol, limit, backwards, work, counts):
    """The sub-step refinement of the module docstring. Forwards: earliest contact up to
    limit; backwards: latest contact from limit on (the same search with time running
    from 1 to 0). inf when none."""
    pa, qa, pb, qb = work.path[0], work.path[1], work.path[2], work.path[3]
    stack = work.path_stack  # sub-steps [a, b] still to search; the top one comes first in time
    # only contacts from the limit on (backwards: up to it) are wanted: the search starts on
    # that part of the step, whose shorter chords have the smaller deviation bound dev h^2
    stack[0, 0] = min(max(limit, 0.0), 1.0) if backwards else 0.0
    stack[0, 1] = 1.0 if backwards else min(max(limit, 0.0), 1.0)
    n = 1
    splits = 0
    while n > 0:
        n -= 1
        a = stack[n, 0]
        b = stack[n, 1]
        if (b < limit) if backwards else (a > limit):
            continue
        h = b - a
        points_at(m_p, p0, p1, a, pa)
        points_at(m_q, q0, q1, a, qa)
        points_at(m_p, p0, p1, b, pb)
        points_at(m_q, q0, q1, b, qb)
        if triangles_intersect(pb, qb) if backwards else triangles_intersect(pa, qa):
            return b if backwards else a  # touching where the sub-step starts: no search needed
        sub_dev = dev * h * h
        tol = 0.5 * dist_tol + sub_dev + eta
        t_lo, t_hi = swept_window(pa, pb, qa, qb, tol)  # where the chords can come within tol
        if t_lo > t_hi:
            continue
        if t_hi - t_lo <= SHRINK_WINDOW and h > MIN_SUBSTEP and splits < MAX_SUBSTEPS:
            # only that part of the sub-step can hold a contact: search it alone, with its own
            # smaller deviation bound (bounds rounded outward)
            splits += 1
            stack[n, 0] = a if t_lo <= 0.0 else min(max(np.nextafter(a + t_lo * h, -np.inf), a), b)
            stack[n, 1] = b if t_hi >= 1.0 else max(min(np.nextafter(a + t_hi * h, np.inf), b), a)
            n += 1
            continue
        final = sub_dev <= 0.25 * dist_tol or h <= MIN_SUBSTEP or splits >= MAX_SUBSTEPS or n + 2 > stack.shape[0]
        # only the final answer needs time_tol; before that any lower bound trims the sub-step
        sub_time_tol = time_tol / max(h, MIN_SUBSTEP) if final else COARSE_TIME_TOL
        # the limit in units of the sub-step, rounded outward
        sub_limit = ((b - limit) if backwards else (limit - a)) / max(h, MIN_SUBSTEP) * (1.0 + 2.0 ** -50)
        if backwards:
            tau = disjoint_pair_toi(pb, pa, qb, qa, sub_time_tol, tol, sub_limit, work, counts)
        else:
            tau = disjoint_pair_toi(pa, pb, qa, qb, sub_time_tol, tol, sub_limit, work, counts)
        if tau == np.inf:
            continue
        # no contact in [a, t) (forwards) or (t, b] (backwards); t rounded outward
        if backwards:
            t = min(np.nextafter(b - tau * h, np.inf), b) if tau > 0.0 else b
        else:
            t = max(np.nextafter(a + tau * h, -np.inf), a) if tau > 0.0 else a
        if final:
            return t
        splits += 1
        counts[COUNT_SPLITS] += 1
        # search what is left, [t, b] (backwards: [a, t]): the piece next to t first, then the rest
        piece = min(_next_piece(h, dev, dist_tol), 0.5 * ((t - a) if backwards else (b - t)))
        if backwards:
            mid = t - piece
            stack[n, 0], stack[n, 1] = a, mid
            stack[n + 1, 0], stack[n + 1, 1] = mid, t
        else:
            mid = t + piece
            stack[n, 0], stack[n, 1] = mid, b
            stack[n + 1, 0], stack[n + 1, 1] = t, mid
        n += 2
    return np.inf
