"""The lecture's closed-form times of impact (collide.analytic): known answers, brute-force
time sampling, and exact rational references (every float is a dyadic rational, so
Fraction(float) is exact; square roots are taken in 60-digit decimal arithmetic)."""
from decimal import Decimal, getcontext
from fractions import Fraction

import numpy as np
import pytest

from collide.analytic import (
    sphere_overlap_window,
    sphere_plane_toi,
    sphere_sphere_overlap_window,
    sphere_sphere_toi,
)

getcontext().prec = 60
T = np.linspace(0.0, 1.0, 100001)
SPACING = T[1] - T[0]


def sampled_overlap(s, v, r):
    """Sampled times at which |s + t v| <= r."""
    d = np.linalg.norm(s[None, :] + T[:, None] * v[None, :], axis=1)
    return T[d <= r]


def exact_roots(s, v, r):
    """Exact (as 60-digit decimals) roots of |s + t v|^2 = r^2, or None (never that close)."""
    s, v, r = [Fraction(float(x)) for x in s], [Fraction(float(x)) for x in v], Fraction(float(r))
    a = sum(x * x for x in v)
    b = sum(x * y for x, y in zip(v, s))
    c = sum(x * x for x in s) - r * r
    if a == 0:
        return None
    disc = b * b - a * c
    if disc < 0:
        return None
    root = Decimal(disc.numerator).sqrt() / Decimal(disc.denominator).sqrt()
    to_dec = lambda f: Decimal(f.numerator) / Decimal(f.denominator)  # noqa: E731
    return (to_dec(-b) - root) / to_dec(a), (to_dec(-b) + root) / to_dec(a)


# --- sphere-sphere time of impact -------------------------------------------------------------

def test_sphere_sphere_known_times():
    # centres 10 apart closing at 20 per step, radii 1 + 2: touch when the gap 10 - 20t = 3
    assert sphere_sphere_toi([0, 0, 0], [10, 0, 0], 1, [10, 0, 0], [-10, 0, 0], 2) == pytest.approx(0.35, abs=1e-15)
    # a glancing pass: offset 2 sideways, radii sum 2.5: touch when 10 - 20t = 1.5
    assert sphere_sphere_toi([0, 2, 0], [20, 0, 0], 1, [10, 0, 0], [0, 0, 0], 1.5) == pytest.approx(0.425, abs=1e-15)
    assert sphere_sphere_toi([0, 0, 0], [0, 0, 0], 1, [1.5, 0, 0], [0, 0, 0], 1) == 0.0      # overlapping
    assert sphere_sphere_toi([0, 0, 0], [5, 0, 0], 1, [2, 0, 0], [0, 0, 0], 1) == 0.0        # touching
    assert sphere_sphere_toi([0, 0, 0], [-1, 0, 0], 1, [5, 0, 0], [0, 0, 0], 1) == np.inf   # moving apart
    assert sphere_sphere_toi([0, 0, 0], [1, 0, 0], 1, [5, 0, 0], [0, 0, 0], 1) == np.inf    # too slow
    assert sphere_sphere_toi([0, 3, 0], [10, 0, 0], 1, [5, 0, 0], [0, 0, 0], 1) == np.inf   # passes by
    assert sphere_sphere_toi([0, 0, 0], [3, 0, 0], 1, [5, 0, 0], [0, 0, 0], 1) == 1.0       # just at the end
    assert sphere_sphere_toi([0, 0, 0], [0, 0, 0], 1, [5, 0, 0], [0, 0, 0], 1) == np.inf    # no motion


def test_sphere_sphere_matches_sampling_and_exact_roots():
    rng = np.random.default_rng(11)
    hits = 0
    for _ in range(400):
        c0, c1, v0, v1 = rng.normal(size=(4, 3)) * [[3], [3], [6], [6]]
        r0, r1 = rng.random(2) * 2 + 0.5
        toi = sphere_sphere_toi(c0, v0, r0, c1, v1, r1)
        times = sampled_overlap(c0 - c1, v0 - v1, r0 + r1)
        if times.size:
            hits += 1
            assert times[0] - SPACING <= toi <= times[0]
        roots = exact_roots(c0 - c1, v0 - v1, r0 + r1)
        if np.linalg.norm(c0 - c1) <= r0 + r1:
            assert toi == 0.0
        elif roots is None or not 0 <= roots[0] <= 1:
            assert toi == np.inf
        else:
            assert abs(toi - float(roots[0])) <= 1e-13
    assert hits > 50


def test_sphere_sphere_far_from_the_origin():
    """Offsets of 1e7 and radii of 1: the textbook b^2 - ac would lose ~14 digits."""
    s, v, r = np.array([1e7, 1.0, 0.0]), np.array([-2e7, 0.0, 0.0]), 1.5
    toi = sphere_sphere_toi(s, v, 1.0, [0, 0, 0], [0, 0, 0], 0.5)
    assert abs(toi - float(exact_roots(s, v, r)[0])) <= 1e-15


