"""FCL's own mesh-mesh test, redone: rob.obj under random rigid poses against a static env.obj.

The reference is brute force: every one of the 2180 x 216 triangle pairs, tested with the
exact predicate (itself checked against exact rational arithmetic in test_predicates.py).
collide must list exactly the same intersecting pairs at every frame, for every split rule.
"""
import numpy as np
import pytest
from conftest import DATA, write_trajectory
from fcl_poses import fcl_model, fcl_poses
from numba import njit

import collide
from collide import config
from collide.load import load_mesh
from collide.packed import world_vertices
from collide.predicates import triangles_intersect

N_POSES = 40


def fcl_like_matrices(n, seed=2026):
    """(n, 1, 4, 4) pose matrices of FCL's test distribution."""
    rotation, translation = fcl_poses(n, seed)
    matrix = np.zeros((n, 1, 4, 4))
    matrix[:, 0, :3, :3] = rotation
    matrix[:, 0, :3, 3] = translation
    matrix[:, 0, 3, 3] = 1.0
    return matrix


@njit(cache=True)
def brute_force_pairs(va, fa, vb, fb):
    """All intersecting (i, j) over every triangle pair, in (i, j) order."""
    out = []
    for i in range(fa.shape[0]):
        p = va[fa[i]]
        for j in range(fb.shape[0]):
            if triangles_intersect(p, vb[fb[j]]):
                out.append((i, j))
    return out


@pytest.fixture(scope="module")
def envrob(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("envrob")
    meshes = tmp / "meshes"
    meshes.mkdir()
    for name in ("env.obj", "rob.obj"):
        (meshes / name).write_bytes((DATA / name).read_bytes())
    matrix = fcl_like_matrices(N_POSES)
    traj = write_trajectory(tmp / "traj.h5", np.arange(N_POSES, dtype=float), ["rob"], matrix=matrix)
    env, rob = load_mesh(meshes / "env.obj"), load_mesh(meshes / "rob.obj")
    reference = {}
    for f in range(N_POSES):
        rob_world = world_vertices(rob.vertices, matrix[f, 0, :3, :])
        for i, j in brute_force_pairs(env.vertices, env.faces, rob_world, rob.faces):
            reference[(f, j, i)] = True   # rob is object 0 (listed), env object 1 (static)
    return meshes, traj, sorted(reference)


@pytest.mark.parametrize("split", config.SPLIT_RULES)
def test_pairs_equal_brute_force_at_every_frame(envrob, split):
    meshes, traj, reference = envrob
    result = collide.scan(meshes, traj, mode="discrete", triangle_pairs=True, split=split)
    assert result.object_names == ["rob", "env"]
    p = result.triangle_pairs
    assert set(p["object_a"].tolist()) <= {0} and set(p["object_b"].tolist()) <= {1}
    got = list(zip(p["frame"].tolist(), p["tri_a"].tolist(), p["tri_b"].tolist()))
    assert len(reference) > 1000                 # the poses do collide, a lot
    assert got == reference                      # same pairs, same (sorted) order
    frames_with_contact = sorted({f for f, _, _ in reference})
    c = result.contacts
    covered = sorted({f for b, e in zip(c["frame_begin"], c["frame_end"]) for f in range(b, e + 1)})
    assert covered == frames_with_contact


@pytest.mark.parametrize("leaf_size", [1, 3, 16])
def test_leaf_size_does_not_change_pairs(envrob, leaf_size):
    meshes, traj, reference = envrob
    p = collide.scan(meshes, traj, mode="discrete", triangle_pairs=True, frames="0:10",
                     leaf_size=leaf_size).triangle_pairs
    got = list(zip(p["frame"].tolist(), p["tri_a"].tolist(), p["tri_b"].tolist()))
    assert got == [r for r in reference if r[0] < 10]


def test_peer_fcl_agrees_on_colliding_frames(envrob):
    """python-fcl (a peer) agrees on which poses collide; it is only used as a sanity check."""
    fcl = pytest.importorskip("fcl")
    meshes, traj, reference = envrob
    env, rob = load_mesh(meshes / "env.obj"), load_mesh(meshes / "rob.obj")

    env_obj = fcl.CollisionObject(fcl_model(fcl, env), fcl.Transform())
    matrix = fcl_like_matrices(N_POSES)
    colliding = []
    for f in range(N_POSES):
        rob_obj = fcl.CollisionObject(fcl_model(fcl, rob), fcl.Transform(matrix[f, 0, :3, :3], matrix[f, 0, :3, 3]))
        if fcl.collide(env_obj, rob_obj, fcl.CollisionRequest(), fcl.CollisionResult()):
            colliding.append(f)
    assert colliding == sorted({f for f, _, _ in reference})


def test_contact_rows_do_not_depend_on_split_or_triangle_pairs(envrob):
    """Contacts name the smallest intersecting pair at their first frame, whether the scan
    enumerated every pair (--triangle-pairs) or stopped at the first one found."""
    meshes, traj, reference = envrob
    # consecutive poses are unrelated random draws: continuous steps between them are wild
    # (turns near half a turn), so the continuous runs look at the first few only
    runs = [collide.scan(meshes, traj, mode=mode, split=split, triangle_pairs=pairs,
                         frames=None if mode == "discrete" else "0:6").contacts
            for mode in ("discrete", "continuous") for split in ("sah", "mean", "lbvh") for pairs in (True, False)]
    for run in runs[1:6]:
        assert all(np.array_equal(runs[0][k], run[k], equal_nan=True) for k in runs[0])
    for run in runs[7:]:
        assert all(np.array_equal(runs[6][k], run[k], equal_nan=True) for k in runs[6])
    smallest = {}
    for f, ta, tb in reference:
        smallest.setdefault(f, (ta, tb))
    c = runs[0]
    assert [smallest[f] for f in c["frame_begin"]] == list(zip(c["tri_a"].tolist(), c["tri_b"].tolist()))
