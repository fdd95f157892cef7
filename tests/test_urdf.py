"""collide urdf: link meshes and link poses from a URDF robot and joint positions.

The robot is described once below as plain Python data; the test writes the URDF from
it and computes the expected link poses with its own forward kinematics (numpy:
origin transforms from rpy, Rodrigues rotation about the joint axis, translation along
it), independent of yourdfpy. World vertices (written mesh vertex in the link frame,
moved by the written link pose) must match the URDF geometry placed by that reference.
"""
import fnmatch
import os

import h5py
import numpy as np
import pytest
import trimesh

pytest.importorskip("yourdfpy")

from conftest import run_cli  # noqa: E402

from collide.errors import InputError  # noqa: E402
from collide.load import load_mesh  # noqa: E402
from collide.urdf import glob_escape, urdf_to_scene  # noqa: E402

ROBOT_SIZE = 1.0                 # the robot spans well under a metre
TOL = 1e-6 * ROBOT_SIZE

# link -> [(element kind, geometry, origin xyz, origin rpy)]
LINKS = {
    "base": [("collision", ("box", (0.4, 0.3, 0.1)), (0.0, 0.0, 0.05), (0.0, 0.0, 0.2)),
             ("collision", ("cylinder", 0.03, 0.1), (-0.12, 0.0, 0.15), (0.3, 0.0, 0.0))],
    "shoulder": [("collision", ("cylinder", 0.06, 0.25), (0.0, 0.0, 0.08), (0.1, 0.2, 0.0)),
                 ("visual", ("box", (0.1, 0.12, 0.3)), (0.0, 0.01, 0.12), (0.0, 0.0, 0.4))],
    "slider": [("collision", ("mesh", "meshes/part.stl", (0.5, 2.0, 1.5)), (0.02, -0.03, 0.05),
                (0.5, -0.4, 1.2))],
    "spinner": [("visual", ("sphere", 0.07), (0.05, 0.0, -0.01), (0.0, 0.0, 0.0))],   # visual only
    "flange": [],                                                                      # no geometry
    "tool[1]": [("collision", ("box", (0.05, 0.06, 0.07)), (0.0, 0.0, 0.035), (0.2, 0.1, -0.3))],
    "finger": [("collision", ("box", (0.02, 0.01, 0.08)), (0.0, 0.01, 0.04), (0.0, 0.0, 0.0))],
}
# (name, type, parent, child, origin xyz, origin rpy, axis, mimic (leader, multiplier, offset))
JOINTS = [
    ("j_shoulder", "revolute", "base", "shoulder", (0.05, 0.0, 0.1), (0.3, -0.2, 0.5), (0, 0, 1), None),
    ("j_slide", "prismatic", "shoulder", "slider", (0.0, 0.05, 0.3), (0.0, 0.4, 0.0), (1, 1, 0), None),
    ("j_spin", "continuous", "slider", "spinner", (0.1, 0.0, 0.0), (-0.7, 0.0, 0.3), (0, 0.6, 0.8), None),
    ("j_flange", "fixed", "spinner", "flange", (0.0, 0.0, 0.1), (0.0, 0.0, 1.0), None, None),
    ("j_tool", "fixed", "flange", "tool[1]", (0.02, 0.0, 0.03), (0.5, 0.0, 0.0), None, None),
    ("j_finger", "revolute", "tool[1]", "finger", (0.0, 0.02, 0.07), (0.0, 0.0, 0.0), (1, 0, 0),
     ("j_shoulder", -2.0, 0.1)),
]
MOVABLE = ["j_shoulder", "j_slide", "j_spin"]
WITH_GEOMETRY = ["base", "shoulder", "slider", "spinner", "tool[1]", "finger"]
# each link with geometry and its nearest ancestor with geometry (flange has none)
ADJACENT = [("base", "shoulder"), ("shoulder", "slider"), ("slider", "spinner"),
            ("spinner", "tool[1]"), ("tool[1]", "finger")]
PART = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.05, 0.0], [0.0, 0.0, 0.03], [0.04, 0.03, 0.02]])
PART_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 4], [2, 3, 4], [3, 1, 4]])


# --- the robot as files ---------------------------------------------------------------------------

def _numbers(values):
    return " ".join(repr(float(v)) for v in values)


