"""The Python API with inputs in memory: the same result as from files, the same type from
collide.scan and collide.read_contacts, and tables for pandas."""
import numpy as np
import pytest
import trimesh
from conftest import REPO

import collide
from collide.errors import InputError, UsageError
from collide.load import load_mesh, load_trajectory
from collide.pipeline import _Progress

FIXTURE = REPO / "examples" / "fixture"


def fixture_in_memory():
    """The bundled fixture scene as arrays: meshes as Trimesh objects and (vertices, faces)
    pairs, the trajectory as a dict of its datasets."""
    import h5py
    meshes = {}
    for k, path in enumerate(sorted((FIXTURE / "meshes").iterdir())):
        mesh = load_mesh(path)
        meshes[path.stem] = (trimesh.Trimesh(mesh.vertices, mesh.faces, process=False) if k % 2
                             else (mesh.vertices, mesh.faces))
    with h5py.File(FIXTURE / "traj.h5", "r") as f:
        trajectory = {"time": f["time"][()], "names": f["objects/name"].asstr()[()],
                      "mesh": [m.split(".")[0] for m in f["objects/mesh"].asstr()[()]],
                      "position": f["poses/position"][()],
                      "orientation": f["poses/orientation"][()], "quaternion_order": "wxyz"}
    return meshes, trajectory


@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_arrays_in_memory_give_the_same_contacts_as_files(mode):
    from_files = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode=mode)
    meshes, trajectory = fixture_in_memory()
    in_memory = collide.scan(meshes, trajectory, mode=mode)
    assert in_memory.object_names == from_files.object_names
    assert in_memory.object_meshes == [m.split(".")[0] for m in from_files.object_meshes]
    for name, column in from_files.contacts.items():
        np.testing.assert_array_equal(in_memory.contacts[name], column, err_msg=name)
    assert in_memory.provenance["inputs"]["trajectory"]["path"] == "<in memory>"
    assert in_memory.provenance["inputs"]["meshes_folder"] == "<in memory>"
    # mixing a folder of meshes with a trajectory in memory works too
    mixed = collide.scan(FIXTURE / "meshes", trajectory, mode=mode)
    np.testing.assert_array_equal(mixed.contacts["t_begin"], from_files.contacts["t_begin"])


def test_scan_and_read_contacts_return_the_same_type_with_dataframes(tmp_path):
    pd = pytest.importorskip("pandas")
    result = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode="discrete", triangle_pairs=True,
                          output=tmp_path / "c.h5")
    back = collide.read_contacts(tmp_path / "c.h5")
    assert type(back) is type(result) is collide.ScanResult
    assert back.object_names == result.object_names and back.mode == "discrete"
    np.testing.assert_array_equal(back.frame_index, result.frame_index)
    for frame in (result.to_dataframe(), back.to_dataframe()):
        assert list(frame.columns[:2]) == ["a", "b"] and len(frame) == result.contacts["t_begin"].size
        names = [tuple(sorted(p)) for p in zip(frame["a"], frame["b"])]
        assert names == [tuple(sorted((result.object_names[a], result.object_names[b])))
                         for a, b in zip(result.contacts["object_a"], result.contacts["object_b"])]
    # with an output file, triangle pairs stream into it (the result does not hold them)
    assert result.triangle_pairs is None
    pairs = back.to_dataframe("triangle-pairs")
    assert isinstance(pairs, pd.DataFrame) and len(pairs) == result.stats["triangle_pairs"] > 0
    np.testing.assert_array_equal(pairs["time"].to_numpy(), back.frame_time[pairs["frame"].to_numpy()])
    assert list(pairs.columns[:4]) == ["a", "b", "time", "frame"]
    none = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode="discrete", ignore="*:*", triangle_pairs=True)
    for table in (none.to_dataframe(), none.to_dataframe("triangle-pairs")):  # empty: the same column types
        assert len(table) == 0 and table["a"].dtype == table["b"].dtype == object
    assert none.to_dataframe("triangle-pairs")["time"].dtype == np.float64
    in_memory = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode="discrete", triangle_pairs=True)
    for name, column in in_memory.triangle_pairs.items():
        np.testing.assert_array_equal(back.triangle_pairs[name], column, err_msg=name)


def test_bad_arrays_are_bad_input_naming_what():
    meshes, trajectory = fixture_in_memory()
    bad = dict(trajectory, orientation=trajectory["orientation"] * 2.0)
    with pytest.raises(InputError, match=r"<trajectory in memory>:poses/orientation: quaternion of norm 2"):
        collide.scan(meshes, bad, mode="discrete")
    with pytest.raises(InputError, match="objects/name"):
        collide.scan(meshes, {k: v for k, v in trajectory.items() if k != "names"}, mode="discrete")
    with pytest.raises(UsageError, match="unknown key"):
        collide.scan(meshes, dict(trajectory, speed=1.0), mode="discrete")
    broken = dict(meshes, peg=(np.zeros((3, 3)), np.array([[0, 1, 5]])))
    with pytest.raises(InputError, match="faces index missing vertices"):
        collide.scan(broken, trajectory, mode="discrete")
    with pytest.raises(UsageError, match="expected a trimesh.Trimesh"):
        collide.scan(dict(meshes, peg="peg"), trajectory, mode="discrete")
    assert load_trajectory(FIXTURE / "traj.h5").names == list(trajectory["names"])


