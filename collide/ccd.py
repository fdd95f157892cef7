"""Certified continuous collision detection (CCD) of moving primitives.

Two queries, each over one time step in which every vertex moves on a straight
line from its position at t = 0 to its position at t = 1:

- vertex-face: point ``v`` against the closed triangle ``f0 f1 f2``;
- edge-edge: closed segment ``ea0 ea1`` against closed segment ``eb0 eb1``.

Both return a *conservative* earliest time of contact: never later than the
true first contact t*, and at most ``time_tol`` earlier (``inf`` when the
primitives never come within ``dist_tol``). They never miss a contact.

Method (inclusion-based root finding, in the spirit of Wang et al. 2021,
"Tight-Inclusion"): contact means F(t, u, v) = 0 for some (t, u, v) in the
domain, with

    vertex-face: F = v(t) - f0(t) - u (f1(t) - f0(t)) - v (f2(t) - f0(t)),
                 t, u, v in [0, 1], u + v <= 1
    edge-edge:   F = ea0(t) + u (ea1(t) - ea0(t)) - eb0(t) - v (eb1(t) - eb0(t)),
                 t, u, v in [0, 1]

and x(t) = x_t0 + t (x_t1 - x_t0). F is affine in each of t, u, v separately,
so over a box of (t, u, v) each coordinate of F lies between the smallest and
largest of its values at the box's 8 corners. A box whose corner values, widened
by the rounding bound below plus ``dist_tol``, exclude 0 on some axis holds no
contact and is dropped; otherwise it is split in two. Boxes are visited in
order of their earliest time, so the first box that is small enough (time
width <= time_tol, F range within the tolerances) gives the answer: its lower
time bound is <= t*, because the box holding t* was never dropped.

Rounding bound. Corner values are computed as x(t) = x_t0 + t * (x_t1 - x_t0),
then (vertex-face) (v - f0) - u (f1 - f0) - v (f2 - f0), (edge-edge)
(ea0 - eb0) + u (ea1 - ea0) - v (eb1 - eb0), with t, u, v dyadic (exact).
With m the largest |coordinate| of the 8 input points on an axis and
eps = 2^-53: each x(t) is within 5 eps m of its exact value and has magnitude
<= m (1 + 5 eps); each difference of two is within 12 eps m; each product with
u or v within 14 eps m; the three-term sum within 12 + 14 + 14 + (2 + 4 + 6) eps m
= 52 eps m. We use 128 eps m per axis (the ignored O(eps^2) terms are far
smaller than the slack). Inputs must be free of overflow/underflow.

If a query needs more than ``MAX_CHECKS`` box checks or more than ``HEAP_SIZE``
live boxes, the earliest live box's lower time is returned: still conservative.
"""
import numpy as np
from numba import njit, prange

VERTEX_FACE = 0
EDGE_EDGE = 1

_EPS = 2.0 ** -53
#: rounding bound per axis, as a multiple of eps * max |coordinate| (derivation above)
ROUNDING_FACTOR = 128.0
#: box checks per query before giving a conservative answer
MAX_CHECKS = 50_000
#: live boxes per query before giving a conservative answer
HEAP_SIZE = 2048
#: boxes narrower than this (in t, u or v) are not split further
_MIN_WIDTH = 2.0 ** -60


# --- F at the corners of a box ------------------------------------------------------------

@njit(cache=True, inline="always")
def _f_value(kind, x_t0, x_t1, t, u, v, axis):
    """One coordinate of F at (t, u, v), evaluated in the order the bound assumes."""
    p0 = x_t0[0, axis] + t * (x_t1[0, axis] - x_t0[0, axis])
    p1 = x_t0[1, axis] + t * (x_t1[1, axis] - x_t0[1, axis])
    p2 = x_t0[2, axis] + t * (x_t1[2, axis] - x_t0[2, axis])
    p3 = x_t0[3, axis] + t * (x_t1[3, axis] - x_t0[3, axis])
    if kind == VERTEX_FACE:  # p0 = v, p1 = f0, p2 = f1, p3 = f2
        return ((p0 - p1) - u * (p2 - p1)) - v * (p3 - p1)
    # p0 = ea0, p1 = ea1, p2 = eb0, p3 = eb1
    return ((p0 - p2) + u * (p1 - p0)) - v * (p3 - p2)


@njit(cache=True)
def _box_corners(kind, x_t0, x_t1, box, corners):
    """corners (8, 3) = F at the 8 corners of box (t_lo, t_hi, u_lo, u_hi, v_lo, v_hi)."""
    for c in range(8):
        t = box[0] if (c & 1) == 0 else box[1]
        u = box[2] if (c & 2) == 0 else box[3]
        v = box[4] if (c & 4) == 0 else box[5]
        for axis in range(3):
            corners[c, axis] = _f_value(kind, x_t0, x_t1, t, u, v, axis)


@njit(cache=True)
def _split_dimension(corners, box):
    """Dimension (0 t, 1 u, 2 v) whose change moves F the most, among the splittable ones."""
    best = -1
    best_change = -1.0
    for dim in range(3):
        if box[2 * dim + 1] - box[2 * dim] <= _MIN_WIDTH:
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


