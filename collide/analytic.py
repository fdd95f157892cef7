"""Closed-form times of impact from the lecture (../shared/seed/collision-detection-lecture.txt):
spheres against spheres and against planes, over one frame step t in [0, 1] in which
centres move linearly (``C + t v``; v is the displacement over the step).

Sphere-sphere: with s = C0 - C1 the centre offset at t = 0, v = v0 - v1 the relative
velocity and r = r0 + r1, the spheres touch when |s + t v| = r, i.e.

    (v.v) t^2 + 2 (v.s) t + (s.s - r^2) = 0,   a = v.v, b = v.s, c = s.s - r^2,
    t = (-b -+ sqrt(b^2 - a c)) / a.

Sphere-plane: plane n.x = d (n unit), centre C + t v: n.(C + t v) = d +- r gives

    t = (+-r - (n.C - d)) / (n.v).

Numerics: b^2 - a c is computed as a r^2 - |v x s|^2 (the same number, by Lagrange's
identity |v|^2 |s|^2 = (v.s)^2 + |v x s|^2), which avoids the cancellation of b^2
against a (s.s) for far-away spheres; the earlier root as c / (-b + sqrt(b^2 - a c))
(the product of the roots is c / a), which avoids cancelling -b against the square root;
and c itself with a compensated (error-free) sum, as it cancels when the spheres nearly
touch at t = 0.

All functions are vectorised: vector arguments have shape (..., 3), scalar ones
broadcast against (...); the result has shape (...) (a numpy float64 scalar for a
single query). ``sphere_sphere_overlap_window`` is a numba kernel (it runs inside the
swept broad phase) and takes one query of (3,) arrays.
"""
import math

import numpy as np

from .jit import njit

_UNIT_ROUNDOFF = 2.0 ** -53


def _vectors(*arrays):
    """float64 arrays with a last axis of 3 (ValueError otherwise)."""
    out = []
    for a in arrays:
        a = np.asarray(a, dtype=np.float64)
        if a.ndim == 0 or a.shape[-1] != 3:
            raise ValueError(f"expected vectors of shape (..., 3), got shape {a.shape}")
        out.append(a)
    return out


def _dot(a, b):
    return np.sum(a * b, axis=-1)


def _split(a):
    """Dekker's split of a into hi + lo, each with at most 26 significant bits."""
    c = 134217729.0 * a  # 2^27 + 1
    hi = c - (c - a)
    return hi, a - hi


def _two_product(a, b):
    """(p, e) with p = fl(a b) and p + e = a b exactly (no overflow assumed)."""
    p = a * b
    a_hi, a_lo = _split(a)
    b_hi, b_lo = _split(b)
    return p, ((a_hi * b_hi - p) + a_hi * b_lo + a_lo * b_hi) + a_lo * b_lo


