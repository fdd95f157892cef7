"""The bundled examples behave as examples/make_examples.py describes them."""
import numpy as np
import pytest
from conftest import REPO, run_cli

import collide
from collide import config

EXAMPLES = REPO / "examples"


def test_tunnel_example_is_missed_by_discrete_and_caught_by_continuous():
    meshes, traj = EXAMPLES / "tunnel" / "meshes", EXAMPLES / "tunnel" / "traj.h5"
    assert collide.scan(meshes, traj, mode="discrete").contacts["t_begin"].size == 0
    result = collide.scan(meshes, traj)
    c = result.contacts
    names = [(result.object_names[a], result.object_names[b]) for a, b in zip(c["object_a"], c["object_b"])]
    assert names == [("bullet", "wall")] and c["kind"].tolist() == [1]   # the ball's 0.2 mm near miss is not
    # bullet (r = 2) at x = -35 + 5000 t' (t' = t - 0.04) meets the wall (|x| <= 0.25) for x in [-2.25, 2.25]
    begin, end = 0.04 + 32.75 / 5000, 0.04 + 37.25 / 5000
    tol = 1e-6 * 0.01
    assert c["t_begin"][0] <= begin <= c["t_begin"][0] + tol + 1e-15
    assert c["t_end"][0] >= end >= c["t_end"][0] - tol - 1e-15


def test_fixture_example_contacts():
    result = collide.scan(EXAMPLES / "fixture" / "meshes", EXAMPLES / "fixture" / "traj.h5")
    c = result.contacts
    pairs = {(result.object_names[a], result.object_names[b]) for a, b in zip(c["object_a"], c["object_b"])}
    assert pairs == {("peg_b", "frame"), ("arm", "pillar")}   # peg_a's 1 mm clearance is a near miss
    assert result.object_meshes[:2] == ["peg.ply", "peg.ply"]



@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_fixture_contacts_do_not_depend_on_the_bvh_rule(tmp_path, mode):
    """Every --split finds sah's contacts on the fixture, value for value (lbvh also through
    the command line; continuous mode: sah and lbvh on every 4th frame, to stay quick)."""
    meshes, traj = EXAMPLES / "fixture" / "meshes", EXAMPLES / "fixture" / "traj.h5"
    frames = None if mode == "discrete" else "0:240:4"
    splits = config.SPLIT_RULES if mode == "discrete" else ("sah", "lbvh")
    runs = {split: collide.scan(meshes, traj, mode=mode, split=split, frames=frames, cache=False).contacts
            for split in splits}
    if mode == "discrete":
        proc = run_cli("scan", meshes, traj, "-o", tmp_path / "lbvh.h5", "--mode", mode, "--split", "lbvh",
                       "--no-cache")
        assert proc.returncode == 0, proc.stderr
        runs["lbvh (command line)"] = collide.read_contacts(tmp_path / "lbvh.h5").contacts
    reference = runs.pop("sah")
    assert reference["t_begin"].size == 2
    for split, contacts in runs.items():
        assert sorted(contacts) == sorted(reference), split
        for name, column in reference.items():
            np.testing.assert_array_equal(contacts[name], column, err_msg=f"{split}: {name}")
