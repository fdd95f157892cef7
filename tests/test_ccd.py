"""Certified CCD primitives (collide.ccd).

- zero false negatives on the benchmark queries of Wang et al. 2021 (a bundled subset
  always, the full set in ../shared when present);
- exact times on analytic motions, including degenerate ones (no motion, zero-length
  edges, parallel and collinear edges, coplanar sliding, zero-area faces);
- random rigid translations against an exact rational reference (t* known exactly):
  t* - time_tol <= toi <= t*;
- random general (turning, deforming) motions against dense time sampling with an
  independent static test: sampling may miss contacts, never invent them, so toi is no
  later than any sampled contact; and a finite toi is followed within time_tol by a
  near contact;
- input validation and the numba-callable kernels.
"""
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from ccd_queries import KINDS, read_scene, scenes
from numba import njit

from collide.ccd import edge_edge_toi, edge_edge_toi_kernel, vertex_face_toi, vertex_face_toi_kernel

TOI = {"vertex-face": vertex_face_toi, "edge-edge": edge_edge_toi}
TOL = 1e-6
BUNDLED = Path(__file__).resolve().parent / "data" / "ccd"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "ccd-queries"


# --- benchmark queries ------------------------------------------------------------------------

def check_no_false_negative(root):
    """Run every scene under root; fail on any missed contact. -> number of positives."""
    positives = 0
    for scene in scenes(root):
        for kind in KINDS:
            x_t0, x_t1, truth = read_scene(scene, kind)  # exact rationals, checked exact in float64
            toi = TOI[kind](x_t0, x_t1)
            missed = np.flatnonzero(truth & ~np.isfinite(toi))
            assert missed.size == 0, f"{scene.name}/{kind}: missed queries {missed.tolist()}"
            finite = toi[np.isfinite(toi)]
            assert ((finite >= 0.0) & (finite <= 1.0)).all()
            positives += int(truth.sum())
    return positives


def test_no_false_negative_on_bundled_queries():
    assert check_no_false_negative(BUNDLED) >= 250


def test_no_false_negative_on_all_benchmark_queries():
    if not SHARED.is_dir():
        pytest.skip(f"benchmark queries not found at {SHARED}")
    assert check_no_false_negative(SHARED) >= 340


# --- analytic motions with known times --------------------------------------------------------

def q(*rows):
    return np.array(rows, dtype=np.float64)


FACE = q([0, 0, 0], [1, 0, 0], [0, 1, 0])


def vf(v0, v1, face0=FACE, face1=FACE, **kw):
    return vertex_face_toi(np.vstack([v0, face0]), np.vstack([v1, face1]), **kw)[0]


def ee(a_t0, a_t1, b_t0, b_t1, **kw):
    """a_t0, a_t1: the 2 endpoints of edge a at t = 0 and t = 1; likewise b."""
    return edge_edge_toi(np.vstack([a_t0, b_t0]), np.vstack([a_t1, b_t1]), **kw)[0]


def within(toi, exact, tol=TOL):
    return exact - tol <= toi <= exact


def test_vertex_falls_onto_face():
    assert within(vf([0.25, 0.25, 1], [0.25, 0.25, -1]), 0.5)
    assert within(vf([0.25, 0.25, 1], [0.25, 0.25, -3]), 0.25)
    assert within(vf([0.25, 0.25, 1], [0.25, 0.25, -1], time_tol=1e-2), 0.5, 1e-2)
    assert within(vf([0.1, 0.2, 0.3], [0.1, 0.2, -0.1]), 0.75)
    # the face moves up to meet a still vertex
    assert within(vf([0.25, 0.25, 1], [0.25, 0.25, 1], FACE, FACE + [0, 0, 4]), 0.25)
    # onto the face's hypotenuse, its corner, and an edge, exactly
    assert within(vf([0.5, 0.5, 1], [0.5, 0.5, -1]), 0.5)
    assert within(vf([0, 0, 1], [0, 0, -1]), 0.5)
    assert within(vf([1, 0, 1], [1, 0, -1]), 0.5)
    assert within(vf([0.5, 0, -1], [0.5, 0, 3]), 0.25)        # from below
    # the vertex rests on the face from the start
    assert vf([0.2, 0.2, 0], [5, 5, 5]) == 0.0


def test_vertex_misses_face():
    assert vf([0.75, 0.75, 1], [0.75, 0.75, -1]) == np.inf               # outside u + v <= 1
    assert vf([0.5 + 1e-9, 0.5 + 1e-9, 1], [0.5 + 1e-9, 0.5 + 1e-9, -1]) == np.inf
    assert vf([-1e-9, 0.5, 1], [-1e-9, 0.5, -1]) == np.inf                # just past an edge
    assert vf([0.25, 0.25, 1], [0.25, 0.25, 1e-9]) == np.inf             # stops short
    assert vf([0.25, 0.25, -1], [0.25, 0.25, -2]) == np.inf              # moves away
    # fast and diagonal, passing 1e-3 beside the face's edge: no contact within
    # time_tol is not enough to report one (the axes cross zero at different times)
    assert vf([-1e6 - 1e-3, 0.5, -1e6], [1e6 - 1e-3, 0.5, 1e6]) == np.inf


def test_time_tolerance_bounds_both_ways():
    for time_tol in (1e-2, 1e-4, 1e-6, 1e-9):
        toi = vf([0.3, 0.3, 1], [0.3, 0.3, -2], time_tol=time_tol)   # t* = 1/3
        assert 1 / 3 - time_tol <= toi <= 1 / 3
        toi = ee([[-1, 0, 1], [1, 0, 1]], [[-1, 0, -3], [1, 0, -3]], [[0, -1, 0], [0, 1, 0]],
                 [[0, -1, 0], [0, 1, 0]], time_tol=time_tol)        # t* = 1/4
        assert 0.25 - time_tol <= toi <= 0.25


def test_distance_tolerance():
    # z(t) = 1 - 2t: within 0.1 of the face from t = 0.45 on
    toi = vf([0.25, 0.25, 1], [0.25, 0.25, -1], dist_tol=0.1)
    assert 0.45 - TOL - 1e-12 <= toi <= 0.45
    # stops 1e-4 short: a contact within dist_tol = 1e-3, none within 1e-5
    assert np.isfinite(vf([0.25, 0.25, 1], [0.25, 0.25, 1e-4], dist_tol=1e-3))
    assert vf([0.25, 0.25, 1], [0.25, 0.25, 1e-4], dist_tol=1e-5) == np.inf


