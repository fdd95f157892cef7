"""closest.contact_point (the reported contact point) against brute force over both triangles."""
import numpy as np
import pytest

from collide.closest import contact_point

#: barycentric grid steps per edge of the brute-force reference
STEPS = 40


def _grid(tri):
    """float64 (G, 3): points of triangle tri (3, 3) on a barycentric grid of STEPS per edge."""
    i, j = np.meshgrid(np.arange(STEPS + 1), np.arange(STEPS + 1), indexing="ij")
    keep = i + j <= STEPS
    u, v = i[keep] / STEPS, j[keep] / STEPS
    return tri[0] + u[:, None] * (tri[1] - tri[0]) + v[:, None] * (tri[2] - tri[0])


def _slack(p, q):
    """How far the grid's nearest points may be from the true ones: a grid point lies within
    one step of every point of its triangle's cells, for both triangles."""
    longest = max(np.linalg.norm(t[i] - t[k]) for t in (p, q) for i in range(3) for k in range(3))
    return 2.0 * longest / STEPS


def _distance_to(point, tri):
    return np.linalg.norm(_grid(tri) - point, axis=1).min()


@pytest.mark.parametrize("seed", range(40))
def test_apart_triangles_report_the_midpoint_of_their_nearest_points(seed):
    rng = np.random.default_rng(seed)
    p = rng.normal(size=(3, 3))
    q = rng.normal(size=(3, 3)) + rng.normal(size=3) * 3.0
    grid_p, grid_q = _grid(p), _grid(q)
    gaps = np.linalg.norm(grid_p[:, None, :] - grid_q[None, :, :], axis=2)
    nearest = gaps.min()
    point, gap = contact_point(p, q)
    point = np.array(point)
    slack = _slack(p, q)
    assert gap <= nearest + 1e-12            # the grid only ever overestimates the distance
    assert gap >= nearest - slack
    # the midpoint of two points at distance ``gap``, one on each triangle
    assert _distance_to(point, p) <= 0.5 * gap + slack
    assert _distance_to(point, q) <= 0.5 * gap + slack


@pytest.mark.parametrize("seed", range(40))
def test_crossing_triangles_report_a_point_on_both(seed):
    """q's edge from q0 to q1 pierces p at a known interior point x: gap 0, and the point lies
    in both triangles (barycentric coordinates within rounding of [0, 1])."""
    rng = np.random.default_rng(100 + seed)
    p = rng.normal(size=(3, 3))
    w = rng.dirichlet(np.ones(3)) * 0.9 + 0.1 / 3
    x = w @ p
    normal = np.cross(p[1] - p[0], p[2] - p[0])
    normal /= np.linalg.norm(normal)
    q = np.empty((3, 3))
    q[0] = x + normal * rng.uniform(0.01, 1.0)
    q[1] = x - normal * rng.uniform(0.01, 1.0)
    q[2] = q[0] + rng.normal(size=3)
    q = q[rng.permutation(3)]  # the piercing edge is any of q's edges, either way round
    point, gap = contact_point(p, q)
    point = np.array(point)
    assert gap <= 1e-12
    for tri in (p, q):
        # barycentric coordinates of point in tri's plane, and its distance from that plane
        e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
        n = np.cross(e1, e2)
        coords, *_ = np.linalg.lstsq(np.stack([e1, e2, n], axis=1), point - tri[0], rcond=None)
        assert abs(coords[2]) * np.linalg.norm(n) <= 1e-9
        assert coords[0] >= -1e-9 and coords[1] >= -1e-9 and coords[0] + coords[1] <= 1 + 1e-9


@pytest.mark.parametrize("case", ["repeated vertex", "collinear", "single point", "identical", "shared vertex"])
def test_degenerate_triangles_still_give_the_nearest_points(case):
    """Zero-area triangles (points, segments) and shared vertices: the same brute-force check
    as for apart triangles, gap 0 where they share a point."""
    rng = np.random.default_rng(7)
    p = rng.normal(size=(3, 3))
    q = rng.normal(size=(3, 3)) + np.array([2.5, 0.0, 0.0])
    if case == "repeated vertex":
        p[1] = p[0]
    elif case == "collinear":
        p[2] = 0.25 * p[0] + 0.75 * p[1]
    elif case == "single point":
        p[:] = p[0]
    elif case == "identical":
        q = p.copy()
    elif case == "shared vertex":
        q[0] = p[1]
    gaps = np.linalg.norm(_grid(p)[:, None, :] - _grid(q)[None, :, :], axis=2)
    point, gap = contact_point(p, q)
    assert np.all(np.isfinite(point))
    assert gaps.min() - _slack(p, q) <= gap <= gaps.min() + 1e-12
    if case in ("identical", "shared vertex"):
        assert gap == 0.0
