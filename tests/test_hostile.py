"""Hostile inputs, in process (fast): generated trajectories, contacts files and output
paths. Whatever the input, collide either works or raises InputError -- never another
exception, a numpy warning, a read outside the file, or an oversized allocation.
The command-line side (exit codes, signals, full disk) is in test_hostile_cli.py."""
import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import warnings

import h5py
import numba
import numpy as np
import pytest
from conftest import identity_quaternions, write_box, write_trajectory
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import collide
from collide import config, output, pipeline
from collide.errors import InputError, Terminated, escape_text, stop_request
from collide.files import parse_size
from collide.load import load_scene, load_trajectory

#: examples per property test: few by default (fast); HOSTILE_EXAMPLES=2000 for a deep run
FAST = settings(max_examples=int(os.environ.get("HOSTILE_EXAMPLES", 25)), deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


def _scene(folder, n_frames=4, position=None, mesh_writer=write_box):
    """meshes/a.stl (static) and meshes/b.stl moving along x; returns (meshes, traj)."""
    meshes = folder / "meshes"
    meshes.mkdir(exist_ok=True)
    mesh_writer(meshes / "a.stl")
    mesh_writer(meshes / "b.stl")
    if position is None:
        position = np.zeros((n_frames, 1, 3))
        position[:, 0, 0] = np.linspace(3.0, 0.0, n_frames)
    traj = write_trajectory(folder / "traj.h5", np.arange(position.shape[0]) * 0.1, ["b"], position,
                            identity_quaternions(position.shape[0], 1))
    return meshes, traj


@pytest.fixture(scope="module")
def contacts_file(tmp_path_factory):
    """A valid contacts file with a contact, triangle pairs and two objects."""
    folder = tmp_path_factory.mktemp("contacts")
    meshes, traj = _scene(folder)
    out = folder / "c.h5"
    collide.scan(meshes, traj, mode="discrete", triangle_pairs=True, output=out)
    cf = collide.read_contacts(out)
    assert cf.contacts["t_begin"].size == 1 and cf.triangle_pairs["frame"].size > 0
    return out


def _no_warnings():
    """A context in which any Python warning (numpy RuntimeWarning included) is an error."""
    catcher = warnings.catch_warnings()
    catcher.__enter__()
    warnings.simplefilter("error")
    return catcher


# --- 1, 3: where an output may go ---------------------------------------------------------

def test_output_that_is_an_input_is_refused_whatever_the_spelling(tmp_path):
    meshes, traj = _scene(tmp_path)
    os.link(traj, tmp_path / "hard.h5")
    (tmp_path / "soft.h5").symlink_to(traj)
    inputs = [traj, meshes / "a.stl", meshes / "b.stl"]
    for spelling in (traj, meshes / ".." / "traj.h5", meshes / "a.stl", tmp_path / "hard.h5",
                     tmp_path / "soft.h5", meshes / "." / "b.stl"):
        with pytest.raises(InputError, match="is an input of this command"):
            output.check_output_path(spelling, inputs)
    assert output.check_output_path(tmp_path / "new.h5", inputs) == tmp_path / "new.h5"
    assert output.check_output_path(meshes / "new.h5", inputs) == meshes / "new.h5"


def test_scan_never_writes_over_an_input(tmp_path):
    meshes, traj = _scene(tmp_path)
    before = {p: p.read_bytes() for p in [traj, *meshes.iterdir()]}
    for target in (traj, meshes / ".." / "traj.h5", meshes / "a.stl"):
        with pytest.raises(InputError, match="input"):
            collide.scan(meshes, traj, mode="discrete", output=target)
    assert {p: p.read_bytes() for p in before} == before
    assert [p.name for p in tmp_path.rglob(".*.tmp")] == []


def test_only_regular_files_are_replaced(tmp_path):
    """(Checks only: nothing is written, so aiming at /dev/null is harmless here.)"""
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "folder").mkdir()
    for target, problem in ((tmp_path / "fifo", "FIFO"), ("/dev/null", "character device"),
                            (tmp_path / "folder", "is a folder")):
        with pytest.raises(InputError, match=problem):
            output.check_output_path(target)
    (tmp_path / "to_null").symlink_to("/dev/null")
    with pytest.raises(InputError, match="character device"):
        output.check_output_path(tmp_path / "to_null")