def test_edges_cross():
    # a along x at height 1 - 2t, b along y at 0: they meet at t = 1/2
    assert within(ee([[-1, 0, 1], [1, 0, 1]], [[-1, 0, -1], [1, 0, -1]], [[0, -1, 0], [0, 1, 0]],
                     [[0, -1, 0], [0, 1, 0]]), 0.5)
    # endpoint onto endpoint (b rises to the left of x = 1, a lies right of it), and an
    # endpoint onto the other's interior
    assert within(ee([[1, 0, 1], [2, 0, 1]], [[1, 0, -1], [2, 0, -1]], [[1, 0, 0], [0, 0, 1]],
                     [[1, 0, 0], [0, 0, 1]]), 0.5)
    assert within(ee([[0, 0, 1], [1, 0, 1]], [[0, 0, -1], [1, 0, -1]], [[0, -1, 0], [0, 1, 0]],
                     [[0, -1, 0], [0, 1, 0]]), 0.5)
    # ... unless a passes beyond b's end, or stops short
    assert ee([[-1, 2, 1], [1, 2, 1]], [[-1, 2, -1], [1, 2, -1]], [[0, -1, 0], [0, 1, 0]],
              [[0, -1, 0], [0, 1, 0]]) == np.inf
    assert ee([[-1, 1 + 1e-9, 1], [1, 1 + 1e-9, 1]], [[-1, 1 + 1e-9, -1], [1, 1 + 1e-9, -1]],
              [[0, -1, 0], [0, 1, 0]], [[0, -1, 0], [0, 1, 0]]) == np.inf
    assert ee([[-1, 0, 1], [1, 0, 1]], [[-1, 0, 1e-9], [1, 0, 1e-9]], [[0, -1, 0], [0, 1, 0]],
              [[0, -1, 0], [0, 1, 0]]) == np.inf


def test_degenerate_motions():
    still = [[0.25, 0.25, 0]]
    assert vf(still, still) == 0.0                                       # no motion, touching
    assert vf([[0.25, 0.25, 1]], [[0.25, 0.25, 1]]) == np.inf            # no motion, apart
    point = q([0.5, 0.5, 0.5])
    assert vertex_face_toi(np.tile(point, (4, 1)), np.tile(point, (4, 1)))[0] == 0.0  # all one point
    # parallel edges approaching sideways, coplanar: meet at t = 0.25
    assert within(ee([[0, 1, 0], [1, 1, 0]], [[0, -3, 0], [1, -3, 0]], [[0.5, 0, 0], [2, 0, 0]],
                     [[0.5, 0, 0], [2, 0, 0]]), 0.25)
    # parallel edges, one above the other, sliding along: never closer than 1e-3
    assert ee([[0, 0, 1e-3], [1, 0, 1e-3]], [[5, 0, 1e-3], [6, 0, 1e-3]], [[2, 0, 0], [3, 0, 0]],
              [[2, 0, 0], [3, 0, 0]]) == np.inf
    # collinear edges sliding into each other: meet at t = 0.5
    assert within(ee([[-3, 0, 0], [-2, 0, 0]], [[-1, 0, 0], [0, 0, 0]], [[-1, 0, 0], [1, 0, 0]],
                     [[-1, 0, 0], [1, 0, 0]]), 0.5)
    # collinear, overlapping from the start and sliding
    assert ee([[0, 0, 0], [2, 0, 0]], [[5, 0, 0], [7, 0, 0]], [[1, 0, 0], [3, 0, 0]],
              [[1, 0, 0], [3, 0, 0]]) == 0.0
    # zero-length edge (a point) hitting an edge, and two points meeting
    assert within(ee([[0, 1, 0], [0, 1, 0]], [[0, -1, 0], [0, -1, 0]], [[-1, 0, 0], [1, 0, 0]],
                     [[-1, 0, 0], [1, 0, 0]]), 0.5)
    assert within(ee([[0, 1, 0], [0, 1, 0]], [[0, -3, 0], [0, -3, 0]], [[0, 0, 0], [0, 0, 0]],
                     [[0, 0, 0], [0, 0, 0]]), 0.25)
    # a vertex sliding within the face's plane into the triangle (coplanar)
    assert within(vf([[-1, 0.25, 0]], [[1, 0.25, 0]]), 0.5)
    assert vf([[-1, 2, 0]], [[1, 2, 0]]) == np.inf                      # coplanar, passing by
    # zero-area faces: a needle and a point
    needle = q([0, 0, 0], [1, 0, 0], [2, 0, 0])
    assert within(vf([[0.5, 0, 1]], [[0.5, 0, -1]], needle, needle), 0.5)
    assert vf([[0.5, 1e-6, 1]], [[0.5, 1e-6, -1]], needle, needle) == np.inf
    dot = q([1, 1, 1], [1, 1, 1], [1, 1, 1])
    assert within(vf([[1, 1, 3]], [[1, 1, -1]], dot, dot), 0.5)
    # the face turns onto a still vertex: its height at y = 0.5 is (1 - 2t) / 2
    turn0 = q([0, 0, 0], [1, 0, 0], [0, 1, 1])
    turn1 = q([0, 0, 0], [1, 0, 0], [0, 1, -1])
    assert within(vf([[0.1, 0.5, 0.25]], [[0.1, 0.5, 0.25]], turn0, turn1), 0.25)


def test_scale_and_offset_do_not_matter():
    for scale, offset in ((1e-6, 0.0), (1e6, 0.0), (1.0, 1e4), (1e-3, -7e3)):
        face = FACE * scale + offset
        toi = vf(np.array([[0.25, 0.25, 1]]) * scale + offset, np.array([[0.25, 0.25, -1]]) * scale + offset,
                 face, face)
        assert within(toi, 0.5), (scale, offset, toi)
        miss = vf(np.array([[0.6, 0.6, 1]]) * scale + offset, np.array([[0.6, 0.6, -1]]) * scale + offset,
                  face, face)
        assert miss == np.inf, (scale, offset)