def _geometry_xml(geometry):
    kind = geometry[0]
    if kind == "box":
        return f'<box size="{_numbers(geometry[1])}"/>'
    if kind == "cylinder":
        return f'<cylinder radius="{geometry[1]!r}" length="{geometry[2]!r}"/>'
    if kind == "sphere":
        return f'<sphere radius="{geometry[1]!r}"/>'
    return f'<mesh filename="{geometry[1]}" scale="{_numbers(geometry[2])}"/>'


def urdf_text():
    lines = ['<?xml version="1.0"?>', '<robot name="testbot">']
    for name, elements in LINKS.items():
        lines.append(f'  <link name="{name}">')
        for kind, geometry, xyz, rpy in elements:
            lines.append(f'    <{kind}><origin xyz="{_numbers(xyz)}" rpy="{_numbers(rpy)}"/>'
                         f'<geometry>{_geometry_xml(geometry)}</geometry></{kind}>')
        lines.append("  </link>")
    for name, kind, parent, child, xyz, rpy, axis, mimic in JOINTS:
        lines.append(f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
                     f'<origin xyz="{_numbers(xyz)}" rpy="{_numbers(rpy)}"/>')
        if axis is not None:
            lines.append(f'    <axis xyz="{_numbers(axis)}"/>')
        if kind in ("revolute", "prismatic"):
            lines.append('    <limit lower="-10" upper="10" effort="1" velocity="1"/>')
        if mimic is not None:
            lines.append(f'    <mimic joint="{mimic[0]}" multiplier="{mimic[1]!r}" offset="{mimic[2]!r}"/>')
        lines.append("  </joint>")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


@pytest.fixture
def robot(tmp_path):
    """The URDF file (with meshes/part.stl beside it)."""
    (tmp_path / "meshes").mkdir()
    trimesh.Trimesh(PART, PART_FACES, process=False).export(tmp_path / "meshes" / "part.stl")
    path = tmp_path / "robot.urdf"
    path.write_text(urdf_text())
    return path


def joint_values(n_frames=5, seed=7):
    """Random joint positions {name: (T,)}: radians, and metres for the prismatic joint."""
    rng = np.random.default_rng(seed)
    return {"j_shoulder": rng.uniform(-1.5, 1.5, n_frames), "j_slide": rng.uniform(-0.1, 0.2, n_frames),
            "j_spin": rng.uniform(-6.0, 6.0, n_frames)}


def write_csv(path, time, values):
    names = list(values)
    rows = [",".join(["time"] + names)]
    for t in range(len(time)):
        rows.append(",".join(repr(float(x)) for x in [time[t]] + [values[n][t] for n in names]))
    path.write_text("\n".join(rows) + "\n")
    return path


def write_joints_h5(path, time, values, unit="s"):
    with h5py.File(path, "w") as f:
        f["time"] = np.asarray(time, dtype=np.float64)
        if unit:
            f["time"].attrs["unit"] = unit
        f.create_dataset("joints/name", data=np.array(list(values), dtype=object), dtype=h5py.string_dtype())
        f["joints/position"] = np.stack([np.asarray(v, np.float64) for v in values.values()], axis=1)
    return path


# --- independent forward kinematics -------------------------------------------------------------------