def test_a_symlinked_output_is_written_through_the_link(tmp_path):
    (tmp_path / "real.bin").write_bytes(b"old")
    (tmp_path / "link.bin").symlink_to("real.bin")
    output.write_bytes_atomic(tmp_path / "link.bin", b"new")
    assert (tmp_path / "link.bin").is_symlink() and (tmp_path / "real.bin").read_bytes() == b"new"


# --- 2: a write that fails part way -----------------------------------------------------

@FAST
@given(fail_after=st.integers(0, 40_000), errno_code=st.sampled_from([errno.ENOSPC, errno.EFBIG, errno.EIO]))
def test_hdf5_write_failing_anywhere_is_a_clean_error(tmp_path, monkeypatch, fail_after, errno_code):
    """Whatever byte the disk fills at, the write ends in one InputError: the old file
    stays, no temporary file is left, and HDF5 never sees the failure (no crash)."""
    folder = tmp_path / f"w{fail_after}-{errno_code}"
    folder.mkdir()
    target = folder / "out.h5"
    target.write_bytes(b"old")
    budget = {"left": fail_after}
    real_pwrite = os.pwrite

    def pwrite(fd, data, offset):
        size = len(memoryview(data).cast("B"))
        if size > budget["left"]:
            raise OSError(errno_code, os.strerror(errno_code))
        budget["left"] -= size
        return real_pwrite(fd, data, offset)

    monkeypatch.setattr(os, "pwrite", pwrite)
    with pytest.raises(InputError, match="cannot write"):
        with output.atomic_hdf5(target) as h5:
            h5["big"] = np.arange(5000, dtype=np.float64)
            h5.create_group("g").attrs["x"] = "y"
    monkeypatch.setattr(os, "pwrite", real_pwrite)
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in folder.iterdir()) == ["out.h5"]


def test_hdf5_written_through_the_sink_reads_back(tmp_path):
    with output.atomic_hdf5(tmp_path / "ok.h5") as h5:
        h5["x"] = np.arange(100_000)
        grow = h5.create_dataset("grow", shape=(0,), maxshape=(None,), chunks=(64,), dtype="i8")
        for _ in range(50):
            grow.resize((grow.shape[0] + 1000,))
            grow[-1000:] = np.arange(1000)
    with h5py.File(tmp_path / "ok.h5", "r") as f:
        assert f["x"][-1] == 99_999 and f["grow"].shape == (50_000,) and f["grow"][-1] == 999


def test_dev_full_gives_no_space_left(tmp_path):
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    fd = os.open("/dev/full", os.O_RDWR)
    try:
        sink = output._FileSink(fd)
        with h5py.File(sink, "w") as h5:
            h5["x"] = np.arange(10_000)
        assert sink.error is not None and sink.error.errno == errno.ENOSPC
    finally:
        os.close(fd)


# --- 5: temporary files of killed runs ------------------------------------------------------

def _dead_pid():
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_stale_temporary_files_of_dead_runs_are_removed_live_ones_kept(tmp_path):
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        dead_name = f".c.h5.{output.HOST_TAG}-{_dead_pid()}.abcd1234.tmp"
        live_name = f".c.h5.{output.HOST_TAG}-{live.pid}.abcd1234.tmp"
        other_host = f".c.h5.00000000-{_dead_pid()}.abcd1234.tmp"
        unrelated = ".c.h5.notours.tmp"
        for name in (dead_name, live_name, other_host, unrelated):
            (tmp_path / name).write_bytes(b"partial")
        output.write_bytes_atomic(tmp_path / "x.bin", b"data")
        left = sorted(p.name for p in tmp_path.iterdir())
        assert left == sorted([live_name, other_host, unrelated, "x.bin"])
    finally:
        live.kill()
        live.wait()


