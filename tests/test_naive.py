"""Tests of the exact naive triangle-triangle reference (tests/naive.py) itself."""
from fractions import Fraction
from itertools import permutations

import numpy as np
import pytest
from naive import (
    barycentric_of_origin,
    check_certificate,
    hand_case_certificates,
    hand_cases,
    orient2d_exact,
    orient3d_exact,
    random_near_degenerate_cases,
    to_fractions,
    triangle_pairs_exact,
    triangles_intersect_exact,
)

CASES = hand_cases()
PERMS = list(permutations(range(3)))


def _exactly_translated(T, t):
    """T + t if every coordinate sum is exact, else None."""
    out = T + np.asarray(t, dtype=np.float64)
    want = [tuple(a + Fraction(float(b)) for a, b in zip(row, t)) for row in to_fractions(T)]
    return out if to_fractions(out) == want else None


# ------------------------------------------------------------------ primitives

def test_to_fractions_is_exact():
    x = np.array([[0.1, -2.0**-1074, 1e300], [np.nextafter(1.0, 2.0), 0.0, -3.5]])
    fr = to_fractions(x)
    assert fr[0][0] == Fraction(3602879701896397, 36028797018963968)
    assert fr[0][1] == -Fraction(1, 2**1074)
    assert fr[1][0] == 1 + Fraction(1, 2**52)
    assert all(float(v) == x[i, k] for i, row in enumerate(fr) for k, v in enumerate(row))
    with pytest.raises(ValueError):
        to_fractions(np.array([[np.nan, 0.0, 0.0]]))


def test_orient3d_convention_and_exactness():
    o, ex, ey, ez = (0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)
    assert orient3d_exact(o, ex, ey, ez) == 1
    assert orient3d_exact(o, ey, ex, ez) == -1
    assert orient3d_exact(o, ex, ey, (5, -7, 0)) == 0
    tiny = np.nextafter(0.0, 1.0)
    assert orient3d_exact(o, ex, ey, (0.3, 0.3, tiny)) == 1
    assert orient3d_exact(o, ex, ey, (0.3, 0.3, -tiny)) == -1
    # points on a tilted plane x + y + z = 1, one pushed off by one ulp
    a, b, c = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    assert orient3d_exact(a, b, c, (0.25, 0.25, 0.5)) == 0
    assert orient3d_exact(a, b, c, (0.25, 0.25, np.nextafter(0.5, 1.0))) == 1
    assert orient3d_exact(a, b, c, (0.25, 0.25, np.nextafter(0.5, 0.0))) == -1
    # coplanar points far from the origin (coordinates near 2^60)
    big = 2.0**60
    assert orient3d_exact((big, big, big), (big + 2**9, big, big), (big, big + 2**9, big),
                          (big + 2**8, big + 2**8, big)) == 0


def test_orient2d_convention():
    assert orient2d_exact((0, 0), (1, 0), (0, 1)) == 1
    assert orient2d_exact((0, 0), (0, 1), (1, 0)) == -1
    assert orient2d_exact((0, 0), (1, 1), (3, 3)) == 0
    assert orient2d_exact((0.5, 0.5), (12.0, 12.0), (24.0, np.nextafter(24.0, 25.0))) == 1


def test_barycentric_of_origin():
    assert barycentric_of_origin([(0, 0, 0)]) == [1]
    assert barycentric_of_origin([(1, 0, 0)]) is None
    assert barycentric_of_origin([(-1, 0, 0), (3, 0, 0)]) == [Fraction(3, 4), Fraction(1, 4)]
    assert barycentric_of_origin([(-1, 1, 0), (3, 1, 0)]) is None        # off the line
    assert barycentric_of_origin([(1, 0, 0), (2, 0, 0), (3, 0, 0)]) is None  # dependent
    tet = [(-1, -1, -1), (3, -1, -1), (-1, 3, -1), (-1, -1, 3)]
    assert barycentric_of_origin(tet) == [Fraction(1, 4)] * 4
    lam = barycentric_of_origin([(5, 0, 0), (0, 7, 0), (0, 0, 2), (-1, -1, -1)])
    assert sum(lam) == 1 and all(lam)  # origin = combination, check it reconstructs
    pts = [(5, 0, 0), (0, 7, 0), (0, 0, 2), (-1, -1, -1)]
    assert all(sum(w * p[k] for w, p in zip(lam, pts)) == 0 for k in range(3))