def test_batch_shapes_and_errors():
    x = np.zeros((5, 4, 3))
    assert vertex_face_toi(x, x).shape == (5,)
    assert vertex_face_toi(x, x).dtype == np.float64
    assert edge_edge_toi(x[0], x[0]).shape == (1,)
    assert edge_edge_toi(x[0].astype(np.float32).tolist(), x[0].astype(int)).shape == (1,)
    assert vertex_face_toi(np.zeros((0, 4, 3)), np.zeros((0, 4, 3))).shape == (0,)
    bad = [(np.zeros((5, 3, 3)), np.zeros((5, 3, 3))), (np.zeros((5, 4, 3)), np.zeros((4, 4, 3))),
           (np.full((1, 4, 3), np.nan), np.zeros((1, 4, 3))), (np.zeros((1, 4, 3)), np.full((1, 4, 3), np.inf)),
           (np.full((1, 4, 3), "a"), np.zeros((1, 4, 3))), (np.full((1, 4, 3), 1e200), np.zeros((1, 4, 3))),
           ([[1, 2], [3]], np.zeros((1, 4, 3)))]
    for x_t0, x_t1 in bad:
        for f in (vertex_face_toi, edge_edge_toi):
            with pytest.raises(ValueError):
                f(x_t0, x_t1)
    with pytest.raises(ValueError):
        vertex_face_toi(x, x, time_tol=-1)
    with pytest.raises(ValueError):
        edge_edge_toi(x, x, dist_tol=np.nan)


def test_batch_equals_single_queries_and_strided_input():
    rng = np.random.default_rng(3)
    x_t0 = rng.normal(size=(64, 4, 3))
    x_t1 = -x_t0 + rng.normal(size=(64, 4, 3)) * 0.1
    for f in (vertex_face_toi, edge_edge_toi):
        batch = f(x_t0, x_t1)
        assert np.isfinite(batch).sum() > 5
        single = np.array([f(a, b)[0] for a, b in zip(x_t0, x_t1)])
        np.testing.assert_array_equal(batch, single)
        strided = f(np.asfortranarray(x_t0[::-1])[::-1], x_t1)  # non-contiguous input
        np.testing.assert_array_equal(batch, strided)


@njit
def _kernel_min(x_t0, x_t1):
    """Calls both kernels from numba code, as the narrow phase does."""
    return min(vertex_face_toi_kernel(x_t0, x_t1, 1e-6, 0.0), edge_edge_toi_kernel(x_t0, x_t1, 1e-6, 0.0))


def test_kernels_are_callable_from_numba():
    x_t0 = np.ascontiguousarray(np.vstack([[0.25, 0.25, 1], FACE]))
    x_t1 = np.ascontiguousarray(np.vstack([[0.25, 0.25, -1], FACE]))
    assert within(_kernel_min(x_t0, x_t1), 0.5)
    assert within(vertex_face_toi_kernel(x_t0, x_t1, 1e-6, 0.0), 0.5)


# --- random rigid translations against an exact rational reference ----------------------------

def dyadic(rng, shape, bits=6, scale=4):
    """Random floats k / 2^bits in [-scale, scale]: sums and small products stay exact."""
    return rng.integers(-scale << bits, (scale << bits) + 1, size=shape) / float(1 << bits)


def frac(a):
    return [Fraction(float(x)) for x in np.ravel(a)]


def det3(c0, c1, c2):
    return (c0[0] * (c1[1] * c2[2] - c1[2] * c2[1]) - c1[0] * (c0[1] * c2[2] - c0[2] * c2[1])
            + c2[0] * (c0[1] * c1[2] - c0[2] * c1[1]))


def solve3(c0, c1, c2, rhs):
    """Exact (x0, x1, x2) with x0 c0 + x1 c1 + x2 c2 = rhs (Cramer), None if singular."""
    d = det3(c0, c1, c2)
    if d == 0:
        return None
    return det3(rhs, c1, c2) / d, det3(c0, rhs, c2) / d, det3(c0, c1, rhs) / d


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def exact_first_contact(kind, x_t0, x_t1):
    """t* for a query whose two primitives each translate rigidly (exactly): F is then
    affine in (t, u, v) jointly, so the contact is the unique solution of a 3 x 3 linear
    system (None when it is singular: parallel or coplanar motion)."""
    point = exact_contact_point(kind, x_t0, x_t1)
    return point if point is None or point == np.inf else point[0]


def exact_contact_point(kind, x_t0, x_t1):
    """(t, u, v) of exact_first_contact's contact, np.inf when there is none, None when
    the system is singular."""
    p = [frac(r) for r in x_t0]
    w = [sub(frac(b), frac(a)) for a, b in zip(x_t0, x_t1)]
    if kind == "vertex-face":
        # v + t wv = f0 + t wf + u (f1 - f0) + v (f2 - f0)
        sol = solve3(sub(w[0], w[1]), sub(p[1], p[2]), sub(p[1], p[3]), sub(p[1], p[0]))
        inside = sol is not None and sol[1] >= 0 and sol[2] >= 0 and sol[1] + sol[2] <= 1
    else:
        # a0 + t wa + u (a1 - a0) = b0 + t wb + v (b1 - b0)
        sol = solve3(sub(w[0], w[2]), sub(p[1], p[0]), sub(p[2], p[3]), sub(p[2], p[0]))
        inside = sol is not None and 0 <= sol[1] <= 1 and 0 <= sol[2] <= 1
    if sol is None:
        return None
    return sol if inside and 0 <= sol[0] <= 1 else np.inf


