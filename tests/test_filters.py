"""Pair filters (--ignore, --only, the trajectory's filters/ignore), static objects named,
mesh selection by --glob, and diff refusing to compare differently filtered scans."""
import fnmatch
import itertools
import json

import h5py
import numpy as np
import pytest
from conftest import identity_quaternions, run_cli, write_box, write_trajectory

import collide
from collide.errors import InputError, UsageError
from collide.filters import build_filters, pair_selected

# --- the filter itself, against fnmatch on every pair --------------------------------------------

def reference_selected(names, ignore, only):
    """Every unordered pair (i, j), i < j, that the patterns select, by brute force."""
    def hit(patterns, a, b):
        return any((fnmatch.fnmatchcase(a, p) and fnmatch.fnmatchcase(b, q)) or
                   (fnmatch.fnmatchcase(b, p) and fnmatch.fnmatchcase(a, q)) for p, q in patterns)
    return {(i, j) for i, j in itertools.combinations(range(len(names)), 2)
            if not hit(ignore, names[i], names[j]) and (not only or hit(only, names[i], names[j]))}


@pytest.mark.parametrize("seed", range(6))
def test_kernel_filter_selects_exactly_the_fnmatch_pairs(seed):
    rng = np.random.default_rng(seed)
    names = [f"{rng.choice(['link', 'tool', 'floor', 'post'])}_{k}" for k in range(int(rng.integers(3, 40)))]
    names = list(dict.fromkeys(names))
    globs = ["link_*", "tool_*", "*", "floor_*", "post_?", "*_1*"]

    def some(k):
        return [(str(rng.choice(globs)), str(rng.choice(globs))) for _ in range(k)]
    # more than 64 patterns exercises the second word of the bit masks
    ignore, only = some(int(rng.integers(0, 70))), some(int(rng.integers(0, 3)))
    ignore = [p for p in ignore if all(any(fnmatch.fnmatchcase(n, g) for n in names) for g in p)]
    only = [p for p in only if all(any(fnmatch.fnmatchcase(n, g) for n in names) for g in p)]
    filters = build_filters(names, [f"{a}:{b}" for a, b in ignore], only)
    kernel = filters.kernel_filter()
    got = {(i, j) for i, j in itertools.combinations(range(len(names)), 2) if pair_selected(kernel, i, j)}
    assert got == reference_selected(names, ignore, only)
    assert got == {(i, j) for i, j in itertools.combinations(range(len(names)), 2) if filters.selected(i, j)}
    # the static passes: per frame, pairs within the static set are dropped; once, only those are kept
    static = rng.random(len(names)) < 0.4
    per_frame, once = filters.kernel_filter(extra_ignore=static), filters.kernel_filter(only_within=static)
    for i, j in itertools.combinations(range(len(names)), 2):
        both = bool(static[i] and static[j])
        assert pair_selected(per_frame, i, j) == ((i, j) in got and not both)
        assert pair_selected(once, i, j) == ((i, j) in got and both)


def test_patterns_that_match_nothing_are_errors():
    names = ["link_0", "link_1", "floor"]
    with pytest.raises(UsageError, match="'lnk_\\*' matches no object"):
        build_filters(names, ["lnk_*:floor"])
    with pytest.raises(UsageError, match="--only"):
        build_filters(names, only=["floor:table"])
    with pytest.raises(InputError, match="filters/ignore"):
        build_filters(names, trajectory_ignore=[("link_0", "wall")], trajectory_path="t.h5")
    with pytest.raises(UsageError, match="expected two name globs"):
        build_filters(names, ["link_0"])
    # a ':' inside a name is written [:]
    assert build_filters(["a:b", "c"], ["a[:]b:c"]).selected(0, 1) is False


# --- scans ----------------------------------------------------------------------------------------

@pytest.fixture
def chain(tmp_path):
    """Three links in a row touching their neighbours at every frame (like a robot's joints),
    a static table the links touch at no frame, a static floor touching the table, and a
    'probe' that passes through link_2 at frames 3-5."""
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    for k in range(3):
        write_box(meshes / f"link_{k}.stl", (1.0, 0.25, 0.25), (k * 1.0, 0.0, 0.0))   # faces touch at x = k + 0.5
    write_box(meshes / "probe.stl", (0.25, 0.25, 0.25))
    write_box(meshes / "table.stl", (4.0, 4.0, 0.5), (0.0, 0.0, -3.0))
    write_box(meshes / "floor.stl", (8.0, 8.0, 0.5), (0.0, 0.0, -3.5))               # touches the table
    n = 9
    pos = np.zeros((n, 4, 3))
    pos[:, 3] = np.stack([np.full(n, 2.0), np.linspace(-2.0, 2.0, n), np.zeros(n)], axis=-1)  # probe along y
    traj = write_trajectory(tmp_path / "traj.h5", np.arange(n) * 0.1, ["link_0", "link_1", "link_2", "probe"],
                            pos, identity_quaternions(n, 4))
    return meshes, traj


def pair_names(result):
    c = result.contacts
    return sorted({tuple(sorted((result.object_names[a], result.object_names[b])))
                   for a, b in zip(c["object_a"], c["object_b"])})


