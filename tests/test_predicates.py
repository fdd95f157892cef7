"""Exact predicates and the triangle-triangle test against exact rational arithmetic."""
import numpy as np
import pytest
from reference import orient2d_exact, orient3d_exact, triangles_intersect_exact

from collide.predicates import orient2d, orient3d, triangles_intersect

RNG_SEED = 20261123


def random_points(rng, kind, n):
    if kind == "grid":
        return rng.integers(-3, 4, (n, 3)).astype(float)
    if kind == "wide":
        return rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-6, 7)
    return rng.normal(size=(n, 3))


def test_orient3d_matches_exact_signs():
    rng = np.random.default_rng(RNG_SEED)
    for k in range(3000):
        pts = random_points(rng, ("grid", "wide", "normal")[k % 3], 4)
        if k % 4 == 3:  # d on the plane of a, b, c up to rounding: the filter cannot decide
            u, v = rng.random(2)
            pts[3] = pts[0] + u * (pts[1] - pts[0]) + v * (pts[2] - pts[0])
        assert orient3d(*pts) == orient3d_exact(*pts)


def test_orient2d_matches_exact_signs():
    rng = np.random.default_rng(RNG_SEED + 1)
    for k in range(3000):
        a, b = rng.normal(size=(2, 2)) * 10.0 ** rng.integers(-3, 4)
        c = a + rng.random() * (b - a) if k % 2 else rng.normal(size=2)
        assert orient2d(*a, *b, *c) == orient2d_exact(*a, *b, *c)


def test_points_in_an_axis_parallel_plane_are_coplanar_whatever_their_rounding():
    """Points sharing one coordinate that is not a short binary fraction (0.1), with
    differences that round on the other axes: the filter cannot decide and the
    differences are not exact, yet the exact sign is 0 (and +-1 one ulp off the plane)."""
    rng = np.random.default_rng(RNG_SEED + 5)
    for k in range(600):
        axis = k % 3
        pts = rng.normal(size=(4, 3)) * 10.0 ** rng.integers(-3, 4)
        pts[:, axis] = 0.1 * (1 + k % 7)
        if k % 4 == 3:
            pts[rng.integers(4), axis] = np.nextafter(pts[0, axis], np.inf)
        assert orient3d(*pts) == orient3d_exact(*pts)
        # the same in 2-D: three points on an axis-parallel line, or two that coincide
        a, b, c = pts[:3, [axis, (axis + 1) % 3]]
        if k % 5 == 4:
            c = b.copy()
        assert orient2d(*a, *b, *c) == orient2d_exact(*a, *b, *c)


def coplanar_pair(rng, plane):
    """Two random triangles (3, 3) exactly in one plane, small-integer grid coordinates
    (so touching, collinear and zero-area cases are common): ``z``, z = 0.1 (the height
    is not a short binary fraction, so coordinate differences round); ``tilted``,
    z = x + y (exact in float64); ``vertical``, x + y = 3 (no triangle has area on (x, y))."""
    uv = rng.integers(0, 4, (6, 2)).astype(float)
    if rng.random() < 0.15:
        uv[1] = uv[0]  # a zero-area triangle
    if plane == "z":
        pts = np.column_stack([uv / 3.0, np.full(6, 0.1)])
    elif plane == "tilted":
        pts = np.column_stack([uv, uv[:, 0] + uv[:, 1]])
    else:
        pts = np.column_stack([uv[:, 0], 3.0 - uv[:, 0], uv[:, 1]])
    return np.ascontiguousarray(pts[:3]), np.ascontiguousarray(pts[3:])


@pytest.mark.parametrize("plane", ["z", "tilted", "vertical"])
def test_random_coplanar_pairs_match_exact_reference(plane):
    """The coplanar 2-D test (one projection that is one-to-one on the plane) against
    exact rational arithmetic, both argument orders."""
    rng = np.random.default_rng(RNG_SEED + 6)
    hits = 0
    for _ in range(400):
        p, q = coplanar_pair(rng, plane)
        expected = triangles_intersect_exact(p, q)
        hits += expected
        assert triangles_intersect(p, q) == expected, (p, q)
        assert triangles_intersect(q, p) == expected, (p, q)
    assert 80 < hits < 320  # both outcomes well represented


def tri(*rows):
    return np.array(rows, dtype=np.float64)


