"""BVH invariants for every split rule, checked against the primitives directly."""
import numpy as np
import pytest
from conftest import DATA

from collide import bvh as bvh_module
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
    check_smallest_id_order(bvh)


def check_smallest_id_order(bvh):
    """Leaves ascend, and smallest_id_under (first primitive of the leftmost leaf) is
    the minimum of the subtree's primitives at every node (computed children first)."""
    first, count = bvh.first.tolist(), bvh.count.tolist()
    smallest = [0] * len(count)
    for node in reversed(range(len(count))):
        if count[node] > 0:
            ids = bvh.prim_ids[first[node]:first[node] + count[node]]
            assert (np.diff(ids) > 0).all()
            smallest[node] = int(ids.min())
        else:
            smallest[node] = min(smallest[first[node]], smallest[first[node] + 1])
        assert bvh_module.smallest_id_under(bvh.first, bvh.count, bvh.prim_ids, node) == smallest[node]
    assert bvh_module.in_smallest_id_order(bvh.first, bvh.count, bvh.prim_ids)


@pytest.mark.parametrize("split", sorted(SPLIT_RULES))
@pytest.mark.parametrize("leaf_size", [1, 2, 4, 9])
def test_invariants_on_fcl_meshes(split, leaf_size):
    for name in ("env.obj", "rob.obj"):
        mesh = load_mesh(DATA / name)
        lo, hi, _ = triangle_boxes(mesh.vertices, mesh.faces)
        check_bvh(build_mesh_bvh(mesh.vertices, mesh.faces, split, leaf_size), lo, hi, leaf_size)


@pytest.mark.parametrize("split", sorted(SPLIT_RULES))
@pytest.mark.parametrize("leaf_size", [1, 3])
def test_degenerate_inputs(split, leaf_size):
    """Coincident centres, one to three primitives, flat boxes, duplicated boxes, centres
    on a coarse grid (many equal Morton codes), tiny and huge extents."""
    rng = np.random.default_rng(3)
    cases = [np.zeros((1, 3)), np.zeros((2, 3)), rng.random((2, 3)), rng.random((3, 3)), np.zeros((3, 3)),
             np.zeros((37, 3)), np.repeat(rng.random((1, 3)), 20, axis=0),
             np.c_[rng.random((50, 2)), np.zeros(50)], np.c_[rng.random(40), np.zeros((40, 2))],
             rng.random((200, 3)), np.round(rng.random((300, 3)), 1), np.repeat(rng.random((5, 3)), 9, axis=0),
             1e-310 * rng.random((30, 3)), 1e80 * (rng.random((30, 3)) - 0.5)]
    for centres in cases:
        lo, hi = centres - 0.01, centres + 0.01
        check_bvh(build_bvh(lo, hi, centres, split, leaf_size), lo, hi, leaf_size)


def test_sah_tree_is_the_cheapest():
    mesh = load_mesh(DATA / "env.obj")
    cost = {s: bvh_stats(build_mesh_bvh(mesh.vertices, mesh.faces, s, 4))["sah_cost"] for s in SPLIT_RULES}
    assert all(cost["sah"] < cost[s] for s in SPLIT_RULES if s != "sah"), cost


def test_triangle_boxes_are_the_corner_reductions():
    """Bit for bit the min, max and mean of each triangle's corners."""
    rng = np.random.default_rng(5)
    vertices = rng.normal(size=(300, 3)) * 10.0 ** rng.integers(-8, 8, size=(300, 1))
    faces = rng.integers(0, 300, size=(2000, 3))
    corners = vertices[faces]
    expected = corners.min(axis=1), corners.max(axis=1), corners.mean(axis=1)
    assert all(a.dtype == b.dtype and a.tobytes() == b.tobytes()
               for a, b in zip(triangle_boxes(vertices, faces), expected))


# --- lbvh: Morton codes and the radix tree ------------------------------------------------------

def test_morton_bits_are_interleaved():
    rng = np.random.default_rng(7)
    for v in [0, 1, 2, 0x1FFFFF, 0x155555, *rng.integers(0, 1 << 21, 50).tolist()]:
        assert bvh_module._spread_bits(v) == sum(((v >> b) & 1) << (3 * b) for b in range(21))
    for x in [1, 2, 3, 255, 256, (1 << 62) + 5, (1 << 63) - 1, *rng.integers(1, 1 << 62, 50).tolist()]:
        assert bvh_module._leading_zeros(x) == 64 - int(x).bit_length()


