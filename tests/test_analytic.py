"""The lecture's closed-form sphere times of impact, against brute-force time sampling."""
import numpy as np
import pytest

from collide.analytic import sphere_overlap_window, sphere_plane_toi, sphere_sphere_toi

T = np.linspace(0.0, 1.0, 100001)


def sampled_overlap(s, v, r):
    d = np.linalg.norm(s[None, :] + T[:, None] * v[None, :], axis=1)
    return T[d <= r]


def test_sphere_sphere_head_on():
    # centres 10 apart closing at 20 per step, radii 1 + 2: touch when the gap 10 - 20t = 3
    assert sphere_sphere_toi([0, 0, 0], [10, 0, 0], 1, [10, 0, 0], [-10, 0, 0], 2) == pytest.approx(0.35)
    assert sphere_sphere_toi([0, 0, 0], [0, 0, 0], 1, [1.5, 0, 0], [0, 0, 0], 1) == 0.0     # overlapping
    assert sphere_sphere_toi([0, 0, 0], [-1, 0, 0], 1, [5, 0, 0], [0, 0, 0], 1) == np.inf  # moving apart
    assert sphere_sphere_toi([0, 0, 0], [1, 0, 0], 1, [5, 0, 0], [0, 0, 0], 1) == np.inf   # too slow


def test_sphere_sphere_matches_sampling():
    rng = np.random.default_rng(11)
    for _ in range(300):
        c0, c1, v0, v1 = rng.normal(size=(4, 3)) * [[3], [3], [6], [6]]
        r0, r1 = rng.random(2) + 0.1
        toi = sphere_sphere_toi(c0, v0, r0, c1, v1, r1)
        times = sampled_overlap(c0 - c1, v0 - v1, r0 + r1)
        if times.size:
            assert toi <= times[0] + 1e-12 and toi >= times[0] - 1e-4
        elif toi != np.inf:  # a graze between two samples: the spheres just touch at toi
            gap = np.linalg.norm((c0 - c1) + toi * (v0 - v1)) - (r0 + r1)
            assert abs(gap) < 1e-9


def test_overlap_window_contains_every_sampled_overlap():
    rng = np.random.default_rng(12)
    nonempty = 0
    for _ in range(500):
        s, v = rng.normal(size=3) * 2, rng.normal(size=3) * 4
        r = rng.random() * 3 + 0.1
        lo, hi = sphere_overlap_window(s, v, r)
        times = sampled_overlap(s, v, r)
        if times.size:
            nonempty += 1
            assert lo <= times[0] and hi >= times[-1]
            assert times[0] - lo < 1e-4 and hi - times[-1] < 1e-4   # and it is tight
        else:
            assert lo > hi or hi - lo < 1e-4
    assert nonempty > 100
    assert sphere_overlap_window(np.array([5.0, 0, 0]), np.zeros(3), 1.0)[0] == np.inf
    assert sphere_overlap_window(np.array([0.5, 0, 0]), np.zeros(3), 1.0) == (0.0, 1.0)


def test_overlap_window_is_conservative_far_from_the_origin():
    """Grazing passes at large offsets, where b² - ac would cancel catastrophically."""
    s = np.array([1e7, 1.0, 0.0])
    v = np.array([-2e7, 0.0, 0.0])
    lo, hi = sphere_overlap_window(s, v, 1.0)          # passes at distance exactly 1: touches at t = 0.5
    assert lo <= 0.5 <= hi


def test_sphere_plane():
    n = np.array([0.0, 0.0, 1.0])
    # centre z = 5 moving down 10 per step, radius 1, plane z = 0: touches when z = 1 -> t = 0.4
    assert sphere_plane_toi([0, 0, 5], [0, 0, -10], 1, n, 0) == pytest.approx(0.4)
    assert sphere_plane_toi([0, 0, -5], [0, 0, 10], 1, n, 0) == pytest.approx(0.4)   # from below
    assert sphere_plane_toi([0, 0, 0.5], [0, 0, 3], 1, n, 0) == 0.0                  # touching already
    assert sphere_plane_toi([0, 0, 5], [3, 0, 0], 1, n, 0) == np.inf                 # parallel motion
    assert sphere_plane_toi([0, 0, 5], [0, 0, -2], 1, n, 0) == np.inf                # does not reach
    rng = np.random.default_rng(13)
    for _ in range(200):
        c, v = rng.normal(size=3) * 4, rng.normal(size=3) * 8
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        d, r = rng.normal(), rng.random() + 0.1
        dist = np.abs((c[None, :] + T[:, None] * v[None, :]) @ normal - d)
        touching = T[dist <= r]
        toi = sphere_plane_toi(c, v, r, normal, d)
        if touching.size:
            assert toi <= touching[0] + 1e-12 and touching[0] - toi < 1e-4
        else:
            assert toi == np.inf
