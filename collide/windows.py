"""Moving-box windows: when, within a step (or sub-step), two moving triangles can be close.

Used to cull triangle pairs before the certified CCD (narrow.py, over a whole step) and
sub-steps of the screw refinement (motion.py). Triangles are 9-tuples of their corners,
row by row (``corners_of``): tuples, not arrays, since array arguments and views cost
reference counting on every call in numba.
"""
import numpy as np

from .jit import njit, njit_borrowing


@njit_borrowing
def corners_of(t):
    """Triangle t (3, 3) as a 9-tuple, row by row."""
    return (t[0, 0], t[0, 1], t[0, 2], t[1, 0], t[1, 1], t[1, 2], t[2, 0], t[2, 1], t[2, 2])


#: relative rounding allowance of the moving-box windows (a few ulps of the coordinates)
_WINDOW_ULPS = 8.0 * 2.0 ** -52


@njit_borrowing
def clip_rising(f0, f1, t_lo, t_hi):
    """Restrict [t_lo, t_hi] to where f(t) = f0 + t (f1 - f0) >= 0 (widened by 1e-12 in t
    for the rounding of the root); empty (t_lo > t_hi) when f < 0 on all of [0, 1]."""
    if f0 >= 0.0 and f1 >= 0.0:
        return t_lo, t_hi
    if f0 < 0.0 and f1 < 0.0:
        return 1.0, 0.0
    root = f0 / (f0 - f1)
    if f0 < 0.0:
        return max(t_lo, root - 1e-12), t_hi
    return t_lo, min(t_hi, root + 1e-12)


@njit_borrowing
def swept_window(p0, p1, q0, q1, margin):
    """swept_window_of for triangles given as (3, 3) arrays."""
    return swept_window_of(corners_of(p0), corners_of(p1), corners_of(q0), corners_of(q1), margin)


@njit_borrowing
def swept_window_of(p0, p1, q0, q1, margin):
    """(t_lo, t_hi) in [0, 1]: outside it the two moving triangles cannot come within
    margin (length units) of each other; t_lo > t_hi when they never do.

    Under linear vertex motion a triangle's extent along any axis n at fraction t of the
    step lies inside the linear blend of its extents at both ends (the largest n.x over
    the corners is convex in t); under screw motion within its deviation bound of it
    (motion.py), which the caller adds to margin. Two such blended extents overlap on an
    interval of t found from two linear functions. Any axis fixed over the step will do.
    These: x, y, z (the corner boxes, box_window); both triangles' normals at the step's
    start, which separate close, nearly parallel faces that boxes do not; and, for what
    is left, the nine cross products of an edge of each at the step's start, which
    separate edges passing close to each other (about two thirds of the pairs the
    other five axes leave on the benchmark scenes, each of which would cost a certified
    search); those two: cross_window. The margin grows by a few ulps for rounding.
    Triangles p0, p1 (p at the step's start and end), q0, q1: 9-tuples (corners_of).
    """
    p_box = moving_box(p0, p1)
    q_box = moving_box(q0, q1)
    t_lo, t_hi = box_window(p_box, q_box, margin)
    if t_lo > t_hi:
        return t_lo, t_hi
    return cross_window(p0, p1, q0, q1, margin, largest_coordinate(p_box, q_box), t_lo, t_hi)


@njit_borrowing
def moving_box(t0, t1):
    """The corner boxes of a triangle at both ends of a step (9-tuples t0, t1) as a
    15-tuple: for axis c, (lo at t0, hi at t0, lo at t1, hi at t1) at 4 c to 4 c + 3,
    and the largest |coordinate| of the four at 12 + c. Computed once per triangle, not
    once per triangle pair."""
    x = _axis_extents(t0, t1, 0)
    y = _axis_extents(t0, t1, 1)
    z = _axis_extents(t0, t1, 2)
    return (x[0], x[1], x[2], x[3], y[0], y[1], y[2], y[3], z[0], z[1], z[2], z[3], x[4], y[4], z[4])


@njit_borrowing
def _axis_extents(t0, t1, c):
    lo0 = min(t0[c], t0[3 + c], t0[6 + c])
    hi0 = max(t0[c], t0[3 + c], t0[6 + c])
    lo1 = min(t1[c], t1[3 + c], t1[6 + c])
    hi1 = max(t1[c], t1[3 + c], t1[6 + c])
    return lo0, hi0, lo1, hi1, max(abs(lo0), abs(hi0), abs(lo1), abs(hi1))


@njit_borrowing
def largest_coordinate(p_box, q_box):
    """The largest |coordinate| of two moving_box tuples."""
    return max(p_box[12], p_box[13], p_box[14], q_box[12], q_box[13], q_box[14])


@njit(cache=True, inline="always")  # part of its callers: a call per node pair costs more than the test
def box_window(p_box, q_box, margin):
    """swept_window_of along x, y and z, from the triangles' moving_box tuples: (t_lo,
    t_hi), t_lo > t_hi when the boxes never come within margin of each other."""
    t_lo = 0.0
    t_hi = 1.0
    for c in range(3):
        m = margin + _WINDOW_ULPS * max(p_box[12 + c], q_box[12 + c])
        # p's top above q's bottom, q's top above p's bottom
        t_lo, t_hi = clip_rising(p_box[4 * c + 1] - q_box[4 * c] + m, p_box[4 * c + 3] - q_box[4 * c + 2] + m,
                                 t_lo, t_hi)
        t_lo, t_hi = clip_rising(q_box[4 * c + 1] - p_box[4 * c] + m, q_box[4 * c + 3] - p_box[4 * c + 2] + m,
                                 t_lo, t_hi)
        if t_lo > t_hi:
            return t_lo, t_hi
    return t_lo, t_hi