def test_rejects_bad_input():
    with pytest.raises(ValueError):
        triangles_intersect_exact(np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError):
        triangles_intersect_exact(np.full((3, 3), np.inf), np.zeros((3, 3)))


# ------------------------------------------------------------------ hand cases

def test_hand_case_inventory():
    names = [c[0] for c in CASES]
    assert len(names) >= 40
    assert len(set(names)) == len(names)
    answers = [c[3] for c in CASES]
    assert sum(answers) >= 15 and len(answers) - sum(answers) >= 15
    for key in ("pierce", "vertex-face", "vertex-vertex", "vertex-edge", "edge-edge",
                "edge-face", "coplanar", "parallel", "ulp", "2^-40", "point-", "needle",
                "large", "identical", "shared edge"):
        assert any(key in n for n in names), key
    for _, P, Q, _ in CASES:
        assert P.shape == Q.shape == (3, 3) and P.dtype == Q.dtype == np.float64
    certs = hand_case_certificates()
    assert set(certs) == set(names)


@pytest.mark.parametrize("name,P,Q,expected", CASES, ids=[c[0] for c in CASES])
def test_hand_case(name, P, Q, expected):
    # three independent sources agree: the stated answer, an exactly checked
    # certificate (common point / separating direction), and the exact algorithm
    assert check_certificate(P, Q, hand_case_certificates()[name]) is expected
    assert triangles_intersect_exact(P, Q) is expected
    assert triangles_intersect_exact(Q, P) is expected


def test_certificate_checker_rejects_wrong_certificates():
    name, P, Q, _ = next(c for c in CASES if c[0].startswith("vertex-face: Q vertex touches"))
    with pytest.raises(AssertionError):
        check_certificate(P, Q, ("meet", (1, 0, 0), (1, 0, 0)))    # not a common point
    with pytest.raises(AssertionError):
        check_certificate(P, Q, ("apart", (0, 0, 1)))               # touching, not apart


def test_hand_cases_vertex_permutations():
    for name, P, Q, expected in CASES:
        for pp in PERMS:
            for qp in PERMS:
                assert triangles_intersect_exact(P[list(pp)], Q[list(qp)]) is expected, (name, pp, qp)


def test_hand_cases_exact_rigid_symmetries():
    """Axis permutations and sign flips are exact and preserve the answer."""
    rng = np.random.default_rng(3)
    for name, P, Q, expected in CASES:
        for _ in range(3):
            axes = rng.permutation(3)
            signs = rng.choice([-1.0, 1.0], size=3)
            assert triangles_intersect_exact(P[:, axes] * signs, Q[:, axes] * signs) is expected, name


def test_hand_cases_translation_invariance():
    offsets = [(1.0, -3.0, 0.5), (1024.0, 0.0, -2.0**-10), (-0.75, 2.0**-30, 7.0),
               (2.0**20, 2.0**20, -2.0**20), (0.0, 0.0, 2.0**-1074)]
    tested = 0
    for name, P, Q, expected in CASES:
        for t in offsets:
            Pt, Qt = _exactly_translated(P, t), _exactly_translated(Q, t)
            if Pt is None or Qt is None:
                continue
            tested += 1
            assert triangles_intersect_exact(Pt, Qt) is expected, (name, t)
    assert tested >= 2 * len(CASES)


def test_hand_cases_power_of_two_scaling():
    tested = 0
    for name, P, Q, expected in CASES:
        for s in (2.0**30, 2.0**-30, 2.0**-900):
            Ps, Qs = P * s, Q * s
            if not (np.array_equal(Ps / s, P) and np.array_equal(Qs / s, Q)):
                continue  # underflow: not exact
            tested += 1
            assert triangles_intersect_exact(Ps, Qs) is expected, (name, s)
    assert tested >= 2 * len(CASES)