@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_stage_and_progress_callbacks_cover_the_whole_scan(mode):
    """stage() names each stage in order; progress() counts every frame (and step) once."""
    stages, done = [], []
    result = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode=mode, stage=stages.append,
                          progress=lambda d, total: done.append((d, total)))
    assert [s.split(" (")[0] for s in stages] == ["loading inputs", "building BVHs", "preparing kernels", "scanning",
                                                   "contact points"]
    frames = result.frame_index.size
    assert done[-1][0] == done[-1][1] and all(b[0] > a[0] for a, b in zip(done, done[1:]))
    if mode == "discrete":  # frames only: one unit each
        assert done[-1] == (frames, frames)
    else:  # at least one unit per frame, and steps weigh something
        assert done[-1][0] > frames


def test_progress_share_follows_time_not_item_counts():
    """Frames costing 0.1 s and steps 0.3 s each (a fake clock): once both have been
    timed, the share reported done equals the share of the scan's time spent; before
    that, steps weigh the prior STEP_WEIGHT."""
    now = [0.0]
    reports = []
    work = _Progress(40, 39, lambda done, total: reports.append((done, total, now[0])), clock=lambda: now[0])
    for n in (10, 10, 10, 10):
        now[0] += 0.1 * n
        work.frames(n)
    for n in (10, 10, 10, 9):
        now[0] += 0.3 * n
        work.steps(n)
    total_time = 0.1 * 40 + 0.3 * 39
    for done, total, at in reports[:4]:
        assert total == pytest.approx(40 + 39 * _Progress.STEP_WEIGHT)
    for done, total, at in reports[4:]:
        assert done / total == pytest.approx(at / total_time, rel=1e-12)
    assert reports[-1][0] == reports[-1][1]
    assert all(b[0] > a[0] for a, b in zip(reports, reports[1:]))


BAD_OPTIONS = [("time_tol", 0), ("time_tol", -1.0), ("time_tol", float("nan")), ("time_tol", float("inf")),
               ("time_tol", 50), ("time_tol", "1e-3"), ("time_tol", True), ("warn_angle", -5.0),
               ("split", "foo"), ("leaf_size", 0), ("leaf_size", 2.5), ("workers", 0), ("workers", 5000),
               ("workers", "two"), ("workers", True), ("frames", 5), ("frames", [1, 2, 3]),
               ("frames", slice("a", None)), ("max_memory", "lots")]


@pytest.mark.parametrize("name, value", BAD_OPTIONS, ids=[f"{n}={v!r}" for n, v in BAD_OPTIONS])
def test_bad_options_are_usage_errors_naming_the_option(name, value):
    with pytest.raises(UsageError, match=rf"\b{name}\b"):
        collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode="discrete", **{name: value})


def test_numeric_options_of_other_types_give_the_same_result():
    """An int time_tol or leaf size, numpy numbers: the same contacts as Python floats
    (and the same compiled kernels: they are converted first)."""
    base = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", time_tol=0.5, workers=1, leaf_size=4)
    other = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", time_tol=np.float32(0.5),
                         workers=np.int64(1), leaf_size=np.int32(4), warn_angle=90)
    for name, column in base.contacts.items():
        np.testing.assert_array_equal(other.contacts[name], column, err_msg=name)
    parameters = other.provenance["parameters"]
    assert type(parameters["time_tol"]) is float and type(parameters["workers"]) is int


def test_provenance_reads_back_as_the_scan_returned_it(tmp_path):
    out = tmp_path / "c.h5"
    scanned = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode="discrete", output=out)
    read = collide.read_contacts(out)
    assert read.provenance == scanned.provenance
    assert read.provenance["parameters"]["mode"] == "discrete" and read.versions == scanned.versions


def test_a_stop_request_inside_numba_s_error_is_raised_as_itself():
    from collide.pipeline import _stop_requests_unwrapped

    def kernel_interrupted():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as stop:
            raise SystemError("returned a result with an exception set") from stop

    def kernel_failed():
        raise SystemError("something else")
    with pytest.raises(KeyboardInterrupt):
        _stop_requests_unwrapped(kernel_interrupted)()
    with pytest.raises(SystemError, match="something else"):
        _stop_requests_unwrapped(kernel_failed)()


def test_one_pattern_as_text_and_glob_with_meshes_in_memory():
    as_list = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode="discrete", ignore=["*:*"])
    as_text = collide.scan(FIXTURE / "meshes", FIXTURE / "traj.h5", mode="discrete", ignore="*:*")
    assert as_text.stats["filters"] == as_list.stats["filters"] and as_text.contacts["t_begin"].size == 0
    meshes, trajectory = fixture_in_memory()
    with pytest.raises(UsageError, match="glob '[*].stl': chooses files of a meshes folder"):
        collide.scan(meshes, trajectory, mode="discrete", glob="*.stl")