def rigid_queries(rng, kind, n):
    """n queries, half of them with a planted contact at a dyadic time."""
    x_t0 = dyadic(rng, (n, 4, 3))
    moving = (0, 1) if kind == "edge-edge" else (0,)
    w_a = dyadic(rng, (n, 1, 3), scale=8)
    w_b = dyadic(rng, (n, 1, 3), scale=2)
    for i in range(n // 2):  # plant: move point a (the vertex, or edge a) onto b at time t
        t = rng.integers(1, 16) / 16.0
        u, v = rng.integers(0, 9, size=2) / 8.0
        if kind == "vertex-face":
            u, v = (u, v) if u + v <= 1 else (1 - u, 1 - v)
            target = x_t0[i, 1] + u * (x_t0[i, 2] - x_t0[i, 1]) + v * (x_t0[i, 3] - x_t0[i, 1])
            x_t0[i, 0] = target + t * (w_b[i, 0] - w_a[i, 0])
        else:
            target = x_t0[i, 2] + v * (x_t0[i, 3] - x_t0[i, 2])
            shift = target + t * (w_b[i, 0] - w_a[i, 0]) - (x_t0[i, 0] + u * (x_t0[i, 1] - x_t0[i, 0]))
            x_t0[i, :2] += shift
    x_t1 = x_t0.copy()
    x_t1[:, list(moving)] += w_a
    x_t1[:, [r for r in range(4) if r not in moving]] += w_b
    return x_t0, x_t1


@pytest.mark.parametrize("kind", KINDS)
def test_rigid_translations_against_exact_reference(kind):
    rng = np.random.default_rng(20240 + len(kind))
    x_t0, x_t1 = rigid_queries(rng, kind, 1200)
    time_tol = 1e-5
    toi = TOI[kind](x_t0, x_t1, time_tol=time_tol)
    hits = misses = 0
    for i in range(len(toi)):
        exact = exact_first_contact(kind, x_t0[i], x_t1[i])
        if exact is None:
            continue
        if exact == np.inf:
            misses += 1
            assert toi[i] == np.inf, (i, toi[i])  # random misses are far from tolerance
        else:
            hits += 1
            assert exact - time_tol <= toi[i] <= exact, (i, float(exact), toi[i])
    assert hits > 500 and misses > 100


# --- random general motions against dense sampling --------------------------------------------

def point_segment_distance(p, a, b):
    """(T,) distances from points p to closed segments ab; all (T, 3)."""
    d = b - a
    dd = np.einsum("ij,ij->i", d, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(dd > 0, np.einsum("ij,ij->i", p - a, d) / dd, 0.0)
    s = np.clip(s, 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * d), axis=1)


def stationary_point(x, y, r, sign):
    """Per row, the (s, t) minimising |r + s x + sign t y| (normal equations, Cramer) and
    whether that 2 x 2 system is well conditioned; x, y, r (T, 3)."""
    a, b, c = (np.einsum("ij,ij->i", p, q) for p, q in ((x, x), (x, y), (y, y)))
    e, f = np.einsum("ij,ij->i", x, r), np.einsum("ij,ij->i", y, r)
    det = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (b * f - c * e) / det
        t = sign * (b * e - a * f) / det
    return s, t, det > 1e-12 * (a * c + 1e-300)


def point_triangle_distance(p, f0, f1, f2):
    """(T,) distances from points to closed triangles: the interior projection when it
    falls inside, else the nearest edge (a convex quadratic's minimum over a triangle)."""
    e1, e2, r = f1 - f0, f2 - f0, p - f0
    u, v, ok = stationary_point(-e1, -e2, r, 1.0)
    inside = ok & (u >= 0) & (v >= 0) & (u + v <= 1)
    interior = np.linalg.norm(r - u[:, None] * e1 - v[:, None] * e2, axis=1)
    edges = np.minimum(np.minimum(point_segment_distance(p, f0, f1), point_segment_distance(p, f1, f2)),
                       point_segment_distance(p, f2, f0))
    return np.where(inside, np.minimum(interior, edges), edges)


def segment_distance(a0, a1, b0, b1):
    """(T,) distances between closed segments: interior stationary point or an endpoint."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    s, t, ok = stationary_point(d1, d2, r, -1.0)
    ok = ok & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    interior = np.linalg.norm(r + s[:, None] * d1 - t[:, None] * d2, axis=1)
    ends = np.minimum.reduce([point_segment_distance(a0, b0, b1), point_segment_distance(a1, b0, b1),
                              point_segment_distance(b0, a0, a1), point_segment_distance(b1, a0, a1)])
    return np.where(ok, np.minimum(interior, ends), ends)


def distances(kind, x_t0, x_t1, times):
    """(T,) distance between the primitives of one query at the given times."""
    x = x_t0[None] + times[:, None, None] * (x_t1 - x_t0)[None]
    if kind == "vertex-face":
        return point_triangle_distance(x[:, 0], x[:, 1], x[:, 2], x[:, 3])
    return segment_distance(x[:, 0], x[:, 1], x[:, 2], x[:, 3])


def general_queries(rng, n):
    """Turning and deforming primitives that pass through each other's neighbourhood."""
    x_t0 = rng.normal(size=(n, 4, 3))
    x_t1 = rng.normal(size=(n, 4, 3)) * 0.8
    x_t0[:, 0] *= 1.5
    x_t1[:, 0] = -x_t0[:, 0] + rng.normal(size=(n, 3)) * 0.3
    return x_t0, x_t1


@pytest.mark.parametrize("kind", KINDS)
def test_never_later_than_a_sampled_near_contact(kind):
    """dist_tol > 0 gives near contacts a positive duration, so dense sampling sees many:
    the reported time must precede every sampled time with distance <= dist_tol
    (Euclidean <= dist_tol implies within dist_tol on every axis)."""
    rng = np.random.default_rng(71 + len(kind))
    x_t0, x_t1 = general_queries(rng, 250)
    dist_tol = 1e-2
    toi = TOI[kind](x_t0, x_t1, dist_tol=dist_tol)
    times = np.linspace(0.0, 1.0, 2001)
    seen = 0
    for i in range(len(toi)):
        close = times[distances(kind, x_t0[i], x_t1[i], times) <= dist_tol * (1 - 1e-9)]
        if close.size:
            seen += 1
            assert toi[i] <= close[0], (i, toi[i], close[0])
    assert seen > 60


@pytest.mark.parametrize("kind", KINDS)
def test_reported_times_are_followed_by_a_near_contact(kind):
    """A finite toi has a time in [toi, toi + time_tol] at which the primitives are within
    dist_tol + 3 delta per axis (so sqrt(3) times that in distance); sampling that window
    finds a time within L * spacing of it, L = 2 x the fastest vertex's speed."""
    rng = np.random.default_rng(5 + len(kind))
    x_t0, x_t1 = general_queries(rng, 300)
    time_tol, dist_tol = 1e-3, 1e-3
    toi = TOI[kind](x_t0, x_t1, time_tol=time_tol, dist_tol=dist_tol)
    checked = 0
    for i in np.flatnonzero(np.isfinite(toi)):
        window = np.linspace(toi[i], min(1.0, toi[i] + time_tol), 201)
        speed = np.linalg.norm(x_t1[i] - x_t0[i], axis=1).max()
        delta = 128 * 2.0 ** -53 * np.abs(np.stack([x_t0[i], x_t1[i]])).max()
        allowed = np.sqrt(3) * (dist_tol + 3 * delta) + 2 * speed * (window[1] - window[0])
        assert distances(kind, x_t0[i], x_t1[i], window).min() <= allowed, i
        checked += 1
    assert checked > 50


# --- coplanar motions: contacts last, so exact sampling (integers) sees them ------------------

def orient(a, b, c):
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def on_segment(p, a, b):
    return (orient(a, b, p) == 0 and min(a[0], b[0]) <= p[0] <= max(a[0], b[0])
            and min(a[1], b[1]) <= p[1] <= max(a[1], b[1]))


def segments_meet(a, b, c, d):
    """Closed 2D segments ab and cd share a point (exact, integer coordinates)."""
    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    if ((o1 > 0 and o2 < 0) or (o1 < 0 and o2 > 0)) and ((o3 > 0 and o4 < 0) or (o3 < 0 and o4 > 0)):
        return True
    return on_segment(c, a, b) or on_segment(d, a, b) or on_segment(a, c, d) or on_segment(b, c, d)


def point_in_triangle(p, a, b, c):
    """Closed 2D triangle abc (possibly of zero area) contains p (exact)."""
    if orient(a, b, c) == 0:
        return on_segment(p, a, b) or on_segment(p, b, c) or on_segment(p, c, a)
    s = [orient(a, b, p), orient(b, c, p), orient(c, a, p)]
    return all(x >= 0 for x in s) or all(x <= 0 for x in s)


@pytest.mark.parametrize("kind", KINDS)
def test_coplanar_motions_against_exact_sampling(kind):
    """All points in the plane z = 0 with integer coordinates; at t = k / 256 the scaled
    positions 256 x(t) are integers, so the static tests are exact."""
    rng = np.random.default_rng(99 + len(kind))
    n = 200
    x_t0 = np.zeros((n, 4, 3))
    x_t1 = np.zeros((n, 4, 3))
    x_t0[:, :, :2] = rng.integers(-40, 41, size=(n, 4, 2))
    x_t1[:, :, :2] = x_t0[:, :, :2] + rng.integers(-20, 21, size=(n, 4, 2))
    x_t1[:, 0, :2] = -x_t0[:, 0, :2]  # the vertex / edge a sweeps through the middle
    if kind == "edge-edge":
        x_t1[:, 1, :2] = -x_t0[:, 1, :2] + rng.integers(-5, 6, size=(n, 2))
    toi = TOI[kind](x_t0, x_t1)
    seen = 0
    for i in range(n):
        p0 = x_t0[i, :, :2].astype(np.int64) * 256
        dp = (x_t1[i, :, :2] - x_t0[i, :, :2]).astype(np.int64)
        for k in range(257):
            p = [tuple(int(c) for c in row) for row in p0 + k * dp]
            touch = (point_in_triangle(p[0], p[1], p[2], p[3]) if kind == "vertex-face"
                     else segments_meet(p[0], p[1], p[2], p[3]))
            if touch:
                seen += 1
                assert toi[i] <= k / 256, (i, toi[i], k / 256)
                break
    assert seen > 40


# --- triangle level, through the narrow phase -------------------------------------------------

def test_triangle_level_times_contain_every_sampled_contact():
    """Integration with collide.narrow: dense sampling may miss contacts, never invent them:
    every sampled time at which the moving triangles intersect (exact static test) lies in
    [first contact, last contact]."""
    from collide.ccd import ccd_work, triangle_pair_toi
    from collide.predicates import triangles_intersect
    from collide.rows import COUNT_WIDTH

    rng = np.random.default_rng(7)
    work = ccd_work()
    counts = np.zeros(COUNT_WIDTH, np.int64)
    samples = np.linspace(0.0, 1.0, 401)
    seen = 0
    for _ in range(150):
        p0, q0 = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
        p1 = p0 + rng.normal(size=3) * 1.5 + rng.normal(size=(3, 3)) * 0.2
        q1 = q0 + rng.normal(size=3) * 1.5
        first = triangle_pair_toi(p0, p1, q0, q1, TOL, 0.0, np.inf, work, counts)
        last = 1.0 - triangle_pair_toi(p1, p0, q1, q0, TOL, 0.0, np.inf, work, counts)
        touching = [t for t in samples if triangles_intersect(
            np.ascontiguousarray(p0 + t * (p1 - p0)), np.ascontiguousarray(q0 + t * (q1 - q0)))]
        if touching:
            seen += 1
            assert first <= touching[0] and last >= touching[-1], (first, last, touching[0], touching[-1])
    assert seen > 20


# --- planted contacts in random motions, with the default time tolerance ----------------------

def planted_queries(rng, kind, n, thin=0.0):
    """n queries of random linear vertex motion with a contact planted at a random time
    ts (so the first contact is at or before ts). thin > 0: the triangle's third corner
    (vertex-face) or edge b's direction (edge-edge) is within thin (relative) of
    collinear / parallel, a sliver or a nearly parallel pair. -> x_t0, x_t1, ts."""
    x_t0 = np.empty((n, 4, 3))
    x_t1 = np.empty((n, 4, 3))
    ts = rng.uniform(0, 1, n)
    for i in range(n):
        x = rng.normal(size=(4, 3))
        if thin:
            base, start = (1, 1) if kind == "vertex-face" else (0, 2)
            x[3] = x[start] + rng.uniform(0.3, 3) * (x[base + 1] - x[base]) + thin * rng.normal(size=3)
        velocity = rng.normal(size=(4, 3)) * rng.choice([0.1, 1.0, 5.0])
        if kind == "vertex-face":
            u, v = rng.dirichlet([1, 1, 1])[:2]
            x[0] = (1 - u - v) * x[1] + u * x[2] + v * x[3]
        else:
            u, v = rng.uniform(0, 1, 2)
            offset = x[0] + u * (x[1] - x[0]) - (x[2] + v * (x[3] - x[2]))
            x[2:] += offset
        x_t0[i] = x - ts[i] * velocity
        x_t1[i] = x + (1 - ts[i]) * velocity
    return x_t0, x_t1, ts


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _point_segment_d2(p, a, b):
    """Exact squared distance from point p to the closed segment ab (Fractions)."""
    d, r = sub(b, a), sub(p, a)
    dd = _dot(d, d)
    s = min(max(_dot(r, d) / dd, 0), 1) if dd else 0
    e = [ri - s * di for ri, di in zip(r, d)]
    return _dot(e, e)


def exact_distance2(kind, points):
    """Exact squared distance between the primitives (4 points as Fractions): a convex
    quadratic over the parameter domain, so its minimum is at the interior stationary
    point or on the domain's boundary (point-segment distances)."""
    if kind == "vertex-face":
        p, f0, f1, f2 = points
        edges = min(_point_segment_d2(p, f0, f1), _point_segment_d2(p, f1, f2), _point_segment_d2(p, f2, f0))
        e1, e2, r = sub(f1, f0), sub(f2, f0), sub(p, f0)
        a11, a12, a22, b1, b2 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2), _dot(r, e1), _dot(r, e2)
        det = a11 * a22 - a12 * a12
        if det:
            u, v = (b1 * a22 - b2 * a12) / det, (a11 * b2 - a12 * b1) / det
            if u >= 0 and v >= 0 and u + v <= 1:
                e = [ri - u * x - v * y for ri, x, y in zip(r, e1, e2)]
                return min(edges, _dot(e, e))
        return edges
    a0, a1, b0, b1 = points
    ends = min(_point_segment_d2(a0, b0, b1), _point_segment_d2(a1, b0, b1),
               _point_segment_d2(b0, a0, a1), _point_segment_d2(b1, a0, a1))
    d1, d2, r = sub(a1, a0), sub(b1, b0), sub(a0, b0)
    a, b, c, e, f = _dot(d1, d1), _dot(d1, d2), _dot(d2, d2), _dot(d1, r), _dot(d2, r)
    det = a * c - b * b
    if det:
        s, t = (b * f - c * e) / det, (a * f - b * e) / det
        if 0 <= s <= 1 and 0 <= t <= 1:
            g = [ri + s * x - t * y for ri, x, y in zip(r, d1, d2)]
            return min(ends, _dot(g, g))
    return ends