BASE = tri([0, 0, 0], [4, 0, 0], [0, 4, 0])
ULP = np.nextafter(0.0, 1.0)
HAND_CASES = [
    # (name, p, q, expected) -- answers known by construction; coordinates are exact dyadics
    ("piercing", BASE, tri([1, 1, -1], [1, 1, 1], [2, 1, 1]), True),
    ("far apart", BASE, BASE + [0, 0, 10], False),
    ("parallel planes, tiny gap", BASE, BASE + [0, 0, 2.0 ** -40], False),
    ("parallel planes, subnormal gap", BASE, BASE + [0, 0, ULP], False),
    ("vertex on face interior", BASE, tri([1, 1, 0], [1, 1, 3], [2, 2, 3]), True),
    ("vertex one ulp above face", BASE, tri([1, 1, 2.0 ** -60], [1, 1, 3], [2, 2, 3]), False),
    ("vertex on vertex", BASE, tri([4, 0, 0], [5, 0, 1], [5, 1, 1]), True),
    ("vertex on edge", BASE, tri([2, 0, 0], [2, -1, 1], [3, -1, 1]), True),
    ("vertex just off edge", BASE, tri([2, -2.0 ** -50, 0], [2, -1, 1], [3, -1, 1]), False),
    ("edge crosses edge at a point", BASE, tri([2, -1, 0], [2, 1, 0], [2, 0, -3]), True),
    ("edge lies on face", BASE, tri([1, 1, 0], [2, 1, 0], [1.5, 1, 3]), True),
    ("shared edge (adjacent)", BASE, tri([4, 0, 0], [0, 4, 0], [4, 4, 0]), True),
    ("identical", BASE, BASE.copy(), True),
    ("coplanar overlapping", BASE, BASE + [1, 1, 0], True),
    ("coplanar contained", BASE, tri([1, 1, 0], [2, 1, 0], [1, 2, 0]), True),
    ("coplanar touching at vertex", BASE, tri([4, 0, 0], [8, 0, 0], [4, 4, 0]), True),
    ("coplanar touching along edge", BASE, tri([0, 0, 0], [4, 0, 0], [0, -4, 0]), True),
    ("coplanar separated by tiny gap", BASE, tri([4 + 2.0 ** -45, 0, 0], [8, 0, 0], [8, 4, 0]), False),
    ("coplanar, one ulp beyond hypotenuse", BASE,
     tri([2, np.nextafter(2.0, 3.0), 0], [3, 3, 0], [2, 5, 0]), False),
    ("point triangle inside face", BASE, tri([1, 1, 0], [1, 1, 0], [1, 1, 0]), True),
    ("point triangle above face", BASE, tri([1, 1, 1], [1, 1, 1], [1, 1, 1]), False),
    ("point triangle on edge", BASE, tri([2, 2, 0], [2, 2, 0], [2, 2, 0]), True),
    ("needle piercing face", BASE, tri([1, 1, -1], [1, 1, 1], [1, 1, 2]), True),
    ("needle above face", BASE, tri([1, 1, 1], [1, 1, 2], [1, 1, 3]), False),
    ("needle lying in face", BASE, tri([1, 1, 0], [2, 1, 0], [3, 1, 0]), True),
    ("needle in plane, outside", BASE, tri([5, 5, 0], [6, 5, 0], [7, 5, 0]), False),
    ("two needles crossing", tri([0, 0, 0], [1, 1, 0], [2, 2, 0]), tri([0, 2, 0], [1, 1, 0], [2, 0, 0]), True),
    ("two skew needles", tri([0, 0, 0], [1, 1, 0], [2, 2, 0]), tri([0, 2, 1], [1, 1, 1], [2, 0, 1]), False),
    ("collinear needles overlapping", tri([0, 0, 0], [1, 0, 0], [2, 0, 0]), tri([1.5, 0, 0], [3, 0, 0], [4, 0, 0]),
     True),
    ("collinear needles apart", tri([0, 0, 0], [1, 0, 0], [2, 0, 0]), tri([2.5, 0, 0], [3, 0, 0], [4, 0, 0]), False),
    ("two equal points", tri([1, 2, 3], [1, 2, 3], [1, 2, 3]), tri([1, 2, 3], [1, 2, 3], [1, 2, 3]), True),
    ("large offset, touching", BASE + 2.0 ** 20, tri([1, 1, 0], [1, 1, 3], [2, 2, 3]) + 2.0 ** 20, True),
    ("large offset, tiny gap", BASE + 2.0 ** 20,
     tri([1, 1, 2.0 ** -30], [1, 1, 3], [2, 2, 3]) + 2.0 ** 20, False),
]


@pytest.mark.parametrize("name,p,q,expected", HAND_CASES, ids=[c[0] for c in HAND_CASES])
def test_hand_cases(name, p, q, expected):
    assert triangles_intersect_exact(p, q) == expected        # the reference agrees by construction
    for a, b in ((p, q), (q, p), (p[[1, 2, 0]], q[[0, 2, 1]])):
        assert triangles_intersect(np.ascontiguousarray(a), np.ascontiguousarray(b)) == expected


def test_random_near_degenerate_pairs_match_exact_reference():
    """Small-integer grids make touching, coplanar and degenerate configurations common."""
    rng = np.random.default_rng(RNG_SEED + 2)
    hits = 0
    for k in range(600):
        p = rng.integers(0, 4, (3, 3)).astype(float)
        q = rng.integers(0, 4, (3, 3)).astype(float)
        if k % 3 == 0:
            q[:, 2] = p[0, 2]  # force the planes to be parallel or equal (z = const)
            p[:, 2] = p[0, 2]
        if k % 5 == 0:
            q[0] = p[rng.integers(3)]  # share a vertex
        expected = triangles_intersect_exact(p, q)
        hits += expected
        assert triangles_intersect(p, q) == expected, (p, q)
    assert 100 < hits < 500  # both outcomes well represented


def test_random_generic_pairs_match_exact_reference():
    rng = np.random.default_rng(RNG_SEED + 3)
    for _ in range(300):
        p = rng.normal(size=(3, 3))
        q = rng.normal(size=(3, 3)) * 0.7 + 0.2
        assert triangles_intersect(p, q) == triangles_intersect_exact(p, q)


def test_second_reference_hand_cases_and_grid_cases():
    """The 76 certified hand cases and grid cases of tests/naive.py (an independent exact
    reference with its own proofs of each answer)."""
    naive = pytest.importorskip("naive")
    for name, p, q, expected in naive.hand_cases():
        p, q = np.ascontiguousarray(p, dtype=np.float64), np.ascontiguousarray(q, dtype=np.float64)
        assert triangles_intersect(p, q) == expected, name
        assert triangles_intersect(q, p) == expected, name
    rng = np.random.default_rng(RNG_SEED + 4)
    for p, q in naive.random_near_degenerate_cases(rng, 300):
        p, q = np.ascontiguousarray(p, dtype=np.float64), np.ascontiguousarray(q, dtype=np.float64)
        assert triangles_intersect(p, q) == naive.triangles_intersect_exact(p, q)