@pytest.mark.parametrize("seed", range(4))
def test_radix_tree_splits_at_the_first_differing_bit(seed):
    """Every inner node found independently (Karras) is the node of the top-down radix
    split of its range: keys (code, index), split after the last key that agrees with the
    range's first key on the highest bit where the range's first and last keys differ;
    the children covering a..s and s + 1..b are inner nodes s and s + 1."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 400))
    codes = np.sort(rng.integers(0, [8, 1 << 20, 1 << 62, 3][seed], n)).astype(np.int64)  # with duplicates
    split = bvh_module._radix_splits(codes)
    keys = [(int(c) << 64) | i for i, c in enumerate(codes)]
    stack, seen = [(0, 0, n - 1)], 0
    while stack:
        node, a, b = stack.pop()
        seen += 1
        bit = (keys[a] ^ keys[b]).bit_length() - 1
        s = max(k for k in range(a, b) if (keys[k] >> bit) & 1 == (keys[a] >> bit) & 1)
        assert split[node] == s, (node, a, b)
        if s > a:
            stack.append((s, a, s))
        if s + 1 < b:
            stack.append((s + 1, s + 1, b))
    assert seen == n - 1


def test_lbvh_collapses_exactly_the_radix_subtrees_that_are_cheaper_as_leaves():
    """The leaf_size 4 tree is the leaf_size 1 tree (the whole radix tree, same primitive
    order up to the order inside each leaf) with every subtree of at most 4 primitives
    whose leaf cost is at most its best cost as an inner node made a leaf; its SAH cost
    is that optimum."""
    mesh = load_mesh(DATA / "env.obj")
    n = mesh.faces.shape[0]
    full = build_mesh_bvh(mesh.vertices, mesh.faces, "lbvh", 1)
    tree = build_mesh_bvh(mesh.vertices, mesh.faces, "lbvh", 4)
    # the same primitive order but within leaves (sorted by id in both)
    assert full.count.shape[0] == 2 * n - 1
    leaf_starts = np.sort(tree.first[tree.count > 0])
    assert np.array_equal(np.concatenate([np.sort(part) for part in np.split(full.prim_ids, leaf_starts[1:])]),
                          tree.prim_ids)

    def ranges(bvh):   # (start, size) of every node's primitives
        m = bvh.count.shape[0]
        start, size = np.zeros(m, np.int64), np.zeros(m, np.int64)
        for node in range(m - 1, -1, -1):
            c = bvh.first[node]
            start[node], size[node] = ((c, bvh.count[node]) if bvh.count[node]
                                       else (min(start[c], start[c + 1]), size[c] + size[c + 1]))
        return list(zip(start.tolist(), size.tolist()))

    areas = [bvh_module._half_area(lo, hi) for lo, hi in zip(full.lo, full.hi)]
    best, as_leaf = np.zeros(2 * n - 1), {}
    for node, (start, size) in reversed(list(enumerate(ranges(full)))):
        c = full.first[node]
        inner = np.inf if full.count[node] else areas[node] + best[c] + best[c + 1]
        leaf = areas[node] * size if size <= 4 else np.inf
        best[node] = min(leaf, inner)
        as_leaf[(start, size)] = leaf <= inner
    tree_ranges = ranges(tree)
    assert all(r in as_leaf for r in tree_ranges)   # every node is a node of the radix tree
    assert all(as_leaf[r] == (tree.count[k] > 0) for k, r in enumerate(tree_ranges))
    assert np.isclose(bvh_stats(tree)["sah_cost"] * areas[0], best[0], rtol=1e-12)


def test_lbvh_does_not_depend_on_the_thread_count(monkeypatch):
    numba = pytest.importorskip("numba")
    monkeypatch.setattr(bvh_module.config, "LBVH_PARALLEL_MIN", 0)   # parallel at any size
    mesh = load_mesh(DATA / "env.obj")
    previous = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = build_mesh_bvh(mesh.vertices, mesh.faces, "lbvh", 4)
    finally:
        numba.set_num_threads(previous)
    many = build_mesh_bvh(mesh.vertices, mesh.faces, "lbvh", 4)
    assert all(a.tobytes() == b.tobytes() for a, b in zip(one, many))


def test_unknown_split_rule_is_an_error():
    with pytest.raises(ValueError, match="unknown split rule"):
        build_bvh(np.zeros((2, 3)), np.ones((2, 3)), np.zeros((2, 3)), "middle")


def test_thread_limit_caps_and_restores_numba_threads():
    numba = pytest.importorskip("numba")
    from collide.jit import thread_limit
    before = numba.get_num_threads()
    with thread_limit(1):
        assert numba.get_num_threads() == 1
    with thread_limit(10**6):
        assert numba.get_num_threads() == numba.config.NUMBA_NUM_THREADS
    assert numba.get_num_threads() == before


@pytest.mark.parametrize("split", ["sah", "median"])
def test_meshes_built_in_threads_pack_the_same_scene(split):
    """pack_scene(workers=3) builds several meshes at once: the same arrays as one by one."""
    from collide.packed import pack_scene
    meshes = [load_mesh(DATA / "env.obj"), load_mesh(DATA / "rob.obj"), load_mesh(DATA / "rob.obj")]
    one, _ = pack_scene(meshes, np.array([0, 1, 2, 1]), split, 3, workers=1)
    three, _ = pack_scene(meshes, np.array([0, 1, 2, 1]), split, 3, workers=3)
    for name, array in one._asdict().items():
        assert np.array_equal(getattr(three, name), array), name