def rotation_rpy(rpy):
    """URDF rpy: roll about x, then pitch about y, then yaw about z (fixed axes)."""
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def rotation_about(axis, angle):
    """Rodrigues: rotation by ``angle`` about the unit vector along ``axis``."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * skew + (1 - np.cos(angle)) * skew @ skew


def rigid(rotation=np.eye(3), translation=(0.0, 0.0, 0.0)):
    m = np.eye(4)
    m[:3, :3] = rotation
    m[:3, 3] = translation
    return m


def expected_link_poses(q):
    """World pose 4x4 of every link for joint positions ``q`` {movable joint: value}; joints
    not in ``q`` at 0; mimic joints = multiplier * leader + offset. JOINTS is in tree order."""
    world = {"base": np.eye(4)}
    for name, kind, parent, child, xyz, rpy, axis, mimic in JOINTS:
        value = q.get(name, 0.0) if mimic is None else mimic[1] * q.get(mimic[0], 0.0) + mimic[2]
        if kind in ("revolute", "continuous"):
            motion = rigid(rotation_about(axis, value))
        elif kind == "prismatic":
            motion = rigid(translation=value * np.asarray(axis, float) / np.linalg.norm(axis))
        else:
            motion = np.eye(4)
        world[child] = world[parent] @ rigid(rotation_rpy(rpy), xyz) @ motion
    return world


def element_points_ok(local, geometry):
    """Which points (n, 3), given in an element's own frame, lie on the element's surface
    as tessellated (box corners, cylinder rims and cap centres, sphere surface, mesh vertices)."""
    kind = geometry[0]
    if kind == "box":
        return (np.abs(np.abs(local) - np.asarray(geometry[1]) / 2) < TOL).all(axis=1)
    if kind == "cylinder":
        radial = np.hypot(local[:, 0], local[:, 1])
        on_cap = np.abs(np.abs(local[:, 2]) - geometry[2] / 2) < TOL
        return on_cap & ((np.abs(radial - geometry[1]) < TOL) | (radial < TOL))
    if kind == "sphere":
        return np.abs(np.linalg.norm(local, axis=1) - geometry[1]) < TOL
    return nearest_distance(local, part_vertices(geometry)) < TOL


def part_vertices(geometry):
    """The mesh element's vertices, scaled, in the element frame (from the STL as stored: float32)."""
    stored = trimesh.load(geometry[3], process=False)
    return np.asarray(stored.vertices, np.float64) * np.asarray(geometry[2])


def nearest_distance(points, targets):
    return np.linalg.norm(points[:, None, :] - targets[None, :, :], axis=2).min(axis=1)


def check_link_geometry(world_vertices, link_pose, elements, base_dir):
    """Every world vertex lies on one of the link's elements (placed by the reference
    kinematics), and every element is fully present."""
    matched = np.zeros(world_vertices.shape[0], dtype=bool)
    for kind, geometry, xyz, rpy in elements:
        if geometry[0] == "mesh":
            geometry = geometry + (base_dir / geometry[1],)
        frame = link_pose @ rigid(rotation_rpy(rpy), xyz)
        local = (world_vertices - frame[:3, 3]) @ frame[:3, :3]
        ok = element_points_ok(local, geometry)
        matched |= ok
        on = local[ok]
        if geometry[0] == "box":      # all 8 corners
            assert len({tuple(s) for s in np.sign(on).astype(int)}) == 8, (kind, geometry)
        elif geometry[0] == "cylinder":   # both caps, each with a full rim
            for side in (1, -1):
                cap = on[np.sign(on[:, 2]) == side]
                assert np.ptp(cap[:, 0]) > 1.9 * geometry[1] and np.ptp(cap[:, 1]) > 1.9 * geometry[1]
        elif geometry[0] == "sphere":
            assert on.shape[0] >= 100 and (np.ptp(on, axis=0) > 1.9 * geometry[1]).all()
        else:                         # every vertex of the mesh file
            assert (nearest_distance(part_vertices(geometry), on) < TOL).all()
    assert matched.all(), f"{(~matched).sum()} vertices off the link's geometry"


def read_outputs(meshes_dir, trajectory):
    """(time (T,), link names, poses (T, N, 4, 4), {link: vertices (V, 3)}, file attributes)."""
    with h5py.File(trajectory, "r") as f:
        time = f["time"][()]
        names = list(f["objects/name"].asstr()[()])
        stems = list(f["objects/mesh"].asstr()[()]) if "objects/mesh" in f else names
        poses = f["poses/matrix"][()]
        ignore = f["filters/ignore"].asstr()[()] if "filters/ignore" in f else None
    vertices = {name: load_mesh(meshes_dir / f"{stem}.ply").vertices for name, stem in zip(names, stems)}
    return time, names, poses, vertices, ignore


def check_against_reference(meshes_dir, trajectory, values, base_dir, geometry="collision"):
    time, names, poses, vertices, _ = read_outputs(meshes_dir, trajectory)
    assert names == WITH_GEOMETRY
    assert poses.shape == (time.shape[0], len(names), 4, 4)
    for t in range(time.shape[0]):
        expected = expected_link_poses({n: v[t] for n, v in values.items()})
        for i, name in enumerate(names):
            assert np.abs(poses[t, i] - expected[name]).max() < TOL, (t, name)
            world = vertices[name] @ poses[t, i, :3, :3].T + poses[t, i, :3, 3]
            check_link_geometry(world, expected[name], chosen_elements(name, geometry), base_dir)


