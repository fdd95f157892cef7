"""Every class of bad input: exit 2, one `collide: error:` line naming the file, no traceback,
no stray temporary file, and an existing output file left byte-identical."""
import h5py
import numpy as np
import pytest
from conftest import identity_quaternions, run_cli, write_box, write_trajectory

N = 4


def good_poses():
    pos = np.zeros((N, 1, 3))
    pos[:, 0, 0] = [3.0, 0.5, 0.0, 3.0]
    return pos, identity_quaternions(N, 1)


def edit(path, fn):
    with h5py.File(path, "r+") as f:
        fn(f)


def replace(name, data, attrs=None):
    def fn(f):
        del f[name]
        f[name] = data
        for k, v in (attrs or {}).items():
            f[name].attrs[k] = v
    return fn


def setup_case(tmp, case):
    """Make a valid scene, then break it as ``case`` says. Returns (meshes, trajectory)."""
    meshes = tmp / "meshes"
    meshes.mkdir()
    write_box(meshes / "a.stl")
    write_box(meshes / "b.obj")
    traj = tmp / "traj.h5"
    pos, quat = good_poses()
    write_trajectory(traj, np.arange(N) * 0.1, ["b"], pos, quat)
    q_bad = quat.copy()
    q_bad[1, 0, 0] = 1.1
    q_nan = quat.copy()
    q_nan[2, 0, 1] = np.nan
    scaled = np.tile(np.eye(4), (N, 1, 1, 1))
    scaled[:, :, 0, 0] = 2.0
    reflected = np.tile(np.eye(4), (N, 1, 1, 1))
    reflected[2, 0, 1, 1] = -1.0  # orthonormal, det -1
    last_row = np.tile(np.eye(4), (N, 1, 1, 1))
    last_row[1, 0, 3, 0] = 0.5
    actions = {
        "missing trajectory": lambda: traj.unlink(),
        "not hdf5": lambda: traj.write_text("time,x,y,z\n0,0,0,0\n"),
        "truncated hdf5": lambda: traj.write_bytes(traj.read_bytes()[:600]),
        "missing time": lambda: edit(traj, lambda f: f.__delitem__("time")),
        "time 2-D": lambda: edit(traj, replace("time", np.zeros((N, 2)))),
        "time NaN": lambda: edit(traj, replace("time", np.array([0, np.nan, 2, 3.0]))),
        "time not increasing": lambda: edit(traj, replace("time", np.array([0, 1, 1, 2.0]))),
        "time empty": lambda: edit(traj, replace("time", np.zeros(0))),
        "missing names": lambda: edit(traj, lambda f: f.__delitem__("objects/name")),
        "missing poses": lambda: edit(traj, lambda f: f.__delitem__("poses")),
        "position wrong shape": lambda: edit(traj, replace("poses/position", np.zeros((N, 1, 2)))),
        "position NaN": lambda: edit(traj, replace("poses/position", np.full((N, 1, 3), np.nan))),
        "orientation NaN": lambda: edit(traj, replace("poses/orientation", q_nan,
                                                      {"quaternion_order": "wxyz"})),
        "missing quaternion_order": lambda: edit(traj, replace("poses/orientation", quat)),
        "unknown quaternion_order": lambda: edit(traj, replace("poses/orientation", quat,
                                                               {"quaternion_order": "zyxw"})),
        "non-unit quaternion": lambda: edit(traj, replace("poses/orientation", q_bad,
                                                          {"quaternion_order": "wxyz"})),
        "non-rigid matrix": lambda: write_trajectory(traj, np.arange(N) * 0.1, ["b"], matrix=scaled),
        "reflecting matrix": lambda: write_trajectory(traj, np.arange(N) * 0.1, ["b"], matrix=reflected),
        "matrix last row": lambda: write_trajectory(traj, np.arange(N) * 0.1, ["b"], matrix=last_row),
        "unknown name": lambda: write_trajectory(traj, np.arange(N) * 0.1, ["zzz"], *good_poses()),
        "duplicate names": lambda: write_trajectory(traj, np.arange(N) * 0.1, ["b", "b"],
                                                    np.zeros((N, 2, 3)), identity_quaternions(N, 2)),
        "mesh list length": lambda: write_trajectory(traj, np.arange(N) * 0.1, ["b"], *good_poses(),
                                                     mesh=["b.obj", "a.stl"]),
        "missing mesh folder": lambda: [p.unlink() for p in meshes.iterdir()] and meshes.rmdir(),
        "empty mesh folder": lambda: [p.unlink() for p in meshes.iterdir()],
        "unreadable mesh": lambda: (meshes / "a.stl").write_bytes(b"solid x\n garbage \x00\x01\x02"),
        "mesh without triangles": lambda: ((meshes / "a.stl").unlink(),
                                           (meshes / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")),
        "mesh with NaN vertex": lambda: (meshes / "b.obj").write_text(
            "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n"),
        "duplicate stems": lambda: write_box(meshes / "a.ply"),
    }
    if case == "missing mesh folder":
        for p in meshes.iterdir():
            p.unlink()
        meshes.rmdir()
    else:
        actions[case]()
    return meshes, traj


CASES = ["missing trajectory", "not hdf5", "truncated hdf5", "missing time", "time 2-D", "time NaN",
         "time not increasing", "time empty", "missing names", "missing poses", "position wrong shape",
         "position NaN", "orientation NaN", "missing quaternion_order", "unknown quaternion_order",
         "non-unit quaternion", "non-rigid matrix", "reflecting matrix", "matrix last row", "unknown name",
         "duplicate names", "mesh list length", "missing mesh folder", "empty mesh folder", "unreadable mesh",
         "mesh without triangles", "mesh with NaN vertex", "duplicate stems"]


@pytest.mark.parametrize("case", CASES)
def test_bad_input_exit_2_one_line_no_damage(tmp_path, case):
    meshes, traj = setup_case(tmp_path, case)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    output = out_dir / "contacts.h5"
    output.write_bytes(b"previous result, must survive")
    before = sorted(p.name for p in out_dir.iterdir())
    proc = run_cli("scan", meshes, traj, "-o", output, "--mode", "discrete")
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("collide: error: "), proc.stderr
    assert "Traceback" not in proc.stderr and proc.stdout == ""
    assert "expected" in lines[0]
    assert str(traj) in lines[0] or str(meshes) in lines[0]
    assert output.read_bytes() == b"previous result, must survive"
    assert sorted(p.name for p in out_dir.iterdir()) == before
    # validate reports the same problem
    check = run_cli("validate", traj, meshes)
    assert check.returncode == 2 and check.stderr.strip() == lines[0]


def test_near_unit_quaternions_are_normalised_with_a_warning(tmp_path):
    meshes, traj = setup_case(tmp_path, "time empty")  # replaced below
    pos, quat = good_poses()
    quat[:, 0, 0] = 1.0005
    write_trajectory(traj, np.arange(N) * 0.1, ["b"], pos, quat)
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete")
    assert proc.returncode == 0, proc.stderr
    assert "normalising quaternions" in proc.stderr
