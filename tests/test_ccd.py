"""Certified CCD primitives: zero false negatives on the benchmark queries, exact times on
analytic motions, degenerate motions, and agreement with dense sampling at triangle level."""
import numpy as np
import pytest

from ccd_queries import KINDS, read_scene, scenes
from collide.ccd import edge_edge_toi, vertex_face_toi
from collide.narrow import triangle_pair_toi
from collide.predicates import triangles_intersect
from conftest import DATA, SHARED_DATA

TOI = {"vertex-face": vertex_face_toi, "edge-edge": edge_edge_toi}
TOL = 1e-6


def assert_no_false_negative(root):
    checked = 0
    for scene in scenes(root):
        for kind in KINDS:
            x_t0, x_t1, truth = read_scene(scene, kind)
            toi = TOI[kind](x_t0, x_t1)
            missed = np.flatnonzero(truth & ~np.isfinite(toi))
            assert missed.size == 0, f"{scene.name}/{kind}: missed queries {missed.tolist()}"
            assert ((toi >= 0) & (toi <= 1) | ~np.isfinite(toi)).all()
            checked += truth.sum()
    return checked


def test_no_false_negative_on_bundled_queries():
    assert assert_no_false_negative(DATA / "ccd") > 150


def test_no_false_negative_on_all_benchmark_queries():
    root = SHARED_DATA / "ccd-queries"
    if not root.is_dir():
        pytest.skip(f"benchmark queries not found at {root}")
    assert assert_no_false_negative(root) > 300


def q(*rows):
    return np.array(rows, dtype=np.float64)


FACE = q([0, 0, 0], [1, 0, 0], [0, 1, 0])


def vf(v0, v1, face0=FACE, face1=FACE, **kw):
    return vertex_face_toi(np.vstack([v0, face0]), np.vstack([v1, face1]), **kw)[0]


def ee(a0, a1, b0, b1, **kw):
    return edge_edge_toi(np.vstack([a0, b0]), np.vstack([a1, b1]), **kw)[0]


def within(toi, exact, tol=TOL):
    return exact - tol <= toi <= exact


def test_vertex_falls_onto_face():
    assert within(vf([0.25, 0.25, 1], [0.25, 0.25, -1]), 0.5)
    assert within(vf([0.25, 0.25, 1], [0.25, 0.25, -3]), 0.25)
    assert within(vf([0.25, 0.25, 1], [0.25, 0.25, -1], time_tol=1e-3), 0.5, 1e-3)
    # the face moves up to meet a still vertex
    assert within(vf([0.25, 0.25, 1], [0.25, 0.25, 1], FACE, FACE + [0, 0, 4]), 0.25)
    # hits the face's edge and its corner exactly
    assert within(vf([0.5, 0.5, 1], [0.5, 0.5, -1]), 0.5)
    assert within(vf([0, 0, 1], [0, 0, -1]), 0.5)


def test_vertex_misses_face():
    assert vf([0.75, 0.75, 1], [0.75, 0.75, -1]) == np.inf              # outside u + v <= 1
    assert vf([0.5 + 1e-4, 0.5 + 1e-4, 1], [0.5 + 1e-4, 0.5 + 1e-4, -1]) == np.inf
    assert vf([0.25, 0.25, 1], [0.25, 0.25, 1e-4]) == np.inf            # stops short
    assert vf([0.25, 0.25, -1], [0.25, 0.25, -2]) == np.inf             # moves away


def test_edges_cross():
    # a along x at height 1 - 2t, b along y at 0: they meet at t = 1/2
    assert within(ee([[-1, 0, 1], [1, 0, 1]], [[-1, 0, -1], [1, 0, -1]], [[0, -1, 0], [0, 1, 0]],
                     [[0, -1, 0], [0, 1, 0]]), 0.5)
    # ... unless a passes beyond b's end
    assert ee([[-1, 2, 1], [1, 2, 1]], [[-1, 2, -1], [1, 2, -1]], [[0, -1, 0], [0, 1, 0]],
              [[0, -1, 0], [0, 1, 0]]) == np.inf


def test_degenerate_motions():
    still = [[0.25, 0.25, 0]]
    assert vf(still, still) == 0.0                                      # no motion, touching
    assert vf([[0.25, 0.25, 1]], [[0.25, 0.25, 1]]) == np.inf           # no motion, apart
    # parallel edges approaching sideways, coplanar: meet at t = 0.25
    assert within(ee([[0, 1, 0], [1, 1, 0]], [[0, -3, 0], [1, -3, 0]], [[0.5, 0, 0], [2, 0, 0]],
                     [[0.5, 0, 0], [2, 0, 0]]), 0.25)
    # collinear edges sliding into each other: meet at t = 0.5
    assert within(ee([[-3, 0, 0], [-2, 0, 0]], [[-1, 0, 0], [0, 0, 0]], [[-1, 0, 0], [1, 0, 0]],
                     [[-1, 0, 0], [1, 0, 0]]), 0.5)
    # zero-length edge (a point) hitting an edge
    assert within(ee([[0, 1, 0], [0, 1, 0]], [[0, -1, 0], [0, -1, 0]], [[-1, 0, 0], [1, 0, 0]],
                     [[-1, 0, 0], [1, 0, 0]]), 0.5)
    # a vertex sliding within the face's plane into the triangle
    assert within(vf([[-1, 0.25, 0]], [[1, 0.25, 0]]), 0.5)
    # degenerate (zero-area) face: a needle
    needle = q([0, 0, 0], [1, 0, 0], [2, 0, 0])
    assert within(vf([[0.5, 0, 1]], [[0.5, 0, -1]], needle, needle), 0.5)


def test_batch_shapes_and_errors():
    x = np.zeros((5, 4, 3))
    assert vertex_face_toi(x, x).shape == (5,)
    assert edge_edge_toi(x[0], x[0]).shape == (1,)
    with pytest.raises(ValueError):
        vertex_face_toi(np.zeros((5, 3, 3)), np.zeros((5, 3, 3)))
    with pytest.raises(ValueError):
        edge_edge_toi(np.full((1, 4, 3), np.nan), np.zeros((1, 4, 3)))


def interpolate(x_t0, x_t1, t):
    return np.ascontiguousarray(x_t0 + t * (x_t1 - x_t0))


def test_triangle_level_times_contain_every_sampled_contact():
    """Dense sampling may miss contacts, never invent them: every sampled time at which the
    moving triangles intersect (exact test) lies in [first contact, last contact]."""
    rng = np.random.default_rng(7)
    x0, x1 = np.empty((4, 3)), np.empty((4, 3))
    samples = np.linspace(0.0, 1.0, 401)
    seen = 0
    for _ in range(150):
        p0, q0 = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
        p1 = p0 + rng.normal(size=3) * 1.5 + rng.normal(size=(3, 3)) * 0.2
        q1 = q0 + rng.normal(size=3) * 1.5
        first = triangle_pair_toi(p0, p1, q0, q1, TOL, 0.0, x0, x1)
        last = 1.0 - triangle_pair_toi(p1, p0, q1, q0, TOL, 0.0, x0, x1)
        touching = [t for t in samples if triangles_intersect(interpolate(p0, p1, t), interpolate(q0, q1, t))]
        if touching:
            seen += 1
            assert first <= touching[0] and last >= touching[-1], (first, last, touching[0], touching[-1])
    assert seen > 20