def assert_followed_by_near_contact(kind, x_t0, x_t1, toi, time_tol, ts=None, samples=41):
    """Each finite toi has a time in [toi, toi + time_tol] where the primitives are within
    3 delta per axis (module guarantee, dist_tol = 0). Nothing to check when a contact
    is known there already (toi >= ts - time_tol for a planted contact at ts); otherwise
    exact distances at samples of the window must find one within the distance the
    fastest vertex pair covers between samples."""
    for i in np.flatnonzero(np.isfinite(toi)):
        if ts is not None and toi[i] >= ts[i] - time_tol:
            continue
        window = np.linspace(toi[i], min(1.0, toi[i] + time_tol), samples)
        speed = np.linalg.norm(x_t1[i] - x_t0[i], axis=1).max()
        delta = 128 * 2.0 ** -53 * np.abs(np.stack([x_t0[i], x_t1[i]])).max()
        allowed = Fraction(np.sqrt(3) * 3 * delta + 2 * speed * (window[1] - window[0]))
        p0, p1 = [frac(r) for r in x_t0[i]], [frac(r) for r in x_t1[i]]
        gap2 = min(exact_distance2(kind, [[a + Fraction(t) * (b - a) for a, b in zip(q0, q1)]
                                          for q0, q1 in zip(p0, p1)]) for t in window)
        assert gap2 <= allowed * allowed, (i, toi[i], float(gap2) ** 0.5, float(allowed))


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("thin", [0.0, 1e-2, 1e-4])
def test_planted_contacts_found_and_not_too_early(kind, thin):
    """Ordinary, thin and nearly parallel primitives with the default time_tol (1e-6):
    never missed, never after the planted contact, and never more than time_tol before
    a near contact. (The search once ran out of live boxes on 0.1 % of such ordinary
    queries and on most thin ones, and answered up to 1 % of the step too early.)"""
    rng = np.random.default_rng({0.0: 3, 1e-2: 4, 1e-4: 5}[thin] + 10 * len(kind))
    x_t0, x_t1, ts = planted_queries(rng, kind, 1500 if thin == 0.0 else 400, thin)
    toi = TOI[kind](x_t0, x_t1)
    assert np.all(toi <= ts)  # also: no inf (never missed)
    assert_followed_by_near_contact(kind, x_t0, x_t1, toi, 1e-6, ts)