@njit(cache=True)
def _excluded(corners, tol):
    """Some axis of F keeps a sign over the box, beyond the tolerance: no contact in it."""
    for axis in range(3):
        lo = corners[:, axis].min()
        hi = corners[:, axis].max()
        if lo > tol[axis] or hi < -tol[axis]:
            return True
    return False


@njit(cache=True)
def _small_in_space(corners, tol):
    """At every time of the box, F varies by at most 2 tol over its (u, v) range.

    Checked on the two time faces of the box (corners with t = t_lo, then t =
    t_hi); F is affine in t, so intermediate times vary no more than these.
    """
    for face in range(2):
        for axis in range(3):
            lo = np.inf
            hi = -np.inf
            for c in range(face, 8, 2):
                lo = min(lo, corners[c, axis])
                hi = max(hi, corners[c, axis])
            if hi - lo > 2.0 * tol[axis]:
                return False
    return True


@njit(cache=True)
def _time_split_excludes_a_half(kind, x_t0, x_t1, box, corners, tol, mid_face):
    """Halving the box in time drops one half at once.

    Preferring such splits keeps boxes that straddle a contact time from
    multiplying along (u, v) when the contact set is a line or an area
    (parallel edges, coplanar sliding), which would otherwise exhaust the search.
    Only the 4 corners at the middle time are new; the halves share the box's
    own corners at t_lo (even indices of ``corners``) and t_hi (odd ones).
    """
    if box[1] - box[0] <= _MIN_WIDTH:
        return False
    mid = 0.5 * (box[0] + box[1])
    for c in range(4):
        u = box[2] if (c & 1) == 0 else box[3]
        v = box[4] if (c & 2) == 0 else box[5]
        for axis in range(3):
            mid_face[c, axis] = _f_value(kind, x_t0, x_t1, mid, u, v, axis)
    for side in range(2):  # 0: [t_lo, mid] with corners 0, 2, 4, 6; 1: [mid, t_hi] with 1, 3, 5, 7
        for axis in range(3):
            lo = mid_face[:, axis].min()
            hi = mid_face[:, axis].max()
            for c in range(side, 8, 2):
                lo = min(lo, corners[c, axis])
                hi = max(hi, corners[c, axis])
            if lo > tol[axis] or hi < -tol[axis]:
                return True
    return False


# --- a min-heap of boxes keyed by (t_lo, -depth) --------------------------------------------

@njit(cache=True, inline="always")
def _before(heap, i, j):
    return heap[i, 0] < heap[j, 0] or (heap[i, 0] == heap[j, 0] and heap[i, 6] > heap[j, 6])


@njit(cache=True)
def _heap_push(heap, n, box, depth):
    heap[n, :6] = box
    heap[n, 6] = depth
    i = n
    while i > 0:
        parent = (i - 1) // 2
        if not _before(heap, i, parent):
            break
        for c in range(7):
            heap[i, c], heap[parent, c] = heap[parent, c], heap[i, c]
        i = parent
    return n + 1


@njit(cache=True)
def _heap_pop(heap, n, out):
    """Remove the first box into out (7,); returns the new size."""
    out[:] = heap[0]
    n -= 1
    heap[0] = heap[n]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= n:
            break
        child = left
        if left + 1 < n and _before(heap, left + 1, left):
            child = left + 1
        if not _before(heap, child, i):
            break
        for c in range(7):
            heap[i, c], heap[child, c] = heap[child, c], heap[i, c]
        i = child
    return n


@njit(cache=True, inline="always")
def _tolerances(x_t0, x_t1, dist_tol):
    """Per axis (a 3-tuple): the rounding bound of F plus dist_tol (see the module docstring)."""
    m0 = 0.0
    m1 = 0.0
    m2 = 0.0
    for r in range(4):
        m0 = max(m0, abs(x_t0[r, 0]), abs(x_t1[r, 0]))
        m1 = max(m1, abs(x_t0[r, 1]), abs(x_t1[r, 1]))
        m2 = max(m2, abs(x_t0[r, 2]), abs(x_t1[r, 2]))
    scale = ROUNDING_FACTOR * _EPS
    return (scale * m0 + dist_tol, scale * m1 + dist_tol, scale * m2 + dist_tol)


@njit(cache=True, inline="always")
def _root_excluded(kind, x_t0, x_t1, tol):
    """_excluded for the whole domain [0, 1]^3, without storing corners."""
    for axis in range(3):
        lo = np.inf
        hi = -np.inf
        for c in range(8):
            value = _f_value(kind, x_t0, x_t1, float(c & 1), float((c >> 1) & 1), float((c >> 2) & 1), axis)
            lo = min(lo, value)
            hi = max(hi, value)
        if lo > tol[axis] or hi < -tol[axis]:
            return True
    return False


# --- the search --------------------------------------------------------------------------

