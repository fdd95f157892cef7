"""BVH invariants for every split rule, checked against the primitives directly."""
import numpy as np
import pytest
from conftest import DATA

from collide.bvh import SPLIT_RULES, build_bvh, build_mesh_bvh, bvh_stats, triangle_boxes
from collide.load import load_mesh


def check_bvh(bvh, lo, hi, leaf_size):
    n = lo.shape[0]
    leaves = np.flatnonzero(bvh.count > 0)
    # every primitive sits in exactly one leaf
    covered = np.concatenate([bvh.prim_ids[bvh.first[k]:bvh.first[k] + bvh.count[k]] for k in leaves])
    assert sorted(covered.tolist()) == list(range(n))
    assert bvh.count[leaves].max() <= leaf_size
    # every leaf box is the exact box of its primitives; inner boxes are the union of their children
    for node in range(bvh.count.shape[0]):
        if bvh.count[node] > 0:
            ids = bvh.prim_ids[bvh.first[node]:bvh.first[node] + bvh.count[node]]
            assert np.array_equal(bvh.lo[node], lo[ids].min(axis=0))
            assert np.array_equal(bvh.hi[node], hi[ids].max(axis=0))
        else:
            kids = [bvh.first[node], bvh.first[node] + 1]
            assert all(k > node for k in kids)
            assert np.array_equal(bvh.lo[node], bvh.lo[kids].min(axis=0))
            assert np.array_equal(bvh.hi[node], bvh.hi[kids].max(axis=0))
    # every node except the root is the child of exactly one inner node
    inner = np.flatnonzero(bvh.count == 0)
    children = np.concatenate([bvh.first[inner], bvh.first[inner] + 1])
    assert sorted(children.tolist()) == list(range(1, bvh.count.shape[0]))


@pytest.mark.parametrize("split", sorted(SPLIT_RULES))
@pytest.mark.parametrize("leaf_size", [1, 2, 4, 9])
def test_invariants_on_fcl_meshes(split, leaf_size):
    for name in ("env.obj", "rob.obj"):
        mesh = load_mesh(DATA / name)
        lo, hi, _ = triangle_boxes(mesh.vertices, mesh.faces)
        check_bvh(build_mesh_bvh(mesh.vertices, mesh.faces, split, leaf_size), lo, hi, leaf_size)


@pytest.mark.parametrize("split", sorted(SPLIT_RULES))
def test_degenerate_inputs(split):
    """Coincident centres, a single primitive, flat boxes, duplicated boxes."""
    rng = np.random.default_rng(3)
    cases = [np.zeros((1, 3)), np.zeros((37, 3)), np.repeat(rng.random((1, 3)), 20, axis=0),
             np.c_[rng.random((50, 2)), np.zeros(50)], rng.random((200, 3))]
    for centres in cases:
        lo, hi = centres - 0.01, centres + 0.01
        check_bvh(build_bvh(lo, hi, centres, split, 3), lo, hi, 3)


def test_sah_tree_is_cheaper_than_median():
    mesh = load_mesh(DATA / "env.obj")
    cost = {s: bvh_stats(build_mesh_bvh(mesh.vertices, mesh.faces, s, 4))["sah_cost"] for s in SPLIT_RULES}
    assert cost["sah"] < cost["median"] and cost["sah"] < cost["mean"]


def test_unknown_split_rule_is_an_error():
    with pytest.raises(ValueError, match="unknown split rule"):
        build_bvh(np.zeros((2, 3)), np.ones((2, 3)), np.zeros((2, 3)), "middle")