def chosen_elements(link, geometry):
    elements = LINKS[link]
    chosen = [e for e in elements if e[0] == geometry]
    return chosen or elements


# --- tests --------------------------------------------------------------------------------------------

def test_csv_joints_world_vertices_match_reference_kinematics(robot, tmp_path):
    values = joint_values()
    del values["j_spin"]                      # not listed: stays at 0, with a warning
    time = np.linspace(0.0, 0.4, 5)
    joints = write_csv(tmp_path / "joints.csv", time, values)
    out, meshes = tmp_path / "traj.h5", tmp_path / "robot_meshes"
    proc = run_cli("urdf", robot, joints, "-o", out, "--meshes-out", meshes)
    assert proc.returncode == 0, proc.stderr
    assert "j_spin" in proc.stderr and "stay at 0" in proc.stderr
    assert "spinner" in proc.stderr             # visual-only link: named as using <visual>
    assert "6 link meshes" in proc.stdout and "5 frames" in proc.stdout
    check_against_reference(meshes, out, values, robot.parent)
    with h5py.File(out, "r") as f:
        assert np.array_equal(f["time"][()], time)
        assert f["poses/matrix"].dtype == np.float64
    assert sorted(p.name for p in meshes.iterdir()) == sorted(
        ["base.ply", "shoulder.ply", "slider.ply", "spinner.ply", "tool_1_.ply", "finger.ply"])
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_hdf5_joints_with_mimic_and_fixed_values_ignored(robot, tmp_path):
    values = joint_values(n_frames=4, seed=3)
    time = np.array([0.0, 0.5, 0.75, 2.0])
    listed = dict(values, j_finger=np.full(4, 9.0), j_tool=np.full(4, 1.0))   # ignored: mimic and fixed
    joints = write_joints_h5(tmp_path / "joints.h5", time, listed)
    out, meshes = tmp_path / "traj.h5", tmp_path / "m"
    proc = run_cli("urdf", robot, joints, "-o", out, "--meshes-out", meshes)
    assert proc.returncode == 0, proc.stderr
    assert "j_finger" in proc.stderr and "j_tool" in proc.stderr and "stay at 0" not in proc.stderr
    check_against_reference(meshes, out, values, robot.parent)
    with h5py.File(out, "r") as f:
        assert f["time"].attrs["unit"] == "s"


def test_api_with_in_memory_joints(robot, tmp_path):
    values = joint_values(n_frames=3, seed=11)
    time = np.array([0.0, 1.0, 2.0])
    scene = urdf_to_scene(robot, dict(values, time=time), tmp_path / "m", tmp_path / "traj.h5")
    assert scene.robot == "testbot" and scene.objects == WITH_GEOMETRY and scene.frames == 3
    assert scene.ignore == ADJACENT and scene.joints_at_zero == [] and scene.fallback_links == ["spinner"]
    assert [p.name for p in scene.mesh_files] == [
        "base.ply", "shoulder.ply", "slider.ply", "spinner.ply", "tool_1_.ply", "finger.ply"]
    assert all(p.is_file() for p in scene.mesh_files) and len(list((tmp_path / "m").iterdir())) == 6
    check_against_reference(tmp_path / "m", tmp_path / "traj.h5", values, robot.parent)


def test_geometry_visual_uses_visual_elements(robot, tmp_path):
    values = joint_values(n_frames=2, seed=5)
    scene = urdf_to_scene(robot, dict(values, time=[0.0, 1.0]), tmp_path / "m", tmp_path / "traj.h5",
                          geometry="visual")
    # shoulder has both kinds (visual box here); the collision-only links fall back
    assert scene.fallback_links == ["base", "slider", "tool[1]", "finger"]
    check_against_reference(tmp_path / "m", tmp_path / "traj.h5", values, robot.parent, geometry="visual")