def test_sphere_sphere_nearly_touching_at_the_start_is_accurate():
    """t ~ 1e-12: the textbook (-b - sqrt(b^2 - ac)) / a cancels; c / (-b + sqrt(...)) does not."""
    for gap in (1e-9, 1e-11, 1e-13):
        s, v = np.array([2.0 + gap, 0.0, 0.0]), np.array([-1e3, 1.0, 0.5])
        toi = sphere_sphere_toi(s, v, 1.25, [0, 0, 0], [0, 0, 0], 0.75)
        exact = float(exact_roots(s, v, 2.0)[0])
        assert exact > 0 and abs(toi - exact) <= 1e-12 * exact, (gap, toi, exact)


def test_sphere_sphere_is_vectorised():
    rng = np.random.default_rng(2)
    c0, v0, c1, v1 = rng.normal(size=(4, 50, 3)) * 3
    r0, r1 = rng.random(50) + 0.5, 1.0
    batch = sphere_sphere_toi(c0, v0, r0, c1, v1, r1)
    assert batch.shape == (50,) and batch.dtype == np.float64
    single = [sphere_sphere_toi(c0[i], v0[i], r0[i], c1[i], v1[i], r1) for i in range(50)]
    np.testing.assert_array_equal(batch, single)
    assert np.ndim(single[0]) == 0
    with pytest.raises(ValueError):
        sphere_sphere_toi([0, 0], [0, 0], 1, [0, 0], [0, 0], 1)


# --- the conservative overlap window ----------------------------------------------------------

def g_exact(s, v, r, t):
    """|s + t v|^2 - r^2 in exact rationals."""
    return sum((Fraction(float(a)) + t * Fraction(float(b))) ** 2 for a, b in zip(s, v)) - Fraction(float(r)) ** 2


def min_g_on(s, v, r, lo, hi):
    """Exact minimum of the convex quadratic g over [lo, hi] (rationals)."""
    vf = [Fraction(float(x)) for x in v]
    a = sum(x * x for x in vf)
    t = Fraction(lo) if a == 0 else -sum(x * Fraction(float(y)) for x, y in zip(vf, s)) / a
    return g_exact(s, v, r, min(max(t, Fraction(lo)), Fraction(hi)))


def assert_window_contains_overlap(s, v, r):
    """Exactly: no t in [0, 1] outside the returned window has |s + t v| <= r."""
    lo, hi = sphere_sphere_overlap_window(np.asarray(s, float), np.asarray(v, float), float(r))
    if lo > hi:
        assert (lo, hi) == (np.inf, -np.inf)
        assert min_g_on(s, v, r, 0, 1) > 0, "an overlap was declared impossible"
        return None
    assert 0.0 <= lo <= hi <= 1.0
    if lo > 0:
        assert min_g_on(s, v, r, 0, lo) > 0, "the window starts after an overlap"
    if hi < 1:
        assert min_g_on(s, v, r, hi, 1) > 0, "the window ends before an overlap"
    return lo, hi


def test_overlap_window_contains_every_overlap_exactly():
    rng = np.random.default_rng(12)
    nonempty = 0
    for _ in range(600):
        s, v = rng.normal(size=3) * 2, rng.normal(size=3) * 4
        r = rng.random() * 3 + 0.1
        window = assert_window_contains_overlap(s, v, r)
        roots = exact_roots(s, v, r)
        if window is not None and roots is not None and roots[0] <= 1 and roots[1] >= 0:
            nonempty += 1  # and it is tight: within 1e-12 of the exact window
            assert window[0] >= max(0.0, float(roots[0])) - 1e-12
            assert window[1] <= min(1.0, float(roots[1])) + 1e-12
    assert nonempty > 120