# ------------------------------------------------------------------ random grid cases

GRID = random_near_degenerate_cases(np.random.default_rng(20240601), 250)
GRID_ANSWERS = [triangles_intersect_exact(P, Q) for P, Q in GRID]


def test_random_grid_cases_are_near_degenerate_and_mixed():
    assert len(GRID) == 250
    for P, Q in GRID:
        assert P.shape == Q.shape == (3, 3) and P.dtype == Q.dtype == np.float64
    n_true = sum(GRID_ANSWERS)
    assert 40 <= n_true <= 210
    coplanar = sum(all(orient3d_exact(P[0], P[1], P[2], v) == 0 for v in Q) and
                   np.any(np.cross(P[1] - P[0], P[2] - P[0])) for P, Q in GRID)
    shared = sum(any((p == q).all() for p in P for q in Q) for P, Q in GRID)
    flat = sum(not np.any(np.cross(T[1] - T[0], T[2] - T[0])) for P, Q in GRID for T in (P, Q))
    assert coplanar >= 25 and shared >= 40 and flat >= 15, (coplanar, shared, flat)


def test_random_grid_symmetry_and_permutations():
    rng = np.random.default_rng(5)
    for (P, Q), ans in zip(GRID, GRID_ANSWERS):
        assert triangles_intersect_exact(Q, P) is ans
        pp, qp = rng.permutation(3), rng.permutation(3)
        assert triangles_intersect_exact(P[pp], Q[qp]) is ans
        assert triangles_intersect_exact(Q[qp], P[pp]) is ans


def test_random_grid_translation_invariance():
    rng = np.random.default_rng(6)
    for (P, Q), ans in zip(GRID, GRID_ANSWERS):
        t = rng.integers(-8, 9, size=3) * 2.0 ** -int(rng.integers(0, 4))
        Pt, Qt = _exactly_translated(P, t), _exactly_translated(Q, t)
        assert Pt is not None and Qt is not None
        assert triangles_intersect_exact(Pt, Qt) is ans


def test_random_grid_monotone_under_inclusion():
    """Growing P (homothety x2 about its vertex 0, a superset) can only add contacts;
    shrinking it to its midpoint triangle (a subset) can only remove them.  Both maps
    are exact on these coordinates."""
    for (P, Q), ans in zip(GRID, GRID_ANSWERS):
        big = P[0] + 2.0 * (P - P[0])
        mid = 0.5 * (P + P[[1, 2, 0]])
        assert _exactly_translated(big, (0.0, 0.0, 0.0)) is not None
        if ans:
            assert triangles_intersect_exact(big, Q)
        else:
            assert not triangles_intersect_exact(mid, Q)


def test_random_grid_against_other_exact_reference():
    """Cross-check with the separately written exact reference in tests/reference.py,
    when it is present."""
    reference = pytest.importorskip("reference")
    other = getattr(reference, "triangles_intersect_exact", None)
    if other is None:
        pytest.skip("tests/reference.py has no triangles_intersect_exact")
    for (P, Q), ans in zip(GRID[:120], GRID_ANSWERS[:120]):
        assert bool(other(P, Q)) is ans


# ------------------------------------------------------------------ float cross-check

def _sat_float(P, Q, margin):
    """Separating-axis test in floating point for non-degenerate triangles.  Axes: both
    normals, the 9 edge x edge cross products and the 6 in-plane edge normals (complete
    for coplanar and non-coplanar pairs).  Returns True/False only when the decision
    margin exceeds `margin`, else None."""
    eP = [P[1] - P[0], P[2] - P[1], P[0] - P[2]]
    eQ = [Q[1] - Q[0], Q[2] - Q[1], Q[0] - Q[2]]
    nP, nQ = np.cross(eP[0], eP[1]), np.cross(eQ[0], eQ[1])
    axes = ([nP, nQ] + [np.cross(e, f) for e in eP for f in eQ]
            + [np.cross(nP, e) for e in eP] + [np.cross(nQ, f) for f in eQ])
    best = -np.inf
    for a in axes:
        norm = np.linalg.norm(a)
        if norm < 1e-3:
            return None  # ill-conditioned direction: do not decide
        a = a / norm
        sp, sq = P @ a, Q @ a
        best = max(best, sq.min() - sp.max(), sp.min() - sq.max())
    if best > margin:
        return False
    if best < -margin:
        return True
    return None