def test_queries_that_once_ran_out_of_boxes():
    """Ordinary queries (found by random testing) on which an earlier search ran out of
    live boxes and answered 2e-6 to 1e-2 of the step too early."""
    hard = np.load(Path(__file__).parent / "data" / "ccd_hard_queries.npz")
    for kind, key in (("vertex-face", "vf"), ("edge-edge", "ee")):
        x_t0, x_t1 = hard[f"{key}_t0"], hard[f"{key}_t1"]
        toi = TOI[kind](x_t0, x_t1)
        assert np.all(np.isfinite(toi))
        assert_followed_by_near_contact(kind, x_t0, x_t1, toi, 1e-6)


# --- the coplanarity filter against exact arithmetic ------------------------------------------

def _exact_points(x_t0, x_t1, t):
    """The query's 4 points at rational time t, exactly (lists of Fractions)."""
    return [[Fraction(float(a)) + t * (Fraction(float(b)) - Fraction(float(a))) for a, b in zip(r0, r1)]
            for r0, r1 in zip(x_t0, x_t1)]


def _plane_vectors_exact(kind, x_t0, x_t1, t):
    """The 3 vectors of ccd._plane_vectors at rational time t, exactly (Fractions)."""
    p = _exact_points(x_t0, x_t1, t)
    if kind == "vertex-face":  # v, f0, f1, f2
        return sub(p[2], p[1]), sub(p[3], p[1]), sub(p[0], p[1])
    return sub(p[1], p[0]), sub(p[3], p[2]), sub(p[2], p[0])


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _coplanarity_cubic(kind, x_t0, x_t1):
    """Exact coefficients (c0, c1, c2, c3) of g(t) = det of the plane vectors: the cubic
    through its values at t = 0, 1/3, 2/3, 1 (Lagrange), low degree first."""
    ts = [Fraction(k, 3) for k in range(4)]
    gs = [_dot(_cross(a, b), c) for a, b, c in (_plane_vectors_exact(kind, x_t0, x_t1, t) for t in ts)]
    coeffs = [Fraction(0)] * 4
    for i, (ti, gi) in enumerate(zip(ts, gs)):
        basis = [Fraction(1)]  # prod over j != i of (t - tj) / (ti - tj)
        for j, tj in enumerate(ts):
            if j != i:
                basis = [(x if k < len(basis) else 0) * -tj + (basis[k - 1] if k > 0 else 0)
                         for k, x in enumerate(basis + [0])]
                basis = [x / (ti - tj) for x in basis]
        coeffs = [c + gi * b for c, b in zip(coeffs, basis)]
    return coeffs