def _two_sum(a, b):
    """(s, e) with s = fl(a + b) and s + e = a + b exactly."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


def _offset_c(s, r):
    """c = s.s - r^2, compensated (as if computed in twice the precision, then rounded):
    it cancels when the spheres nearly touch at t = 0, and the smaller root is
    proportional to it."""
    total = np.zeros(np.broadcast_shapes(s.shape[:-1], np.shape(r)))
    error = np.zeros_like(total)
    for x, y in ((s[..., 0], s[..., 0]), (s[..., 1], s[..., 1]), (s[..., 2], s[..., 2]), (r, -r)):
        p, e = _two_product(x, y)
        total, q = _two_sum(total, p)
        error = error + (q + e)
    return total + error


def _scalar_or_array(x):
    """A numpy float64 scalar for 0-d results, else the array."""
    return x[()] if x.ndim == 0 else x


def sphere_sphere_toi(c0, v0, r0, c1, v1, r1):
    """Earliest t in [0, 1] at which spheres (c0 + t v0, r0) and (c1 + t v1, r1) touch.

    c0, v0, c1, v1: (..., 3) centres at t = 0 and displacements over the step (length
    units); r0, r1: radii, scalars or (...). Returns float64 (...): 0 where the
    spheres already touch or overlap at t = 0, inf where they do not meet in [0, 1]
    (moving apart, passing by, or too slow). Uses the lecture's quadratic (module
    docstring) with c = s.s - r^2 compensated; accurate to a few units in the last
    place away from grazing contact (not a conservative bound).
    """
    c0, v0, c1, v1 = _vectors(c0, v0, c1, v1)
    s = c0 - c1
    v = v0 - v1
    r = np.asarray(r0, dtype=np.float64) + np.asarray(r1, dtype=np.float64)
    a = _dot(v, v)
    b = _dot(v, s)
    c = _offset_c(s, r)
    discriminant = a * r * r - _dot(np.cross(v, s), np.cross(v, s))
    approaching = (b < 0.0) & (discriminant >= 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = c / (-b + np.sqrt(np.maximum(discriminant, 0.0)))
    t = np.where(approaching & (t <= 1.0), t, np.inf)
    return _scalar_or_array(np.where(c <= 0.0, 0.0, t))


def sphere_plane_toi(c, v, r, n, d):
    """Earliest t in [0, 1] at which the sphere (c + t v, r) touches the plane n.x = d.

    c, v, n: (..., 3) centre at t = 0, displacement over the step, unit plane normal;
    r, d: radius and plane offset (length units), scalars or (...). Returns float64
    (...): 0 where the sphere already touches or crosses the plane at t = 0, inf where
    it does not reach it in [0, 1] (moving away, parallel (n.v = 0) or too slow).
    """
    c, v, n = _vectors(c, v, n)
    r = np.asarray(r, dtype=np.float64)
    distance = _dot(n, c) - np.asarray(d, dtype=np.float64)  # signed, at t = 0
    speed = _dot(n, v)
    target = np.where(distance > 0.0, r, -r)  # the plane displaced toward the sphere's side
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (target - distance) / speed
    t = np.where((speed != 0.0) & (t >= 0.0) & (t <= 1.0), t, np.inf)
    return _scalar_or_array(np.where(np.abs(distance) <= r, 0.0, t))


@njit(cache=True)
def sphere_sphere_overlap_window(s, v, r):
    """Times (t_lo, t_hi) within [0, 1] containing every t with |s + t v| <= r;
    (inf, -inf) when there is none. A conservative broad-phase test.

    s, v: float64 (3,) centre offset at t = 0 and relative displacement over the step;
    r: sum of the radii (length units). Magnitudes should lie within 1e-100..1e100
    (or be 0).

    Method: with e = v / |v|, the closest approach is at distance p = -s.e along the
    path and d = |s x e| from the other centre, so the overlap is |v| t in
    [p - h, p + h] with h = sqrt((r - d)(r + d)). Rounding, with u = 2^-53: p is
    within 8 u |s| and d within 17 u |s| + 2 u d of their exact values, so the radius
    is widened to R = r (1 + 8 u) + 64 u |s|, which makes the computed h no smaller
    than the exact one (to a few u relative), and both ends are widened by
    64 u (|s| + R) / |v| in time (about 1e-14 for comparable sizes), well over the
    remaining error of p, h and the division. Decisions that rule overlap out keep a
    relative margin of 1e-12. A relative motion below 1e-100 of the scene's size is
    treated as none (the window is then [0, 1] if the spheres are close enough).
    """
    u = _UNIT_ROUNDOFF
    ns = math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2])
    nv = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if ns > (r + nv) * (1.0 + 1e-12):  # |s + t v| >= |s| - |v| > r for all t in [0, 1]
        return np.inf, -np.inf
    if nv <= 1e-100 * (ns + r):  # no relative motion to speak of; close enough (above)
        return 0.0, 1.0
    e0 = v[0] / nv
    e1 = v[1] / nv
    e2 = v[2] / nv
    p = -(s[0] * e0 + s[1] * e1 + s[2] * e2)
    w0 = s[1] * e2 - s[2] * e1
    w1 = s[2] * e0 - s[0] * e2
    w2 = s[0] * e1 - s[1] * e0
    dist = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    radius = r * (1.0 + 8.0 * u) + 64.0 * u * ns
    if dist > radius:
        return np.inf, -np.inf
    h = math.sqrt((radius - dist) * (radius + dist))
    widen = 64.0 * u * (ns + radius) / nv
    t_lo = max(0.0, (p - h) / nv - widen)
    t_hi = min(1.0, (p + h) / nv + widen)
    if t_lo > t_hi:
        return np.inf, -np.inf
    return t_lo, t_hi


#: the name the swept broad phase (collide/swept.py) imports
sphere_overlap_window = sphere_sphere_overlap_window