@njit_borrowing
def cross_window(p0, p1, q0, q1, margin, largest, t_lo, t_hi):
    """[t_lo, t_hi] restricted by swept_window_of's tests along the triangles' normals and
    the cross products of their edges at the step's start; largest: the largest
    |coordinate| of the four corner sets (largest_coordinate), for rounding."""
    xs, ys, zs = _coordinates(p0, p1, q0, q1)
    for side in range(2):  # the normals: edge (0, 1) x edge (0, 2)
        u = p0 if side == 0 else q0
        t_lo, t_hi = _clip_along(_cross(u, 0, 1, u, 0, 2), xs, ys, zs, margin, largest, t_lo, t_hi)
        if t_lo > t_hi:
            return t_lo, t_hi
    for i in range(3):  # edge (i, i + 1) of p against edge (j, j + 1) of q
        for j in range(3):
            t_lo, t_hi = _clip_along(_cross(p0, i, (i + 1) % 3, q0, j, (j + 1) % 3), xs, ys, zs, margin, largest,
                                     t_lo, t_hi)
            if t_lo > t_hi:
                return t_lo, t_hi
    return t_lo, t_hi


@njit(cache=True, inline="always")
def _coordinates(p0, p1, q0, q1):
    """The x, y and z coordinates of the corners of p0, p1, q0 and q1 (9-tuples), three
    per triangle in that order, as three 12-tuples: laid out so that the 12 dot products
    of _clip_along vectorise."""
    xs = (p0[0], p0[3], p0[6], p1[0], p1[3], p1[6], q0[0], q0[3], q0[6], q1[0], q1[3], q1[6])
    ys = (p0[1], p0[4], p0[7], p1[1], p1[4], p1[7], q0[1], q0[4], q0[7], q1[1], q1[4], q1[7])
    zs = (p0[2], p0[5], p0[8], p1[2], p1[5], p1[8], q0[2], q0[5], q0[8], q1[2], q1[5], q1[8])
    return xs, ys, zs


@njit(cache=True, inline="always")
def _cross(u, u0, u1, v, v0, v1):
    """(u[u1] - u[u0]) x (v[v1] - v[v0]) for corners of triangles u and v (9-tuples)."""
    ux = u[3 * u1] - u[3 * u0]
    uy = u[3 * u1 + 1] - u[3 * u0 + 1]
    uz = u[3 * u1 + 2] - u[3 * u0 + 2]
    vx = v[3 * v1] - v[3 * v0]
    vy = v[3 * v1 + 1] - v[3 * v0 + 1]
    vz = v[3 * v1 + 2] - v[3 * v0 + 2]
    return uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx


@njit(cache=True, inline="always")
def _clip_along(n, xs, ys, zs, margin, size, t_lo, t_hi):
    """swept_window_of's test along n (3-tuple): [t_lo, t_hi] restricted to where the
    blended extents of p and q along n come within margin |n|; unchanged when n is zero
    or not finite (parallel edges, a degenerate or huge triangle). xs, ys, zs: the
    corners of p0, p1, q0, q1 (_coordinates). ``size``: the largest |coordinate| of the
    four corner sets, for the rounding of the dot products (at most a few ulps of |n|_1
    size)."""
    nx, ny, nz = n
    length = np.sqrt(nx * nx + ny * ny + nz * nz)
    if not length > 0.0 or not np.isfinite(length):
        return t_lo, t_hi
    # rounding: a few ulps of |n|_1 size, and 1e-300 for products that underflow
    m = margin * length * (1.0 + _WINDOW_ULPS) + _WINDOW_ULPS * size * (abs(nx) + abs(ny) + abs(nz)) + 1e-300
    d = (nx * xs[0] + ny * ys[0] + nz * zs[0], nx * xs[1] + ny * ys[1] + nz * zs[1],
         nx * xs[2] + ny * ys[2] + nz * zs[2], nx * xs[3] + ny * ys[3] + nz * zs[3],
         nx * xs[4] + ny * ys[4] + nz * zs[4], nx * xs[5] + ny * ys[5] + nz * zs[5],
         nx * xs[6] + ny * ys[6] + nz * zs[6], nx * xs[7] + ny * ys[7] + nz * zs[7],
         nx * xs[8] + ny * ys[8] + nz * zs[8], nx * xs[9] + ny * ys[9] + nz * zs[9],
         nx * xs[10] + ny * ys[10] + nz * zs[10], nx * xs[11] + ny * ys[11] + nz * zs[11])
    p_lo0, p_hi0 = _extent(d[0], d[1], d[2])
    p_lo1, p_hi1 = _extent(d[3], d[4], d[5])
    q_lo0, q_hi0 = _extent(d[6], d[7], d[8])
    q_lo1, q_hi1 = _extent(d[9], d[10], d[11])
    t_lo, t_hi = clip_rising(p_hi0 - q_lo0 + m, p_hi1 - q_lo1 + m, t_lo, t_hi)
    return clip_rising(q_hi0 - p_lo0 + m, q_hi1 - p_lo1 + m, t_lo, t_hi)


@njit(cache=True, inline="always")
def _extent(d0, d1, d2):
    """(min, max) of three projections, folded from (inf, -inf) in order."""
    lo = min(min(min(np.inf, d0), d1), d2)
    hi = max(max(max(-np.inf, d0), d1), d2)
    return lo, hi