def _poly_eval(c, t):
    return sum(ci * t ** k for k, ci in enumerate(c))


def _poly_rem(a, b):
    """Remainder of a / b (low degree first, b's leading coefficient nonzero)."""
    a = list(a)
    while len(a) >= len(b) and any(a):
        factor = a[-1] / b[-1]
        shift = len(a) - len(b)
        for k, bk in enumerate(b):
            a[k + shift] -= factor * bk
        a.pop()
    return a


def _trim(c):
    c = list(c)
    while c and c[-1] == 0:
        c.pop()
    return c


def _roots_in(c, lo, hi):
    """Number of distinct real roots of the polynomial c in [lo, hi] (Sturm's theorem)."""
    c = _trim(c)
    if not c:
        return np.inf  # g is zero everywhere
    chain = [c, _trim([k * ck for k, ck in enumerate(c)][1:])]
    while len(chain[-1]) > 1:
        chain.append(_trim([-x for x in _poly_rem(chain[-2], chain[-1])]))
        if not chain[-1]:
            chain.pop()
            break

    def sign_changes(t):
        signs = [s for s in (np.sign(_poly_eval(p, t)) for p in chain if p) if s != 0]
        return sum(1 for a, b in zip(signs, signs[1:]) if a != b)
    return sign_changes(lo) - sign_changes(hi) + (1 if _poly_eval(c, lo) == 0 else 0)


def _coplanarity_cases(rng):
    """Queries with coplanar moments (planted contacts, slivers, general motions), also
    moved far from the origin, each with time ranges: all of [0, 1], random ones, and
    narrow ones around a planted contact."""
    cases = []
    for kind in KINDS:
        for x_t0, x_t1, ts in (planted_queries(rng, kind, 40), planted_queries(rng, kind, 20, thin=1e-4),
                               (*general_queries(rng, 40), rng.uniform(0, 1, 40))):
            for i in range(len(x_t0)):
                offset = rng.choice([0.0, 1e3]) * rng.normal(size=3)
                ranges = [(0.0, 1.0), tuple(np.sort(rng.uniform(0, 1, 2)))]
                ranges += [(max(0.0, ts[i] - w), min(1.0, ts[i] + w)) for w in (1e-3, 1e-8)]
                ranges += [(max(0.0, ts[i] - 2 * w), ts[i] - w) for w in (1e-4, 1e-9) if ts[i] > 2 * w]
                cases.append((kind, x_t0[i] + offset, x_t1[i] + offset, ranges))
        for _ in range(20):  # exactly coplanar at every moment: in the plane z = x + y, far out
            x = dyadic(rng, (2, 4, 3)) + 512 * rng.integers(-4, 5, size=3)
            x[..., 2] = x[..., 0] + x[..., 1]
            cases.append((kind, x[0], x[1], [(0.0, 1.0), tuple(np.sort(rng.uniform(0, 1, 2)))]))
    return cases


@pytest.mark.parametrize("dist_tol", [0.0, 1e-3])
def test_coplanarity_filter_never_drops_a_moment_of_contact(dist_tol):
    """ccd._coplanarity_excluded drops a time range only when, exactly, the 4 points are
    never coplanar in it (Sturm count of the exact cubic), and with dist_tol > 0 when the
    points also stay beyond dist_tol of coplanar at every sampled moment of it
    (|g(t)| > dist_tol * sum |n_i(t)|, n the exact normal): the condition under which no
    two points of the primitives come within dist_tol on every axis. It must also drop
    most ranges that are far from coplanar, or it would be a filter in name only."""
    from collide import ccd
    rng = np.random.default_rng(77 + int(dist_tol > 0))
    scratch = np.empty((8, 3))
    dropped = clear = missed_clear = 0
    for kind, x_t0, x_t1, ranges in _coplanarity_cases(rng):
        x_t0 = np.ascontiguousarray(x_t0)
        x_t1 = np.ascontiguousarray(x_t1)
        m = ccd._largest_coordinates(x_t0, x_t1)
        code = np.int64(ccd.VERTEX_FACE if kind == "vertex-face" else ccd.EDGE_EDGE)
        cubic = _coplanarity_cubic(kind, x_t0, x_t1)
        for lo, hi in ranges:
            excluded = ccd._coplanarity_excluded(code, x_t0, x_t1, lo, hi, dist_tol, m, scratch)
            lo_f, hi_f = Fraction(float(lo)), Fraction(float(hi))
            samples = [lo_f + (hi_f - lo_f) * Fraction(k, 16) for k in range(17)]
            margins = []
            for t in samples:
                a, b, c = _plane_vectors_exact(kind, x_t0, x_t1, t)
                normal = _cross(a, b)
                margins.append(abs(_dot(normal, c)) - dist_tol * sum(abs(x) for x in normal))
            if excluded:
                dropped += 1
                assert _roots_in(cubic, lo_f, hi_f) == 0, (kind, lo, hi)
                assert min(margins) > 0, (kind, lo, hi)
            # far from coplanar: |g| minus dist_tol |n|_1 stays above a tenth of the
            # cubic's largest coefficient
            if min(margins) > max(abs(x) for x in cubic) / 10 and _roots_in(cubic, lo_f, hi_f) == 0:
                clear += 1
                missed_clear += not excluded
    assert dropped > 100 and clear > 50 and missed_clear <= clear // 20