def test_temporary_file_names_carry_host_and_pid(tmp_path):
    seen = []
    with output.atomic_path(tmp_path / "r.h5") as tmp:
        seen.append(tmp.name)
        tmp.write_bytes(b"x")
    match = output._TEMPORARY.match(seen[0])
    assert match and match["host"] == output.HOST_TAG and int(match["pid"]) == os.getpid()


# --- 4: trajectories that reach outside themselves ----------------------------------------

def _external_variants(folder, traj):
    """{name: path} of copies of ``traj`` whose data lives (partly) in other files."""
    with h5py.File(traj, "r") as f:
        position = f["poses/position"][()]
        time = f["time"][()]
    with h5py.File(folder / "elsewhere.h5", "w") as g:
        g["p"] = position
    variants = {}

    def variant(name, edit):
        path = folder / f"{name}.h5"
        shutil.copy(traj, path)
        with h5py.File(path, "r+") as f:
            edit(f)
        variants[name] = path

    def external_link(f):
        del f["poses/position"]
        f["poses/position"] = h5py.ExternalLink("elsewhere.h5", "/p")

    def external_group(f):
        f["outside"] = h5py.ExternalLink("elsewhere.h5", "/")
        del f["poses/position"]
        f["poses/position"] = h5py.SoftLink("/outside/p")

    def external_storage(f):
        del f["time"]
        f.create_dataset("time", shape=time.shape, dtype="f8", external=[("/etc/hostname", 0, time.size * 8)])

    def virtual(f):
        del f["poses/position"]
        layout = h5py.VirtualLayout(shape=position.shape, dtype="f8")
        layout[...] = h5py.VirtualSource("missing.h5", "p", shape=position.shape)
        f["poses"].create_virtual_dataset("position", layout, fillvalue=0.0)

    for name, edit in (("external_link", external_link), ("external_group", external_group),
                       ("external_storage", external_storage), ("virtual", virtual)):
        variant(name, edit)
    return variants


def test_data_outside_the_trajectory_is_refused_unless_allowed(tmp_path):
    meshes, traj = _scene(tmp_path)
    for name, path in _external_variants(tmp_path, traj).items():
        dataset = "time" if name == "external_storage" else "poses/position"
        with pytest.raises(InputError) as info:
            load_trajectory(path)
        assert f"{path}:{dataset}:" in str(info.value) and "--allow-external-data" in str(info.value), name
        if name in ("external_link", "external_group", "virtual"):
            load_scene(meshes, path, allow_external=True)  # the user's explicit choice


def test_soft_links_inside_the_file_are_followed_and_loops_refused(tmp_path):
    _, traj = _scene(tmp_path)
    with h5py.File(traj, "r+") as f:
        f.move("time", "real/time")
        f["time"] = h5py.SoftLink("real/time")
    assert load_trajectory(traj).time.shape == (4,)
    with h5py.File(traj, "r+") as f:
        del f["time"]
        f["time"] = h5py.SoftLink("/loop")
        f["loop"] = h5py.SoftLink("/time")
    with pytest.raises(InputError, match="soft links nest"):
        load_trajectory(traj)


def test_fifo_inputs_are_refused_without_blocking(tmp_path):
    meshes, traj = _scene(tmp_path)
    os.mkfifo(tmp_path / "pipe.h5")
    with pytest.raises(InputError, match="FIFO"):
        load_trajectory(tmp_path / "pipe.h5")
    with pytest.raises(InputError, match="FIFO"):
        collide.read_contacts(tmp_path / "pipe.h5")
    os.mkfifo(meshes / "c.stl")
    with pytest.raises(InputError, match=r"c\.stl: is a FIFO"):
        load_scene(meshes, traj)