def test_overlap_window_grazing_and_extreme_cases():
    cases = [
        ([1e7, 1.0, 0.0], [-2e7, 0.0, 0.0], 1.0),            # passes at distance exactly r, at t = 1/2
        ([1e7, 1.0, 0.0], [-2e7, 0.0, 0.0], 1.0 - 2 ** -40),  # misses by a hair
        ([3.0, 4.0, 0.0], [-6.0, 0.0, 0.0], 4.0),             # tangent at t = 1/2, small numbers
        ([1e-3, 1e-3, 0.0], [-2e-3, 0.0, 0.0], 1e-3),         # small scene
        ([1e5, 1e5, 1e5], [-2e5, -2e5, -2e5], 1e-3),          # through the centre, long path
        ([2.0, 0.0, 0.0], [0.0, 0.0, 0.0], 2.0),              # no motion, touching
        ([2.0, 0.0, 0.0], [0.0, 0.0, 0.0], 1.999999),         # no motion, apart
        ([2.0, 0.0, 0.0], [1e-120, 0.0, 0.0], 2.0),           # next to no motion
        ([0.5, 0.0, 0.0], [3.0, 0.0, 0.0], 1.0),              # overlapping at the start only
        ([-3.5, 0.0, 0.0], [3.0, 0.0, 0.0], 1.0),             # overlapping at the end only
        ([0.1, 0.2, 0.3], [1e9, 1e9, -1e9], 1e3),             # very fast
    ]
    windows = [assert_window_contains_overlap(*case) for case in cases]
    assert windows[0] is not None and windows[0][0] <= 0.5 <= windows[0][1]
    assert windows[2] is not None and windows[2][0] <= 0.5 <= windows[2][1]
    assert windows[5] == (0.0, 1.0) and windows[6] is None
    assert windows[8][0] == 0.0 and windows[9][1] == 1.0
    rng = np.random.default_rng(13)
    for _ in range(400):  # grazing passes at all scales: distance of closest approach ~ r
        scale = 10.0 ** rng.integers(-6, 7)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        side = np.cross(d, rng.normal(size=3))
        side /= np.linalg.norm(side)
        r = scale * (rng.random() + 0.1)
        t0 = rng.random()
        s = side * r * (1 + rng.normal() * 1e-15) - t0 * d * scale * 3
        assert_window_contains_overlap(s, d * scale * 3, r)


def test_overlap_window_name_used_by_the_broad_phase():
    assert sphere_overlap_window is sphere_sphere_overlap_window


# --- sphere-plane -------------------------------------------------------------------------------

def test_sphere_plane_known_times():
    n = np.array([0.0, 0.0, 1.0])
    # centre z = 5 moving down 10 per step, radius 1, plane z = 0: touches when z = 1 -> t = 0.4
    assert sphere_plane_toi([0, 0, 5], [0, 0, -10], 1, n, 0) == pytest.approx(0.4, abs=1e-15)
    assert sphere_plane_toi([0, 0, -5], [0, 0, 10], 1, n, 0) == pytest.approx(0.4, abs=1e-15)   # from below
    assert sphere_plane_toi([0, 0, 7], [0, 0, -10], 1, n, 2) == pytest.approx(0.4, abs=1e-15)   # plane z = 2
    assert sphere_plane_toi([0, 0, 0.5], [0, 0, 3], 1, n, 0) == 0.0                  # touching already
    assert sphere_plane_toi([0, 0, 1], [0, 0, -3], 1, n, 0) == 0.0                   # exactly touching
    assert sphere_plane_toi([0, 0, 5], [3, 0, 0], 1, n, 0) == np.inf                 # parallel motion
    assert sphere_plane_toi([0, 0, 5], [0, 0, -2], 1, n, 0) == np.inf                # does not reach
    assert sphere_plane_toi([0, 0, 5], [0, 0, 2], 1, n, 0) == np.inf                 # moves away
    assert sphere_plane_toi([0, 0, 5], [0, 0, -4], 1, n, 0) == 1.0                   # at the very end
    tilted = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    assert sphere_plane_toi([3, 3, 0], [-6, -6, 0], np.sqrt(2), tilted, 0) == pytest.approx(1 / 3, abs=1e-15)


def test_sphere_plane_matches_sampling_and_exact_time():
    rng = np.random.default_rng(13)
    hits = 0
    for _ in range(300):
        c, v = rng.normal(size=3) * 4, rng.normal(size=3) * 8
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        d, r = rng.normal(), rng.random() + 0.1
        toi = sphere_plane_toi(c, v, r, normal, d)
        dist = np.abs((c[None, :] + T[:, None] * v[None, :]) @ normal - d)
        touching = T[dist <= r]
        if touching.size:
            hits += 1
            assert touching[0] - SPACING <= toi <= touching[0]
            # exact: the signed distance is linear in t
            nf = [Fraction(float(x)) for x in normal]
            dist0 = sum(a * Fraction(float(b)) for a, b in zip(nf, c)) - Fraction(float(d))
            speed = sum(a * Fraction(float(b)) for a, b in zip(nf, v))
            rf = Fraction(float(r))
            exact = 0 if abs(dist0) <= rf else ((rf if dist0 > 0 else -rf) - dist0) / speed
            assert abs(toi - float(exact)) <= 1e-14
        else:
            assert toi == np.inf
    assert hits > 60


def test_sphere_plane_is_vectorised():
    rng = np.random.default_rng(4)
    c, v = rng.normal(size=(2, 40, 3)) * 4
    n = np.array([0.0, 1.0, 0.0])
    toi = sphere_plane_toi(c, v, 1.0, n, 0.5)
    assert toi.shape == (40,)
    np.testing.assert_array_equal(toi, [sphere_plane_toi(c[i], v[i], 1.0, n, 0.5) for i in range(40)])
    with pytest.raises(ValueError):
        sphere_plane_toi([0, 0, 0, 0], [0, 0, 0, 0], 1.0, n, 0.0)