def _exact_f(kind, x_t0, x_t1, t, u, v):
    """F (module docstring of collide.ccd) at rational (t, u, v), exactly (Fractions)."""
    p = _exact_points(x_t0, x_t1, t)
    if kind == "vertex-face":
        return [(p[0][i] - p[1][i]) - u * (p[2][i] - p[1][i]) - v * (p[3][i] - p[1][i]) for i in range(3)]
    return [(p[0][i] - p[2][i]) + u * (p[1][i] - p[0][i]) - v * (p[3][i] - p[2][i]) for i in range(3)]


@pytest.mark.parametrize("dist_tol", [0.0, 1e-3])
def test_shrinking_cuts_off_only_parts_beyond_the_tolerance(dist_tol):
    """ccd._shrink cuts ends off a box only where, exactly, F is beyond dist_tol on some
    axis: checked with exact arithmetic at points of every cut-off end, including its
    inner boundary. Boxes are random, also tiny ones around planted contacts (where the
    cuts are narrowest) and ones around an edge that a vertex passes just beside."""
    from collide import ccd
    rng = np.random.default_rng(91 + int(dist_tol > 0))
    work = ccd.ccd_work()
    box = np.empty(7)
    checked = cut = 0
    for kind in KINDS:
        code = np.int64(ccd.VERTEX_FACE if kind == "vertex-face" else ccd.EDGE_EDGE)
        x_t0s, x_t1s, ts = planted_queries(rng, kind, 60)
        x_t0s[30:] += rng.normal(size=(30, 1, 3)) * 1e-9  # near misses, just beside the contact
        for x_t0, x_t1, ts_i in zip(x_t0s, x_t1s, ts):
            x_t0 = np.ascontiguousarray(x_t0)
            x_t1 = np.ascontiguousarray(x_t1)
            delta = ccd._rounding_bound(ccd._largest_coordinates(x_t0, x_t1))
            tol_out = tuple(dist_tol + d for d in delta)
            for size in (1.0, 1e-2, 1e-5, 1e-9):
                centre = np.array([ts_i, *rng.uniform(0, 1, 2)])
                lo = np.clip(centre - size * rng.uniform(0.1, 1, 3), 0, 1)
                hi = np.clip(centre + size * rng.uniform(0.1, 1, 3), 0, 1)
                box[:] = (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], 0.0)
                before = box.copy()
                ccd._box_corners(code, x_t0, x_t1, box, work.corners)
                outcome = ccd._shrink(work.corners, box, tol_out)
                checked += 1
                if outcome == 0:
                    assert np.array_equal(box, before)
                    continue
                cut += 1
                slabs = []  # (dimension, outer bound, bound next to what is kept)
                for d in range(3):
                    if outcome < 0:  # all of it is ruled out
                        slabs.append((d, before[2 * d], before[2 * d + 1]))
                        continue
                    if box[2 * d] > before[2 * d]:
                        slabs.append((d, before[2 * d], np.nextafter(box[2 * d], -np.inf)))
                    if box[2 * d + 1] < before[2 * d + 1]:
                        slabs.append((d, before[2 * d + 1], np.nextafter(box[2 * d + 1], np.inf)))
                for d, outer, inner in slabs:
                    for s in (Fraction(0), Fraction(1, 2), Fraction(1)):  # inner: just beside the kept box
                        point = [Fraction(float(rng.uniform(before[2 * k], before[2 * k + 1]))) for k in range(3)]
                        point[d] = Fraction(float(outer)) + s * (Fraction(float(inner)) - Fraction(float(outer)))
                        f = _exact_f(kind, x_t0, x_t1, *point)
                        assert max(abs(x) for x in f) > dist_tol, (kind, before, box, d, point)
    assert checked > 400 and cut > 40


def test_shrinking_keeps_every_exact_contact():
    """A box that holds an exact contact point (rigid dyadic motions, contact solved in
    rational arithmetic) is never ruled out by ccd._shrink, and the point stays in the
    box it leaves, even when the point lies a millionth of the box's width from a side."""
    from collide import ccd
    rng = np.random.default_rng(5)
    work = ccd.ccd_work()
    box = np.empty(7)
    kept = 0
    for kind in KINDS:
        code = np.int64(ccd.VERTEX_FACE if kind == "vertex-face" else ccd.EDGE_EDGE)
        x_t0s, x_t1s = rigid_queries(rng, kind, 200)
        for x_t0, x_t1 in zip(x_t0s[:100], x_t1s[:100]):  # the planted half
            point = exact_contact_point(kind, x_t0, x_t1)
            if point is None or point == np.inf:
                continue
            delta = ccd._rounding_bound(ccd._largest_coordinates(x_t0, x_t1))
            for size in (0.5, 1e-3, 1e-7):
                side = rng.integers(0, 3)
                lo, hi = np.empty(3), np.empty(3)
                for d in range(3):
                    near = 1e-6 if d == side else rng.uniform(0.1, 0.9)  # the point's place in the box
                    lo[d] = float(point[d]) - near * size
                    hi[d] = lo[d] + size
                if rng.random() < 0.5:  # near the upper side instead
                    lo[side], hi[side] = float(point[side]) - (1 - 1e-6) * size, float(point[side]) + 1e-6 * size
                box[:] = (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], 0.0)
                inside = [Fraction(box[2 * d]) <= point[d] <= Fraction(box[2 * d + 1]) for d in range(3)]
                if not all(inside):
                    continue  # rounding put the point just outside: nothing to check
                ccd._box_corners(code, np.ascontiguousarray(x_t0), np.ascontiguousarray(x_t1), box, work.corners)
                assert ccd._shrink(work.corners, box, delta) >= 0, (kind, point, size)
                assert all(Fraction(box[2 * d]) <= point[d] <= Fraction(box[2 * d + 1]) for d in range(3))
                kept += 1
    assert kept > 300