def test_external_storage_on_a_fifo_is_refused_without_blocking(tmp_path):
    _, traj = _scene(tmp_path)
    os.mkfifo(tmp_path / "pipe")
    with h5py.File(traj, "r+") as f:
        del f["time"]
        f.create_dataset("time", shape=(4,), dtype="f8", external=[(str(tmp_path / "pipe"), 0, 32)])
    with pytest.raises(InputError, match="external storage"):
        load_trajectory(traj)


def test_mesh_assets_outside_the_meshes_folder_are_not_read(tmp_path):
    """A GLTF's buffer is read only from inside the meshes folder."""
    import trimesh
    meshes, traj = _scene(tmp_path)
    files = trimesh.creation.box().export(file_type="gltf")
    document = json.loads(files["model.gltf"])
    for k, buffer in enumerate(document["buffers"]):
        (tmp_path / f"outside{k}.bin").write_bytes(files[buffer["uri"]])
        buffer["uri"] = f"../outside{k}.bin"
    (meshes / "c.gltf").write_text(json.dumps(document))
    with pytest.raises(InputError, match=r"c\.gltf: cannot load mesh"):
        load_scene(meshes, traj)
    for k, buffer in enumerate(document["buffers"]):
        (meshes / f"inside{k}.bin").write_bytes((tmp_path / f"outside{k}.bin").read_bytes())
        buffer["uri"] = f"inside{k}.bin"
    (meshes / "c.gltf").write_text(json.dumps(document))
    assert load_scene(meshes, traj).names == ["b", "a", "c"]


def test_symlinked_mesh_files_are_followed(tmp_path):
    meshes, traj = _scene(tmp_path)
    write_box(tmp_path / "library_box.stl")
    (meshes / "c.stl").symlink_to(tmp_path / "library_box.stl")
    assert load_scene(meshes, traj).names == ["b", "a", "c"]
    (meshes / "d.stl").symlink_to(tmp_path / "missing.stl")
    with pytest.raises(InputError, match="dangling symbolic link"):
        load_scene(meshes, traj)


def test_external_link_in_a_contacts_file_is_refused(tmp_path, contacts_file):
    copy = tmp_path / "c.h5"
    shutil.copy(contacts_file, copy)
    with h5py.File(tmp_path / "other.h5", "w") as g:
        g["t"] = np.zeros(1)
    with h5py.File(copy, "r+") as f:
        del f["contacts/t_begin"]
        f["contacts/t_begin"] = h5py.ExternalLink("other.h5", "/t")
    with pytest.raises(InputError, match="contacts/t_begin: is an external link"):
        collide.read_contacts(copy)


# --- 6: declared shapes far beyond memory -------------------------------------------------

@FAST
@given(frames=st.integers(1, 10**12), objects=st.integers(1, 10**10), matrix=st.booleans())
def test_declared_shapes_are_checked_before_reading(tmp_path_factory, frames, objects, matrix):
    """Chunked, unwritten datasets of any declared size: refused by shape or by memory
    estimate (never read, never a MemoryError)."""
    path = tmp_path_factory.mktemp("big") / "t.h5"
    with h5py.File(path, "w") as f:
        f.create_dataset("time", shape=(frames,), chunks=(min(frames, 1024),), dtype="f8")
        f.create_dataset("objects/name", shape=(objects,), chunks=(min(objects, 1024),),
                         dtype=h5py.string_dtype())
        if matrix:
            f.create_dataset("poses/matrix", shape=(frames, objects, 4, 4), chunks=(1, 1, 4, 4), dtype="f8")
        else:
            f.create_dataset("poses/position", shape=(frames, objects, 3), chunks=(1, 1, 3), dtype="f8")
            f.create_dataset("poses/orientation", shape=(frames, objects, 4), chunks=(1, 1, 4), dtype="f8")
            f["poses/orientation"].attrs["quaternion_order"] = "wxyz"
    needed = frames * objects * config.POSE_BYTES
    limit = 64 * 2**20
    assume(needed > limit)
    with pytest.raises(InputError, match="needs about .* of memory, more than the limit"):
        load_trajectory(path, max_memory=limit)