def test_filters_ignore_holds_adjacent_links_as_exact_patterns(robot, tmp_path):
    joints = write_csv(tmp_path / "j.csv", [0.0], {"j_shoulder": [0.1]})
    out = tmp_path / "traj.h5"
    assert run_cli("urdf", robot, joints, "-o", out, "--meshes-out", tmp_path / "m").returncode == 0
    *_, ignore = read_outputs(tmp_path / "m", out)
    assert ignore.shape == (len(ADJACENT), 2)
    assert [tuple(row) for row in ignore] == [(glob_escape(a), glob_escape(b)) for a, b in ADJACENT]
    assert ("spinner", "tool[[]1]") in [tuple(row) for row in ignore]     # through geometry-less flange
    for (a, b), (pattern_a, pattern_b) in zip(ADJACENT, ignore):
        assert [n for n in WITH_GEOMETRY if fnmatch.fnmatchcase(n, pattern_a)] == [a]
        assert [n for n in WITH_GEOMETRY if fnmatch.fnmatchcase(n, pattern_b)] == [b]

    out2 = tmp_path / "traj2.h5"
    proc = run_cli("urdf", robot, joints, "-o", out2, "--meshes-out", tmp_path / "m2", "--no-ignore-adjacent")
    assert proc.returncode == 0, proc.stderr
    with h5py.File(out2, "r") as f:
        assert "filters" not in f


def test_glob_escape():
    for name in ["plain", "a*b", "q?", "x[1]", "[*?]"]:
        pattern = glob_escape(name)
        assert fnmatch.fnmatchcase(name, pattern)
        assert not fnmatch.fnmatchcase(name + "x", pattern) and not fnmatch.fnmatchcase("y" + name, pattern)
    assert glob_escape("tool[1]") == "tool[[]1]" and glob_escape("a*?") == "a[*][?]"
    assert not fnmatch.fnmatchcase("ab", glob_escape("a*"))
    assert not fnmatch.fnmatchcase("x1", glob_escape("x?"))


def test_scan_end_to_end(robot, tmp_path):
    """The shoulder's cylinder dips into the base's box at every frame (by design of the
    robot), so a scan without the ignore list reports that pair over the whole motion,
    and a scan of the default output (adjacent links ignored) does not."""
    values = joint_values(n_frames=4, seed=1)
    time = np.arange(4) * 0.1
    joints = write_csv(tmp_path / "j.csv", time, values)
    found = {}
    for flag, name in (("--ignore-adjacent", "a"), ("--no-ignore-adjacent", "b")):
        proc = run_cli("urdf", robot, joints, "-o", tmp_path / f"{name}.h5", "--meshes-out", tmp_path / name,
                       flag)
        assert proc.returncode == 0, proc.stderr
        proc = run_cli("scan", tmp_path / name, tmp_path / f"{name}.h5", "--mode", "discrete",
                       "-o", tmp_path / f"contacts_{name}.h5")
        assert proc.returncode == 0, proc.stderr
        with h5py.File(tmp_path / f"contacts_{name}.h5", "r") as f:
            objects = list(f["objects/name"].asstr()[()])
            pairs = {(objects[a], objects[b]): (t0, t1) for a, b, t0, t1 in zip(
                f["contacts/object_a"][()], f["contacts/object_b"][()], f["contacts/t_begin"][()],
                f["contacts/t_end"][()])}
        assert sorted(objects) == sorted(WITH_GEOMETRY)
        found[name] = pairs
    assert found["b"][("base", "shoulder")] == (time[0], time[-1])
    assert ("base", "shoulder") not in found["a"] and ("shoulder", "base") not in found["a"]


def test_force_writes_into_a_folder_and_keeps_other_files(robot, tmp_path):
    joints = write_csv(tmp_path / "j.csv", [0.0], {"j_shoulder": [0.0]})
    meshes = tmp_path / "m"
    meshes.mkdir()
    (meshes / "notes.txt").write_text("keep me")
    (meshes / "base.ply").write_text("old")
    proc = run_cli("urdf", robot, joints, "-o", tmp_path / "t.h5", "--meshes-out", meshes)
    assert proc.returncode == 2 and "not empty" in proc.stderr and "--force" in proc.stderr
    assert not (tmp_path / "t.h5").exists() and (meshes / "base.ply").read_text() == "old"
    proc = run_cli("urdf", robot, joints, "-o", tmp_path / "t.h5", "--meshes-out", meshes, "--force")
    assert proc.returncode == 0, proc.stderr
    assert (meshes / "notes.txt").read_text() == "keep me"
    assert load_mesh(meshes / "base.ply").faces.shape[0] > 12
    assert len(list(meshes.glob("*.ply"))) == 6
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


