"""Closed-form times of impact from the lecture (../shared/seed): spheres against
spheres and planes, over one time step t in [0, 1] with centres moving linearly.

Sphere-sphere: with s the centre offset at t = 0, v the relative velocity and r
the sum of radii, |s + t v| = r  <=>  (v·v) t² + 2 (v·s) t + (s·s − r²) = 0,
so with a = v·v, b = v·s, c = s·s − r²:  t = (−b ± sqrt(b² − a c)) / a.

Sphere-plane: plane n·x = d (n unit), centre C + t v: n·(C + t v) = d ± r gives
t = (±r − (n·C − d)) / (n·v).

``sphere_overlap_window`` is the broad-phase form used by continuous scans: the
whole time window in which the spheres overlap, widened so that rounding can
only make it larger, never smaller.
"""
import math

import numpy as np
from numba import njit

_EPS = 2.0 ** -53


@njit(cache=True)
def sphere_overlap_window(s, v, r):
    """Times (t_lo, t_hi) within [0, 1] when |s + t v| <= r; (inf, -inf) if never.

    s, v: float64 (3,) centre offset at t = 0 and relative velocity over the
    step; r: sum of radii. Conservative: computed via the closest approach
    (which avoids the cancellation of b² − a c) with the radius widened by a
    bound on the rounding of |s + t v| and the ends widened by 1e-9 relative.
    """
    a = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    size = math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]) + math.sqrt(a)
    radius = r + 16.0 * _EPS * size
    if a == 0.0:
        if s[0] * s[0] + s[1] * s[1] + s[2] * s[2] <= radius * radius:
            return 0.0, 1.0
        return np.inf, -np.inf
    t_closest = -(v[0] * s[0] + v[1] * s[1] + v[2] * s[2]) / a
    d2 = 0.0
    for i in range(3):
        p = s[i] + t_closest * v[i]
        d2 += p * p
    if d2 > radius * radius:
        return np.inf, -np.inf
    half = math.sqrt(radius * radius - d2) / math.sqrt(a)
    widen = 1e-9 * (half + abs(t_closest)) + 1e-300
    t_lo = max(0.0, t_closest - half - widen)
    t_hi = min(1.0, t_closest + half + widen)
    if t_lo > t_hi:
        return np.inf, -np.inf
    return t_lo, t_hi


def sphere_sphere_toi(c0, v0, r0, c1, v1, r1):
    """Earliest t in [0, 1] at which spheres (c0 + t v0, r0) and (c1 + t v1, r1) touch.

    0 when they already overlap at t = 0; inf when they do not meet in [0, 1].
    Uses the lecture's quadratic formula.
    """
    s = np.asarray(c0, dtype=np.float64) - np.asarray(c1, dtype=np.float64)
    v = np.asarray(v0, dtype=np.float64) - np.asarray(v1, dtype=np.float64)
    r = float(r0) + float(r1)
    a, b, c = float(v @ v), float(v @ s), float(s @ s) - r * r
    if c <= 0.0:
        return 0.0
    if a == 0.0 or b >= 0.0:  # not moving, or moving apart
        return np.inf
    discriminant = b * b - a * c
    if discriminant < 0.0:
        return np.inf
    t = (-b - math.sqrt(discriminant)) / a
    return t if t <= 1.0 else np.inf


def sphere_plane_toi(c, v, r, n, d):
    """Earliest t in [0, 1] at which the sphere (c + t v, r) touches the plane n·x = d (n unit).

    0 when it already touches at t = 0; inf when it does not reach the plane in [0, 1].
    """
    c, v, n = (np.asarray(x, dtype=np.float64) for x in (c, v, n))
    distance = float(n @ c) - float(d)
    if abs(distance) <= r:
        return 0.0
    speed = float(n @ v)
    if speed == 0.0:
        return np.inf
    target = r if distance > 0 else -r  # the side the sphere starts on
    t = (target - distance) / speed
    return t if 0.0 <= t <= 1.0 else np.inf