def test_huge_contacts_column_is_refused_before_reading(tmp_path, contacts_file):
    copy = tmp_path / "c.h5"
    shutil.copy(contacts_file, copy)
    with h5py.File(copy, "r+") as f:
        for name in list(f["contacts"]):
            dtype = f["contacts"][name].dtype
            del f["contacts"][name]
            f["contacts"].create_dataset(name, shape=(10**11,), chunks=(10**5,), dtype=dtype)
    with pytest.raises(InputError, match="more than the limit"):
        collide.read_contacts(copy, max_memory="1G")


@given(value=st.floats(1, 2**40), unit=st.sampled_from(["", "K", "M", "G", "T", "k", "g"]),
       suffix=st.sampled_from(["", "B", "iB"]))
@settings(max_examples=30, deadline=None)
def test_sizes_parse_as_powers_of_1024(value, unit, suffix):
    text = f"{value!r}{unit}{suffix if unit else ''}"
    factor = {"": 1, "k": 1024, "m": 1024**2, "g": 1024**3, "t": 1024**4}[unit.lower()]
    assume(value * factor < 2**62)
    assert parse_size(text) == int(value * factor)


@pytest.mark.parametrize("text", ["", "G", "-1G", "0", "1X", "nan", "inf", "1e30T", "4 G B"])
def test_bad_sizes_are_refused(text):
    with pytest.raises(ValueError):
        parse_size(text)


# --- 7: coordinates that would overflow ---------------------------------------------------------

def _obj_triangle(path, scale):
    path.write_text(f"v {scale!r} 0 0\nv 0 {scale!r} 0\nv 0 0 {scale!r}\nf 1 2 3\n")


@FAST
@given(position_exp=st.floats(0, 308), mesh_exp=st.floats(-5, 308), sign=st.sampled_from([-1.0, 1.0]))
def test_coordinates_beyond_the_limit_are_refused(tmp_path_factory, position_exp, mesh_exp, sign):
    """Either the scene loads and every world coordinate stays within the limit, or it is
    an InputError; no numpy warning either way."""
    folder = tmp_path_factory.mktemp("far")
    meshes = folder / "meshes"
    meshes.mkdir()
    _obj_triangle(meshes / "a.obj", 10.0 ** mesh_exp)
    _obj_triangle(meshes / "b.obj", 1.0)
    position = np.zeros((2, 1, 3))
    position[1, 0, 0] = sign * 10.0 ** position_exp
    traj = write_trajectory(folder / "t.h5", [0.0, 1.0], ["a"], position, identity_quaternions(2, 1))
    catcher = _no_warnings()
    try:
        scene = load_scene(meshes, traj)
    except InputError as exc:
        assert f"{config.MAX_COORDINATE:g}" in str(exc)
        assert 10.0 ** position_exp + 10.0 ** mesh_exp > config.MAX_COORDINATE * (1 - 1e-12)
        return
    finally:
        catcher.__exit__(None, None, None)
    poses = scene.poses.read(0, scene.poses.n_frames)
    world = np.einsum("tnij,vj->tnvi", poses[:, :1, :, :3], scene.meshes[0].vertices) + poses[:, :1, None, :, 3]
    assert np.abs(world).max() <= config.MAX_COORDINATE


def test_objects_1e200_apart_are_refused_not_reported_in_contact(tmp_path):
    meshes, traj = _scene(tmp_path, position=np.full((3, 1, 3), 1e200))
    expected = "poses/position: position at frame 0, object 0 lies 1.73e\\+200 from the origin"
    with pytest.raises(InputError, match=expected):
        collide.scan(meshes, traj, mode="discrete")