# --- bad input ------------------------------------------------------------------------------------------

def _break(case, robot, tmp_path):
    """Make the inputs for an error case; returns (urdf, joints, text the message must contain)."""
    good = write_csv(tmp_path / "good.csv", [0.0, 0.1], {"j_shoulder": [0.0, 0.1]})
    csv = tmp_path / "bad.csv"
    h5 = tmp_path / "bad.h5"
    if case == "missing urdf":
        return tmp_path / "nope.urdf", good, "nope.urdf: no such file"
    if case == "unparseable urdf":
        robot.write_text(urdf_text()[:300])
        return robot, good, "robot.urdf: not well-formed XML"
    if case == "not a robot":
        robot.write_text("<model name='x'/>")
        return robot, good, "root element is <model>"
    if case == "missing mesh file":
        (robot.parent / "meshes" / "part.stl").unlink()
        return robot, good, "robot.urdf: link 'slider' <collision>: mesh file 'meshes/part.stl' not found"
    if case == "two parents":
        robot.write_text(urdf_text().replace('<child link="spinner"/>', '<child link="shoulder"/>'))
        return robot, good, "link 'shoulder' is the child of two joints"
    if case == "missing joints file":
        return robot, tmp_path / "none.csv", "none.csv: no such file"
    if case == "csv without time":
        csv.write_text("t,j_shoulder\n0,0\n")
        return robot, csv, "bad.csv: no 'time' column"
    if case == "csv time not increasing":
        csv.write_text("time,j_shoulder\n0,0\n0.2,0\n0.1,0\n")
        return robot, csv, "bad.csv:time: not strictly increasing at line 4 (0.2 then 0.1)"
    if case == "csv nan":
        csv.write_text("time,j_shoulder\n0,0\n0.1,nan\n")
        return robot, csv, "bad.csv:j_shoulder: line 3: nan; expected finite numbers"
    if case == "csv ragged":
        csv.write_text("time,j_shoulder\n0,0\n0.1\n")
        return robot, csv, "bad.csv: line 3 has 1 values"
    if case == "unknown joints":
        csv.write_text("time,j_shoulder,j_elbow,wrist\n0,0,0,0\n")
        return robot, csv, "unknown joints 'j_elbow', 'wrist'"
    if case == "hdf5 wrong shape":
        write_joints_h5(h5, [0.0, 1.0], {"j_shoulder": [0.0, 1.0]})
        with h5py.File(h5, "r+") as f:
            del f["joints/position"]
            f["joints/position"] = np.zeros((2, 2))
        return robot, h5, "bad.h5:joints/position: has shape (2, 2)"
    if case == "hdf5 missing time":
        write_joints_h5(h5, [0.0, 1.0], {"j_shoulder": [0.0, 1.0]})
        with h5py.File(h5, "r+") as f:
            del f["time"]
        return robot, h5, "bad.h5:time: missing dataset"
    if case == "hdf5 nan":
        write_joints_h5(h5, [0.0, 1.0], {"j_shoulder": [0.0, np.nan]})
        return robot, h5, "bad.h5:joints/position: non-finite value at index (1, 0)"
    if case == "hdf5 unknown joint":
        write_joints_h5(h5, [0.0], {"elbow": [0.0]})
        return robot, h5, "bad.h5:joints/name: unknown joint 'elbow'"
    raise AssertionError(case)


ERROR_CASES = ["missing urdf", "unparseable urdf", "not a robot", "missing mesh file", "two parents",
               "missing joints file", "csv without time", "csv time not increasing", "csv nan", "csv ragged",
               "unknown joints", "hdf5 wrong shape", "hdf5 missing time", "hdf5 nan", "hdf5 unknown joint"]


@pytest.mark.parametrize("case", ERROR_CASES)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(case, robot, tmp_path):
    urdf, joints, message = _break(case, robot, tmp_path)
    out, meshes = tmp_path / "traj.h5", tmp_path / "out_meshes"
    proc = run_cli("urdf", urdf, joints, "-o", out, "--meshes-out", meshes)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("collide: error: "), proc.stderr
    assert message in lines[0] and "; expected " in lines[0], lines[0]
    assert "Traceback" not in proc.stderr and "SPEC" not in proc.stderr
    assert not out.exists() and not meshes.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