@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_ignore_drops_the_always_touching_pairs_and_their_work(chain, mode):
    meshes, traj = chain
    everything = collide.scan(meshes, traj, mode=mode)
    assert pair_names(everything) == [("floor", "table"), ("link_0", "link_1"), ("link_1", "link_2"),
                                      ("link_2", "probe")]
    filtered = collide.scan(meshes, traj, mode=mode, ignore=["link_*:link_*", "floor:table"])
    assert pair_names(filtered) == [("link_2", "probe")]
    # the probe's interval is the same with or without the filter
    keep = [k for k, (a, b) in enumerate(zip(everything.contacts["object_a"], everything.contacts["object_b"]))
            if {everything.object_names[a], everything.object_names[b]} == {"link_2", "probe"}]
    for column in ("t_begin", "t_end", "tri_a", "tri_b"):
        assert everything.contacts[column][keep].tolist() == filtered.contacts[column].tolist()
    # filtered pairs cost nothing: fewer BVH descents
    assert filtered.stats["work"]["object_pairs"] < everything.stats["work"]["object_pairs"]
    only = collide.scan(meshes, traj, mode=mode, only=["probe:*"])
    assert pair_names(only) == [("link_2", "probe")]
    assert only.stats["filters"] == {"ignore": [], "only": [["*", "probe"]]}


def test_trajectory_filters_travel_with_the_motion_and_the_command_line_adds(chain, tmp_path):
    meshes, traj = chain
    with h5py.File(traj, "r+") as f:
        f.create_dataset("filters/ignore", data=np.array([["link_*", "link_*"]], dtype=object),
                         dtype=h5py.string_dtype())
    result = collide.scan(meshes, traj, mode="discrete")
    assert pair_names(result) == [("floor", "table"), ("link_2", "probe")]
    result = collide.scan(meshes, traj, mode="discrete", ignore=["table:floor"])
    assert pair_names(result) == [("link_2", "probe")]
    assert result.stats["filters"]["ignore"] == [["floor", "table"], ["link_*", "link_*"]]
    # --fail-on-contact follows the filters
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete", "--fail-on-contact",
                   "--ignore", "table:floor", "--ignore", "probe:*")
    assert proc.returncode == 0, proc.stderr
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete", "--fail-on-contact",
                   "--ignore", "table:floor")
    assert proc.returncode == 1, proc.stderr
    # a typo in the trajectory's list is an input error naming the dataset
    with h5py.File(traj, "r+") as f:
        del f["filters/ignore"]
        f.create_dataset("filters/ignore", data=np.array([["lnk_*", "link_*"]], dtype=object),
                         dtype=h5py.string_dtype())
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete")
    assert proc.returncode == 2 and "filters/ignore" in proc.stderr and "lnk_*" in proc.stderr
    assert len(proc.stderr.splitlines()) == 1
    # and validate, which reads the inputs as scan does, says the same
    checked = run_cli("validate", traj, meshes)
    assert checked.returncode == 2 and checked.stderr == proc.stderr and checked.stdout == ""


def test_unmatched_pattern_on_the_command_line_exits_2(chain, tmp_path):
    meshes, traj = chain
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete", "--ignore", "lnik_*:*")
    assert proc.returncode == 2 and "'lnik_*' matches no object" in proc.stderr, proc.stderr
    assert len(proc.stderr.splitlines()) == 1 and not (tmp_path / "c.h5").exists()


def test_static_objects_are_named(chain, tmp_path):
    meshes, traj = chain
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete", "--format", "json")
    assert proc.returncode == 0, proc.stderr
    assert "2 meshes not in the trajectory, static at their mesh coordinates: floor, table" in proc.stderr
    assert json.loads(proc.stdout)["static_objects"] == ["floor", "table"]
    quiet = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete", "-q")
    assert quiet.stderr == ""


def test_glob_chooses_among_mesh_formats(tmp_path):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    write_box(meshes / "link_0.stl")
    write_box(meshes / "link_0.obj")
    write_box(meshes / "post.stl", centre=(0.75, 0, 0))
    traj = write_trajectory(tmp_path / "t.h5", [0.0], ["link_0"], np.zeros((1, 1, 3)), identity_quaternions(1, 1))
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete")
    assert proc.returncode == 2 and "--glob" in proc.stderr, proc.stderr
    result = collide.scan(meshes, traj, mode="discrete", glob="*.stl")
    assert result.object_meshes == ["link_0.stl", "post.stl"] and pair_names(result) == [("link_0", "post")]
    with pytest.raises(InputError, match="no mesh files match"):
        collide.scan(meshes, traj, mode="discrete", glob="*.ply")


def test_diff_refuses_differently_filtered_scans(chain, tmp_path):
    meshes, traj = chain
    for name, extra in (("all.h5", []), ("some.h5", ["--ignore", "link_*:link_*"]),
                        ("again.h5", ["--ignore", "link_*:link_*"])):
        proc = run_cli("scan", meshes, traj, "-o", tmp_path / name, "--mode", "discrete", *extra)
        assert proc.returncode == 0, proc.stderr
    proc = run_cli("diff", tmp_path / "all.h5", tmp_path / "some.h5")
    assert proc.returncode == 2 and "--ignore-filters" in proc.stderr and len(proc.stderr.splitlines()) == 1
    proc = run_cli("diff", tmp_path / "all.h5", tmp_path / "some.h5", "--ignore-filters")
    assert proc.returncode == 1 and "disappeared" in proc.stdout
    proc = run_cli("diff", tmp_path / "some.h5", tmp_path / "again.h5")
    assert proc.returncode == 0, proc.stdout + proc.stderr