# --- 8: damaged contacts files ---------------------------------------------------------------

COLUMN_CASES = [("contacts", "object_a"), ("contacts", "object_b"), ("contacts", "tri_a"), ("contacts", "tri_b"),
                ("contacts", "frame_begin"), ("contacts", "frame_end"), ("contacts", "kind"),
                ("triangle_pairs", "frame"), ("triangle_pairs", "object_a"), ("triangle_pairs", "object_b"),
                ("triangle_pairs", "tri_a"), ("triangle_pairs", "tri_b")]


@FAST
@given(case=st.sampled_from(COLUMN_CASES),
       value=st.one_of(st.integers(-2**62, -1), st.integers(12, 2**62), st.sampled_from([-1, 2**31, 2**40])))
def test_indices_out_of_range_are_bad_input(tmp_path_factory, contacts_file, case, value):
    group, column = case
    copy = tmp_path_factory.mktemp("idx") / "c.h5"
    shutil.copy(contacts_file, copy)
    with h5py.File(copy, "r+") as f:
        data = f[f"{group}/{column}"][()].astype(np.int64)
        data[0] = value
        del f[f"{group}/{column}"]
        f[f"{group}/{column}"] = data
    with pytest.raises(InputError, match=f"{group}/"):
        collide.read_contacts(copy)


@pytest.mark.parametrize("column", ["t_begin", "t_end"])
@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite_times_are_bad_input(tmp_path, contacts_file, column, value):
    copy = tmp_path / "c.h5"
    shutil.copy(contacts_file, copy)
    with h5py.File(copy, "r+") as f:
        f[f"contacts/{column}"][0] = value
        f["frames/time"][0] = 0.0
    with pytest.raises(InputError, match="non-finite"):
        collide.read_contacts(copy)


@FAST
@given(data=st.data())
def test_corrupted_contacts_files_are_bad_input_or_valid(tmp_path_factory, contacts_file, data):
    """Overwrite random bytes of a valid file: read_contacts returns a Contacts or raises
    InputError, nothing else (no RuntimeError from h5py, no IndexError later)."""
    raw = bytearray(contacts_file.read_bytes())
    for _ in range(data.draw(st.integers(1, 8))):
        start = data.draw(st.integers(0, len(raw) - 1))
        chunk = data.draw(st.binary(min_size=1, max_size=16))
        raw[start:start + len(chunk)] = chunk
    copy = tmp_path_factory.mktemp("corrupt") / "c.h5"
    copy.write_bytes(bytes(raw[:len(contacts_file.read_bytes())]))
    catcher = _no_warnings()
    try:
        cf = collide.read_contacts(copy)
    except InputError:
        return
    finally:
        catcher.__exit__(None, None, None)
    from collide.report import contact_rows, triangle_pair_rows
    rows = list(contact_rows(cf)) + list(triangle_pair_rows(cf) if cf.triangle_pairs is not None else [])
    assert all(isinstance(r["a"], str) for r in rows)


# --- mutated trajectories ------------------------------------------------------------------------

DATASETS = ["time", "objects/name", "poses/position", "poses/orientation"]
DTYPES = ["f2", "f4", "f8", "i1", "u8", "c16", "?", "S4", "V8", "O"]


@st.composite
def _dataset_mutation(draw):
    name = draw(st.sampled_from(DATASETS))
    shape = tuple(draw(st.lists(st.integers(0, 5), max_size=4)))
    dtype = draw(st.sampled_from(DTYPES))
    special = draw(st.sampled_from([None, np.nan, np.inf, -1e308, 1e300, 0.0]))
    return name, shape, dtype, special