@njit(cache=True)
def _toi(kind, x_t0, x_t1, time_tol, dist_tol):
    tol = _tolerances(x_t0, x_t1, dist_tol)
    if _root_excluded(kind, x_t0, x_t1, tol):
        return np.inf  # the common case, decided without allocating anything
    corners = np.empty((8, 3))
    root = np.array([0.0, 1.0, 0.0, 1.0, 0.0, 1.0])
    heap = np.empty((HEAP_SIZE, 7))
    mid_face = np.empty((4, 3))
    half = np.empty(6)
    box = np.empty(7)
    n = _heap_push(heap, 0, root, 0.0)
    checks = 0
    while n > 0:
        n = _heap_pop(heap, n, box)
        checks += 1
        if checks > MAX_CHECKS:
            return box[0]
        if kind == VERTEX_FACE and box[2] + box[4] > 1.0:
            continue  # entirely outside the triangle u + v <= 1
        _box_corners(kind, x_t0, x_t1, box, corners)
        if _excluded(corners, tol):
            continue
        small = _small_in_space(corners, tol)
        if small and box[1] - box[0] <= time_tol:
            return box[0]
        if small or _time_split_excludes_a_half(kind, x_t0, x_t1, box, corners, tol, mid_face):
            dim = 0
        else:
            dim = _split_dimension(corners, box)
        if dim < 0 or box[2 * dim + 1] - box[2 * dim] <= _MIN_WIDTH:
            return box[0]  # nothing left to split: conservative
        if n + 2 > HEAP_SIZE:
            return box[0]  # the earliest live box: conservative
        mid = 0.5 * (box[2 * dim] + box[2 * dim + 1])
        half[:] = box[:6]
        half[2 * dim + 1] = mid
        n = _heap_push(heap, n, half, box[6] + 1.0)
        half[2 * dim + 1] = box[2 * dim + 1]
        half[2 * dim] = mid
        n = _heap_push(heap, n, half, box[6] + 1.0)
    return np.inf


@njit(cache=True)
def vertex_face_toi_kernel(x_t0, x_t1, time_tol, dist_tol):
    """Earliest contact time of a moving point and triangle (conservative), inf if none.

    x_t0, x_t1: float64 (4, 3), rows v, f0, f1, f2 at t = 0 and t = 1.
    time_tol: in units of the step; dist_tol: length units.
    """
    return _toi(VERTEX_FACE, x_t0, x_t1, time_tol, dist_tol)


@njit(cache=True)
def edge_edge_toi_kernel(x_t0, x_t1, time_tol, dist_tol):
    """Earliest contact time of two moving segments (conservative), inf if none.

    x_t0, x_t1: float64 (4, 3), rows ea0, ea1, eb0, eb1 at t = 0 and t = 1.
    """
    return _toi(EDGE_EDGE, x_t0, x_t1, time_tol, dist_tol)


# --- batched public API ------------------------------------------------------------------

@njit(cache=True, parallel=True)
def _toi_batch(kind, x_t0, x_t1, time_tol, dist_tol):
    out = np.empty(x_t0.shape[0])
    for i in prange(x_t0.shape[0]):
        out[i] = _toi(kind, x_t0[i], x_t1[i], time_tol, dist_tol)
    return out


def _batch(kind, x_t0, x_t1, time_tol, dist_tol):
    x_t0 = np.ascontiguousarray(x_t0, dtype=np.float64)
    x_t1 = np.ascontiguousarray(x_t1, dtype=np.float64)
    if x_t0.shape == (4, 3):
        x_t0, x_t1 = x_t0[None], x_t1.reshape(1, 4, 3) if x_t1.shape == (4, 3) else x_t1
    if x_t0.ndim != 3 or x_t0.shape[1:] != (4, 3) or x_t1.shape != x_t0.shape:
        raise ValueError(f"expected two float arrays of shape (n, 4, 3), got {x_t0.shape} and {x_t1.shape}")
    if not (np.isfinite(x_t0).all() and np.isfinite(x_t1).all()):
        raise ValueError("coordinates must be finite")
    if not time_tol > 0 or not dist_tol >= 0:
        raise ValueError("time_tol must be > 0 and dist_tol >= 0")
    return _toi_batch(kind, x_t0, x_t1, float(time_tol), float(dist_tol))


def vertex_face_toi(x_t0, x_t1, time_tol=1e-6, dist_tol=0.0):
    """Earliest times of contact of moving points and triangles (SPEC §5).

    x_t0, x_t1: float64 (n, 4, 3) (or one (4, 3) query): rows v, f0, f1, f2 at
    t = 0 and t = 1; every vertex moves linearly in between. Returns float64
    (n,): for each query a time in [0, 1] no later than the first contact and at
    most ``time_tol`` earlier, or inf when the point never comes within
    ``dist_tol`` (length units, per axis) of the closed triangle.
    """
    return _batch(VERTEX_FACE, x_t0, x_t1, time_tol, dist_tol)


def edge_edge_toi(x_t0, x_t1, time_tol=1e-6, dist_tol=0.0):
    """Earliest times of contact of moving segments: rows ea0, ea1, eb0, eb1 (see vertex_face_toi)."""
    return _batch(EDGE_EDGE, x_t0, x_t1, time_tol, dist_tol)