@pytest.mark.parametrize("written", ["trajectory over the joints", "trajectory over the urdf",
                                     "trajectory over a mesh it names", "link mesh over a mesh it names",
                                     "trajectory over a visual mesh", "link mesh over a visual mesh",
                                     "trajectory where a link mesh goes"])
def test_nothing_written_replaces_an_input(written, robot, tmp_path):
    joints = write_csv(tmp_path / "j.csv", [0.0, 0.1], {"j_shoulder": [0.0, 0.1]})
    part = robot.parent / "meshes" / "part.stl"
    before = {p: p.read_bytes() for p in (joints, robot, part)}
    out, meshes, extra = tmp_path / "t.h5", tmp_path / "m", ()
    if written == "trajectory over the joints":
        out = tmp_path / "." / "j.csv"
    elif written == "trajectory over the urdf":
        out = robot
    elif written == "trajectory over a mesh it names":
        out = part
    elif written == "trajectory where a link mesh goes":
        out, meshes = tmp_path / "m" / "base.ply", tmp_path / "m"
        (tmp_path / "m").mkdir()
    else:  # the slider link's mesh would go to meshes/slider.ply: a file the URDF names (as <visual> of
        # the base link, whose <collision> geometry is used, in the visual cases)
        trimesh.Trimesh(PART, PART_FACES, process=False).export(robot.parent / "meshes" / "slider.ply")
        if "visual" in written:
            text = urdf_text().replace('<link name="base">', '<link name="base">\n    <visual><geometry>'
                                       '<mesh filename="meshes/slider.ply"/></geometry></visual>', 1)
        else:
            text = urdf_text().replace("meshes/part.stl", "meshes/slider.ply", 1)
        robot.write_text(text)
        part = robot.parent / "meshes" / "slider.ply"
        before = {p: p.read_bytes() for p in (joints, robot, part)}
        out, meshes, extra = (part, tmp_path / "m", ()) if written.startswith("trajectory") else \
            (tmp_path / "t.h5", robot.parent / "meshes", ("--force",))
    proc = run_cli("urdf", robot, joints, "-o", out, "--meshes-out", meshes, *extra)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    line, = [x for x in proc.stderr.splitlines() if x.startswith("collide: error: ")]  # (and a warning)
    assert ("is an input of this command" in line or "is where link 'base'" in line) and "; expected " in line, line
    assert {p: p.read_bytes() for p in before} == before
    assert not (tmp_path / "t.h5").exists()


def test_bad_in_memory_joints_raise_input_error(robot, tmp_path):
    with pytest.raises(InputError, match=r"<joints>:time: not strictly increasing at index 2"):
        urdf_to_scene(robot, {"time": [0.0, 1.0, 1.0], "j_spin": [0, 0, 0]}, tmp_path / "m",
                      tmp_path / "t.h5")
    with pytest.raises(InputError, match=r"<joints>:j_spin: has 2 values, time 3"):
        urdf_to_scene(robot, {"time": [0.0, 1.0, 2.0], "j_spin": [0, 0]}, tmp_path / "m", tmp_path / "t.h5")
    assert not (tmp_path / "m").exists() and not (tmp_path / "t.h5").exists()


def test_without_yourdfpy_a_usage_error_says_how_to_install(robot, tmp_path):
    stub = tmp_path / "stub"
    stub.mkdir()
    (stub / "yourdfpy.py").write_text("raise ImportError('hidden for this test')\n")
    joints = write_csv(tmp_path / "j.csv", [0.0], {"j_shoulder": [0.0]})
    inherited = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
    env = {"PYTHONPATH": os.pathsep.join([str(stub)] + inherited)}
    proc = run_cli("urdf", robot, joints, "-o", tmp_path / "t.h5", "--meshes-out", tmp_path / "m", env=env)
    assert proc.returncode == 2
    assert proc.stderr.strip() == "collide: error: collide urdf needs the yourdfpy package: " \
                                  "pip install 'collide[urdf]'"