def test_random_float_cross_check_with_sat():
    rng = np.random.default_rng(11)
    decided = {True: 0, False: 0}
    tries = 0
    while min(decided.values()) < 60 and tries < 5000:
        tries += 1
        P = rng.uniform(-1, 1, (3, 3))
        Q = rng.uniform(-1, 1, (3, 3)) + rng.uniform(-0.6, 0.6, 3)
        want = _sat_float(P, Q, margin=1e-6)
        if want is None:
            continue
        decided[want] += 1
        assert triangles_intersect_exact(P, Q) is want, (P, Q)
    assert min(decided.values()) >= 60, decided


def test_float_sat_helper_is_sane():
    T0 = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert _sat_float(T0, np.array([[0.0, 0, 1], [1, 0.3, 1.2], [0.2, 1, 1.5]]), 1e-6) is False
    assert _sat_float(T0, T0 + [0, 0, 1], 1e-6) is None  # parallel edges: declines to decide
    assert _sat_float(T0, np.array([[0.25, 0.25, -1], [0.25, 0.25, 1], [-1, -1, 0.5]]), 1e-6) is True
    # coplanar, separated only by an in-plane edge normal
    assert _sat_float(T0, np.array([[1.0, 1, 0], [2, 0.6, 0], [0.7, 2, 0]]), 1e-6) is False


# ------------------------------------------------------------------ mesh pairs

def _box(lo, hi):
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    V = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], dtype=np.float64)
    F = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                  [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])
    return V, F


def test_triangle_pairs_exact_matches_brute_force():
    VA, FA = _box((0, 0, 0), (1, 1, 1))
    for lo, hi in [((1, 0, 0), (2, 1, 1)), ((0.5, 0.5, 0.5), (1.5, 1.5, 1.5)),
                   ((np.nextafter(1.0, 2.0), 0, 0), (2, 1, 1)), ((1, 1, 1), (2, 2, 2)),
                   ((0.25, 0.25, 0.25), (0.75, 0.75, 0.75))]:
        VB, FB = _box(lo, hi)
        got = triangle_pairs_exact(VA, FA, VB, FB)
        want = sorted((i, j) for i in range(len(FA)) for j in range(len(FB))
                      if triangles_intersect_exact(VA[FA[i]], VB[FB[j]]))
        assert got == want
        assert got == sorted(set(got))
    VB, FB = _box((np.nextafter(1.0, 2.0), 0, 0), (2, 1, 1))
    assert triangle_pairs_exact(VA, FA, VB, FB) == []
    VB, FB = _box((0.25, 0.25, 0.25), (0.75, 0.75, 0.75))     # nested, no surface contact
    assert triangle_pairs_exact(VA, FA, VB, FB) == []
    VB, FB = _box((1, 1, 1), (2, 2, 2))                        # corner to corner
    got = triangle_pairs_exact(VA, FA, VB, FB)
    assert got and all(1.0 in VA[FA[i]].max(axis=0) for i, _ in got)


def test_triangle_pairs_exact_small_known():
    VA = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    FA = np.array([[0, 1, 2]])
    VB = np.array([[0.25, 0.25, 0], [0.25, 0, 1], [0, 0.25, 1], [5, 5, 5], [6, 5, 5], [5, 6, 5]])
    FB = np.array([[3, 4, 5], [0, 1, 2]])
    assert triangle_pairs_exact(VA, FA, VB, FB) == [(0, 1)]
    assert triangle_pairs_exact(VA, FA[:0], VB, FB) == []