def _make_array(shape, dtype, special, rng):
    if dtype == "O":
        return np.array([str(i) for i in range(int(np.prod(shape)))], dtype=object).reshape(shape), \
            h5py.string_dtype()
    if dtype == "V8":
        return np.zeros(shape, dtype="V8"), None
    values = rng.normal(size=shape) * 3
    if special is not None and values.size:
        values.reshape(-1)[rng.integers(values.size)] = special
    with np.errstate(all="ignore"):
        return values.astype(dtype), None


@FAST
@given(mutations=st.lists(_dataset_mutation(), min_size=1, max_size=3), seed=st.integers(0, 2**32 - 1))
def test_mutated_trajectories_load_or_are_bad_input(tmp_path_factory, mutations, seed):
    """Replace datasets of a valid trajectory with arbitrary shapes, dtypes and values:
    load_scene either loads a valid scene or raises InputError naming the file; no
    other exception and no numpy warning."""
    folder = tmp_path_factory.mktemp("mut")
    meshes, traj = _scene(folder)
    rng = np.random.default_rng(seed)
    with h5py.File(traj, "r+") as f:
        for name, shape, dtype, special in mutations:
            data, h5dtype = _make_array(shape, dtype, special, rng)
            del f[name]
            f.create_dataset(name, data=data, dtype=h5dtype)
            if name == "poses/orientation":
                f[name].attrs["quaternion_order"] = "wxyz"
    catcher = _no_warnings()
    try:
        scene = load_scene(meshes, traj)
    except InputError as exc:
        assert str(traj) in str(exc) and "expected" in str(exc) and "\n" not in str(exc)
        return
    finally:
        catcher.__exit__(None, None, None)
    assert np.isfinite(scene.poses.read(0, scene.poses.n_frames)).all() and (np.diff(scene.time) > 0).all()


# --- messages ------------------------------------------------------------------------------------

@given(text=st.text(max_size=40))
@settings(max_examples=30, deadline=None)
def test_escaped_text_is_one_printable_line(text):
    escaped = escape_text(text)
    assert "\n" not in escaped and "\r" not in escaped
    assert all(c.isprintable() for c in escaped)
    if text.isprintable():
        assert escaped == text


def test_input_errors_are_one_line_whatever_the_file_name():
    error = InputError("meshes/bad\nname\x1b[31m.stl", "cannot load mesh (line 1\nline 2)", "a mesh")
    assert str(error) == "meshes/bad\\nname\\x1b[31m.stl: cannot load mesh (line 1\\nline 2); expected a mesh"


# --- plot: any names, any finite times -------------------------------------------------------------

@pytest.mark.filterwarnings("ignore:Glyph .* missing from font:UserWarning")  # the CLI logs these at -vv
@settings(max_examples=int(os.environ.get("HOSTILE_EXAMPLES", 12)), deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(names=st.lists(st.text(min_size=1, max_size=12).filter(lambda s: "\x00" not in s), min_size=2, max_size=4,
                      unique=True),
       times=st.lists(st.floats(allow_nan=False, allow_infinity=False), min_size=2, max_size=5, unique=True),
       title=st.one_of(st.none(), st.text(max_size=12)))
def test_plot_draws_any_names_and_finite_times_or_refuses(tmp_path_factory, names, times, title):
    """Object names are text, not matplotlib math ($...$); times of any finite size are
    drawn or refused as bad input -- never an internal error."""
    pytest.importorskip("matplotlib")
    from collide.output import Contacts
    from collide.plot import plot_timeline
    frame_time = np.sort(np.array(times))
    n = frame_time.size
    contacts = {"object_a": np.zeros(1, np.int32), "object_b": np.ones(1, np.int32),
                "t_begin": frame_time[:1].copy(), "t_end": frame_time[-1:].copy(),
                "frame_begin": np.zeros(1, np.int64), "frame_end": np.array([n - 1]), "kind": np.zeros(1, np.uint8),
                "tri_a": np.zeros(1, np.int32), "tri_b": np.zeros(1, np.int32),
                "point_x": np.zeros(1), "point_y": np.zeros(1), "point_z": np.zeros(1)}
    cf = Contacts.from_file(contacts, {"name": names, "mesh": names, "triangles": np.ones(len(names), np.int64)},
                            frame_time, np.arange(n), None, {"mode": "discrete"}, {})
    png = tmp_path_factory.mktemp("plot") / "t.png"
    try:
        plot_timeline(cf, png, title)
    except InputError as exc:
        assert "too large to draw" in str(exc)
        assert np.abs(frame_time).max() > config.PLOT_MAX_TIME
        return
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unreadable_inputs_say_permission_denied(tmp_path, monkeypatch):
    """(Simulated: the tests may run as root, who can read everything.)"""
    meshes, traj = _scene(tmp_path)
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: False if str(path) == str(traj)
                        else real_access(path, mode, **kw))
    with pytest.raises(InputError, match=r"traj\.h5: cannot read file \(permission denied\); expected"):
        load_trajectory(traj)
    real_open = os.open

    def refusing_open(path, flags, *args, **kwargs):
        if str(path).endswith("a.stl"):
            raise PermissionError(errno.EACCES, "Permission denied")
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", refusing_open)
    with pytest.raises(InputError, match=r"a\.stl: cannot open \(permission denied\); expected"):
        collide.load.load_mesh(meshes / "a.stl")


def test_time_span_beyond_float64_is_refused(tmp_path):
    meshes, traj = _scene(tmp_path)
    with h5py.File(traj, "r+") as f:
        f["time"][...] = [-1e308, -1.0, 1.0, 1e308]
    with pytest.raises(InputError, match="time: spans -1e\\+308 to 1e\\+308, beyond float64"):
        load_trajectory(traj)



@numba.njit(nogil=True)
def _spin(n, x):
    """About n dependent float operations (about 0.5 s for n = 3e8), then two arrays, as the
    scan kernels return (boxing them calls Python)."""
    for i in range(n):
        x = x * 0.999999 + (i % 7) * 1e-9
    out = np.full(1, x)
    return out, out


def _spin_with_a_signal(call, signum=signal.SIGUSR1):
    """call() with signum sent to this process 0.05 s later, its handler raising Terminated."""
    def stop(signum, frame):
        raise Terminated(signum)

    _spin(10, 0.5)  # compile first
    previous = signal.signal(signum, stop)
    timer = threading.Timer(0.05, os.kill, (os.getpid(), signum))
    try:
        timer.start()
        return call()
    finally:
        timer.cancel()
        timer.join()
        signal.signal(signum, previous)


def test_a_signal_while_a_kernel_runs_in_the_main_thread_is_found_in_numbas_error():
    """A stop signal that lands while a kernel runs in the main thread is handled as numba
    converts the result, which numba reports as a SystemError caused by the handler's
    exception: the command line must exit with 128 + N (stop_request finds it), not
    report an internal error. (Scans run their chunks in worker threads, which never
    run signal handlers.)"""
    with pytest.raises(SystemError) as raw:
        _spin_with_a_signal(lambda: _spin(300_000_000, 0.25))
    assert isinstance(stop_request(raw.value), Terminated)
    assert stop_request(raw.value).signum == signal.SIGUSR1
    assert stop_request(SystemError("no cause")) is None and stop_request(ValueError()) is None


def test_one_worker_chunks_hold_stop_signals_until_the_kernel_returns():
    """A one-worker scan runs its kernels in the main thread with stop signals held back
    (pipeline._Deferred): SIGTERM in mid-kernel comes out after the kernel returns, as
    the handler's own exception, not wrapped in numba's SystemError."""
    with pytest.raises(Terminated) as caught:
        _spin_with_a_signal(lambda: pipeline._Deferred(_spin, (300_000_000, 0.25)).result(), signal.SIGTERM)
    assert caught.value.signum == signal.SIGTERM
    assert caught.value.__context__ is None and caught.value.__cause__ is None
