"""Hostile inputs through the real command line: every refusal is exit 2 with exactly one
`collide: error: <file>[:<dataset>]: <problem>; expected <what>` line, no traceback, no
temporary file, inputs and any existing output untouched; signals end a run cleanly."""
import json
import os
import resource
import shutil
import signal
import stat
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
import trimesh
from conftest import (
    default_sigint,
    identity_quaternions,
    run_cli,
    run_in_process,
    signal_when_scanning,
    write_box,
    write_trajectory,
)

import collide


def _scene(folder, n_frames=4, position=None):
    meshes = folder / "meshes"
    meshes.mkdir()
    write_box(meshes / "a.stl")
    write_box(meshes / "b.stl")
    if position is None:
        position = np.zeros((n_frames, 1, 3))
        position[:, 0, 0] = np.linspace(3.0, 0.0, n_frames)
    traj = write_trajectory(folder / "traj.h5", np.arange(position.shape[0]) * 0.1, ["b"], position,
                            identity_quaternions(position.shape[0], 1))
    return meshes, traj


def _snapshot(folder):
    """{relative path: bytes} of every file under ``folder`` (symlinks as their target)."""
    return {p.relative_to(folder): (os.readlink(p) if p.is_symlink() else p.read_bytes())
            for p in sorted(folder.rglob("*")) if p.is_file() or p.is_symlink()}


def assert_bad_input(proc, *fragments):
    """Exit 2, exactly one `collide: error:` line with an `expected` part, no traceback
    (a scan's notes on its inputs, printed before a late error such as a full disk, are
    not part of the error)."""
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = [line for line in proc.stderr.splitlines() if not line.startswith("collide: note: ")]
    assert len(lines) == 1 and lines[0].startswith("collide: error: ") and "; expected " in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr and "Warning" not in proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])


@pytest.fixture(scope="module")
def scanned(tmp_path_factory):
    """A scene and its contacts file (discrete, with triangle pairs)."""
    folder = tmp_path_factory.mktemp("scanned")
    meshes, traj = _scene(folder)
    out = folder / "c.h5"
    proc = run_cli("scan", meshes, traj, "-o", out, "--mode", "discrete", "--triangle-pairs")
    assert proc.returncode == 0, proc.stderr
    return meshes, traj, out


# --- 1, 3: outputs ----------------------------------------------------------------------------

def test_scan_refuses_to_write_over_its_inputs(tmp_path):
    meshes, traj = _scene(tmp_path)
    os.link(traj, tmp_path / "hard.h5")
    before = _snapshot(tmp_path)
    for target in (traj, meshes / ".." / "traj.h5", meshes / "a.stl", tmp_path / "hard.h5"):
        proc = run_cli("scan", meshes, traj, "-o", target, "--mode", "discrete")
        assert_bad_input(proc, f"{target}: is an input of this command")
    assert _snapshot(tmp_path) == before


def test_plot_refuses_to_write_over_the_contacts_file(scanned, tmp_path):
    _, _, out = scanned
    copy = tmp_path / "c.h5"
    shutil.copy(out, copy)
    before = copy.read_bytes()
    for target in (copy, tmp_path / "." / "c.h5"):
        assert_bad_input(run_cli("plot", copy, "-o", target), "is an input of this command")
    assert copy.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == ["c.h5"]


def _device_node(folder):
    """A character device node like /dev/null inside ``folder`` (needs root), or None.
    The test never aims at the real /dev/null: a regression would replace it."""
    node = folder / "null"
    try:
        os.mknod(node, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except OSError:
        return None
    return node


def test_outputs_onto_devices_and_fifos_are_refused(scanned, tmp_path):
    meshes, traj, _ = scanned
    os.mkfifo(tmp_path / "fifo.h5")
    targets = [(tmp_path / "fifo.h5", "FIFO")]
    device = _device_node(tmp_path)
    if device is not None:
        targets.append((device, "character device"))
    for target, problem in targets:
        proc = run_cli("scan", meshes, traj, "-o", target, "--mode", "discrete")
        assert_bad_input(proc, problem, "only regular files are replaced")
    assert stat.S_ISFIFO(os.stat(tmp_path / "fifo.h5").st_mode)
    assert device is None or stat.S_ISCHR(os.stat(device).st_mode)


# --- 2: full disk / file size limit ----------------------------------------------------------

def _run_with_file_size_limit(limit, *args):
    """collide with RLIMIT_FSIZE = ``limit`` bytes and SIGXFSZ ignored (writes beyond it
    fail with EFBIG, as on a full disk), without root."""
    def limit_file_size():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return subprocess.run([sys.executable, "-m", "collide_cli.main", *map(str, args)], preexec_fn=limit_file_size,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("fraction", [0.0, 0.3, 0.97])
def test_scan_onto_a_full_disk_is_a_clean_error(scanned, tmp_path, fraction):
    meshes, traj, reference = scanned
    out = tmp_path / "c.h5"
    out.write_bytes(b"old result")
    limit = int(fraction * reference.stat().st_size)
    proc = _run_with_file_size_limit(limit, "scan", meshes, traj, "-o", out, "--mode", "discrete",
                                     "--triangle-pairs")
    assert proc.returncode != -signal.SIGSEGV
    assert_bad_input(proc, f"{out}: cannot write (file too large)")
    assert "Exception ignored" not in proc.stderr
    assert out.read_bytes() == b"old result" and sorted(p.name for p in tmp_path.iterdir()) == ["c.h5"]


def test_plot_onto_a_full_disk_is_a_clean_error(scanned, tmp_path):
    pytest.importorskip("matplotlib")
    _, _, contacts = scanned
    proc = _run_with_file_size_limit(2000, "plot", contacts, "-o", tmp_path / "t.png")
    assert_bad_input(proc, "t.png: cannot write (file too large)")
    assert list(tmp_path.iterdir()) == []


def test_a_file_size_limit_above_the_result_is_no_problem(scanned, tmp_path):
    meshes, traj, reference = scanned
    out = tmp_path / "c.h5"
    proc = _run_with_file_size_limit(10 * reference.stat().st_size, "scan", meshes, traj, "-o", out,
                                     "--mode", "discrete", "--triangle-pairs")
    assert proc.returncode == 0, proc.stderr
    assert run_cli("diff", reference, out, "--time-tol", "0").returncode == 0


# --- 4: inputs that reach outside themselves ----------------------------------------------------

def test_external_link_in_the_trajectory_needs_allow_external_data(tmp_path):
    meshes, traj = _scene(tmp_path)
    with h5py.File(traj, "r+") as f:
        position = f["poses/position"][()]
        del f["poses/position"]
        f["poses/position"] = h5py.ExternalLink("positions.h5", "/p")
    with h5py.File(tmp_path / "positions.h5", "w") as g:
        g["p"] = position
    for command in (["validate", traj, meshes], ["scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete"]):
        proc = run_cli(*command)
        assert_bad_input(proc, f"{traj}:poses/position: is an external link to 'positions.h5'",
                         "--allow-external-data")
        assert run_cli(*command, "--allow-external-data").returncode == 0
    assert (tmp_path / "c.h5").exists()


def test_external_storage_pointing_at_any_file_is_refused(tmp_path):
    meshes, traj = _scene(tmp_path)
    secret = tmp_path / "secret.txt"
    secret.write_bytes(b"top secret bytes 0123456789abcdef")
    with h5py.File(traj, "r+") as f:
        del f["time"]
        f.create_dataset("time", shape=(4,), dtype="f8", external=[(str(secret), 0, 32)])
    proc = run_cli("validate", traj, meshes)
    assert_bad_input(proc, f"{traj}:time: has external storage")
    assert "top secret" not in proc.stderr


def test_fifo_inputs_are_refused_not_waited_on(scanned, tmp_path):
    meshes, traj, contacts = scanned
    fifo = tmp_path / "pipe.h5"
    os.mkfifo(fifo)
    for command in (["validate", fifo], ["report", fifo], ["diff", contacts, fifo],
                    ["scan", meshes, fifo, "-o", tmp_path / "c.h5"]):
        assert_bad_input(run_cli(*command), f"{fifo}: is a FIFO (named pipe), not a regular file")
    fifo_meshes = tmp_path / "m"
    shutil.copytree(meshes, fifo_meshes)
    os.mkfifo(fifo_meshes / "c.obj")
    assert_bad_input(run_cli("validate", traj, fifo_meshes), "c.obj: is a FIFO")


# --- 5: signals ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def slow_scene(tmp_path_factory):
    """A discrete scan listing triangle pairs that takes several seconds on one thread (two
    fine spheres in contact at every one of 4000 frames)."""
    folder = tmp_path_factory.mktemp("slow")
    meshes = folder / "m"
    meshes.mkdir()
    trimesh.creation.icosphere(subdivisions=4).export(meshes / "a.stl")
    trimesh.creation.icosphere(subdivisions=4).export(meshes / "b.stl")
    n = 4000
    pos = np.zeros((n, 1, 3))
    pos[:, 0, 0] = np.linspace(-0.5, 0.5, n)
    traj = write_trajectory(folder / "t.h5", np.arange(n, dtype=float), ["b"], pos, identity_quaternions(n, 1))
    return meshes, traj


def _caught_signals(pid):
    """The set of signal numbers process ``pid`` has handlers for (Linux /proc; empty
    once the process is gone)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            mask = next(int(line.split()[1], 16) for line in f if line.startswith("SigCgt:"))
    except (OSError, StopIteration):
        return set()
    return {n for n in range(1, 65) if mask >> (n - 1) & 1}


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_signal_during_scan_exits_cleanly_and_keeps_the_old_output(slow_scene, tmp_path, signum, code):
    meshes, traj = slow_scene
    out = tmp_path / "c.h5"
    out.write_bytes(b"old result")
    proc = subprocess.Popen([sys.executable, "-m", "collide_cli.main", "scan", str(meshes), str(traj), "-o",
                             str(out), "--mode", "discrete", "--workers", "1", "--triangle-pairs"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    assert signal_when_scanning(proc, tmp_path, signum), proc.communicate()[1]
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == code, stderr
    lines = [line for line in stderr.splitlines() if not line.startswith("collide: note: ")]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    assert out.read_bytes() == b"old result" and sorted(p.name for p in tmp_path.iterdir()) == ["c.h5"]


def _sigterm_scan_keeps_the_old_output(scanned, tmp_path, patch):
    """A discrete scan into an existing output, run by a program that first executes
    ``patch`` (Python source that arranges a SIGTERM at some moment): exit 143 with
    the one-line notice, no temporary file left, the old output kept."""
    meshes, traj, _ = scanned
    out = tmp_path / "c.h5"
    out.write_bytes(b"old result")
    program = "import os, signal, sys\n" + patch + "from collide_cli.main import main\nmain(sys.argv[1:])\n"
    proc = subprocess.run([sys.executable, "-c", program, "scan", str(meshes), str(traj), "-o", str(out),
                           "--mode", "discrete"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 143, proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == "collide: terminated by SIGTERM", proc.stderr
    assert out.read_bytes() == b"old result" and sorted(p.name for p in tmp_path.iterdir()) == ["c.h5"]


def test_sigterm_as_the_temporary_file_is_made_drops_it(scanned, tmp_path):
    """SIGTERM the instant the output's temporary file exists (before its name is
    returned; a test that signals when it sees the file hits this): exit 143, the
    temporary file removed, the old output kept."""
    _sigterm_scan_keeps_the_old_output(scanned, tmp_path, (
        "import tempfile\n"
        "real = tempfile.mkstemp\n"
        "def made(*a, **k):\n    r = real(*a, **k)\n    os.kill(os.getpid(), signal.SIGTERM)\n    return r\n"
        "tempfile.mkstemp = made\n"))


def test_sigterm_while_writing_drops_the_temporary_file(scanned, tmp_path):
    """SIGTERM that arrives in the middle of the HDF5 write: held back until the write
    is done, then the temporary file is removed and the old output kept (exit 143)."""
    _sigterm_scan_keeps_the_old_output(scanned, tmp_path, (
        "import collide.output as o\n"
        "real = o._write_columns\n"
        "def columns(*a):\n    os.kill(os.getpid(), signal.SIGTERM)\n    return real(*a)\n"
        "o._write_columns = columns\n"))


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="needs Linux /proc")
@pytest.mark.parametrize("delay", [0.0, 0.03, 0.1, 0.25])
def test_ctrl_c_while_starting_up_is_quiet(scanned, delay):
    """Ctrl-C from the moment collide's code runs (it installs its handler before the
    slow imports: numpy, h5py, numba) until the command ends: exit 130, one line."""
    _, traj, _ = scanned
    proc = subprocess.Popen([sys.executable, "-m", "collide_cli.main", "validate", str(traj)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    while signal.SIGTERM not in _caught_signals(proc.pid):  # collide's handlers are in place
        if proc.poll() is not None:
            pytest.fail("collide ran to its end without installing its stop-signal handlers")
        time.sleep(0.001)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    if proc.returncode == 0:
        pytest.skip("finished before the interrupt")
    assert proc.returncode == 130, stderr
    assert stderr.strip() == "collide: interrupted"


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_stop_signal_before_the_command_runs_says_so(monkeypatch, scanned, signum):
    """A stop signal that lands in main before the command's own handling is in place
    (here: while logging is set up) exits 128 + N with the one line, as anywhere else
    (it used to exit silently: the start-up Ctrl-C test's rare empty stderr)."""
    from collide_cli import main as cli_main

    from collide.errors import Terminated

    def stopped():
        raise Terminated(signum)
    monkeypatch.setattr(cli_main, "_configure_logging", stopped)
    _, traj, _ = scanned
    result = run_in_process("validate", traj)
    assert result.returncode == 128 + signum
    expected = "collide: interrupted" if signum == signal.SIGINT else "collide: terminated by SIGTERM"
    assert result.stderr.strip() == expected


def test_a_stop_signal_while_the_handlers_are_restored_is_not_lost(monkeypatch):
    """Ctrl-C that lands while main puts the signal handlers back (seen as a rare
    traceback and exit 1 after a finished command): the restoring completes, and the
    signal goes to the restored handler (as the program: collide: interrupted, 130)."""
    import warnings

    from collide_cli import main as cli_main

    from collide.errors import Terminated
    real_signal = signal.signal
    installed, delivered = [], []

    def signal_hit_once(signum, handler):
        if not installed and not delivered and signum == signal.SIGINT and handler is not cli_main._terminate:
            delivered.append("during")  # Python runs the pending handler inside signal.signal
            raise Terminated(signal.SIGINT)
        installed.append((signum, handler))
        return real_signal(signum, handler)

    def restored(signum, frame):
        delivered.append(signum)

    before = signal.getsignal(signal.SIGINT)
    previous = {"signals": {signal.SIGINT: restored}, "showwarning": warnings.showwarning,
                "unraisablehook": sys.unraisablehook}
    monkeypatch.setattr(cli_main, "_AS_PROGRAM", False)
    monkeypatch.setattr(signal, "signal", signal_hit_once)
    try:
        cli_main._restore_handlers(previous)
    finally:
        real_signal(signal.SIGINT, before)
    assert installed == [(signal.SIGINT, restored)]
    assert delivered == ["during", signal.SIGINT]


def test_temporary_file_of_a_killed_run_is_removed_by_the_next(scanned, tmp_path):
    meshes, traj, _ = scanned
    out = tmp_path / "c.h5"
    from collide.output import HOST_TAG
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".c.h5.{HOST_TAG}-{dead.pid}.x1y2z3w4.tmp"
    stale.write_bytes(b"left by kill -9")
    proc = run_cli("scan", meshes, traj, "-o", out, "--mode", "discrete")
    assert proc.returncode == 0, proc.stderr
    assert not stale.exists() and "removed" in proc.stderr and "temporary file" in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.h5"]


# --- 6: declared sizes ------------------------------------------------------------------------------

def test_huge_declared_shapes_are_refused_with_the_memory_needed(tmp_path):
    meshes, traj = _scene(tmp_path)
    with h5py.File(traj, "r+") as f:
        for name in ("time", "objects/name", "poses"):
            del f[name]
        f.create_dataset("time", shape=(10**9,), chunks=(10**4,), dtype="f8")
        f.create_dataset("objects/name", shape=(1000,), data=[f"o{i}" for i in range(1000)],
                         dtype=h5py.string_dtype())
        f.create_dataset("poses/matrix", shape=(10**9, 1000, 4, 4), chunks=(1, 1, 4, 4), dtype="f8")
    proc = run_cli("validate", traj)
    assert_bad_input(proc, "a trajectory of 1000000000 frames and 1000 objects needs about", "--max-memory")
    # poses are read a block at a time: what must fit is the frame times (16 bytes a frame)
    assert_bad_input(run_cli("validate", traj, "--max-memory", "8G"), "needs about 14.9 GiB", "limit of 8 GiB")
    proc = run_cli("validate", traj, "--max-memory", "lots")
    assert proc.returncode == 2 and "'lots' is not a size" in proc.stderr


def test_huge_contacts_column_is_refused(scanned, tmp_path):
    _, _, contacts = scanned
    copy = tmp_path / "c.h5"
    shutil.copy(contacts, copy)
    with h5py.File(copy, "r+") as f:
        for name in list(f["contacts"]):
            dtype = f["contacts"][name].dtype
            del f["contacts"][name]
            f["contacts"].create_dataset(name, shape=(10**11,), chunks=(10**5,), dtype=dtype)
    for command in (["report", copy], ["diff", contacts, copy], ["plot", copy, "-o", tmp_path / "t.png"]):
        assert_bad_input(run_cli(*command), f"{copy}: reading this contacts file needs about")


# --- 7: coordinates -----------------------------------------------------------------------------------

def test_objects_1e200_apart_are_bad_input_and_numpy_stays_quiet(tmp_path):
    position = np.zeros((3, 1, 3))
    position[:, 0, 0] = 1e200
    meshes, traj = _scene(tmp_path, position=position)
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5")
    assert_bad_input(proc, f"{traj}:poses/position: position at frame 0, object 0 lies 1e+200 from the origin",
                     "within 1e+90 of the origin")
    assert not (tmp_path / "c.h5").exists()


# --- 8: damaged contacts files, odd values, odd names ----------------------------------------------

def _corrupted_copy(contacts, folder):
    """A copy of ``contacts`` with 8 bytes overwritten where h5py then raises RuntimeError."""
    raw = contacts.read_bytes()
    probe = folder / "probe.h5"
    for offset in range(0, len(raw), 16):
        probe.write_bytes(raw[:offset] + b"\xff" * 8 + raw[offset + 8:])
        try:
            with h5py.File(probe, "r") as f:
                for group in ("contacts", "objects", "frames", "triangle_pairs"):
                    for name in f[group]:
                        f[group][name][()]
        except RuntimeError:
            return probe
        except Exception:
            continue
    pytest.skip("no corruption of this file makes h5py raise RuntimeError")


def test_corrupted_contacts_file_is_bad_input_for_every_reader(scanned, tmp_path):
    _, _, contacts = scanned
    bad = _corrupted_copy(contacts, tmp_path)
    for command in (["report", bad], ["diff", contacts, bad], ["plot", bad, "-o", tmp_path / "t.png"]):
        assert_bad_input(run_cli(*command), f"collide: error: {bad}")


@pytest.mark.parametrize("column", ["triangle_pairs/tri_b", "contacts/t_end", "frames/time", "objects/name"])
def test_a_corrupt_data_chunk_is_bad_input_naming_its_dataset(scanned, tmp_path, column):
    _, _, contacts = scanned
    bad = tmp_path / "bad.h5"
    shutil.copy(contacts, bad)
    with h5py.File(bad, "r+") as f:  # the column again, compressed, so that garbage fails to inflate
        data = f[column][()]
        del f[column]
        info = f.create_dataset(column, data=data, chunks=data.shape, compression="gzip").id.get_chunk_info(0)
    raw = bytearray(bad.read_bytes())
    raw[info.byte_offset + 2:info.byte_offset + info.size] = b"\x5a" * (info.size - 2)  # after zlib's header
    bad.write_bytes(bytes(raw))
    for command in (["report", bad], ["diff", contacts, bad], ["plot", bad, "-o", tmp_path / "t.png"]):
        assert_bad_input(run_cli(*command), f"collide: error: {bad}:{column}: cannot read (")


@pytest.mark.parametrize("column, value", [("triangle_pairs/tri_a", 10**6), ("triangle_pairs/object_b", -1),
                                           ("triangle_pairs/frame", 99), ("contacts/tri_b", -5)])
def test_indices_out_of_range_are_bad_input_for_every_reader(scanned, tmp_path, column, value):
    _, _, contacts = scanned
    bad = tmp_path / "bad.h5"
    shutil.copy(contacts, bad)
    with h5py.File(bad, "r+") as f:
        f[column][0] = value
    for command in (["report", bad, "--what", "triangle-pairs"], ["diff", contacts, bad],
                    ["plot", bad, "-o", tmp_path / "t.png"]):
        assert_bad_input(run_cli(*command), f"{bad}:{column}: ", "out of range")


def test_plot_with_nan_frame_times_is_bad_input(scanned, tmp_path):
    _, _, contacts = scanned
    bad = tmp_path / "bad.h5"
    shutil.copy(contacts, bad)
    with h5py.File(bad, "r+") as f:
        f["frames/time"][1] = np.nan
    assert_bad_input(run_cli("plot", bad, "-o", tmp_path / "t.png"), f"{bad}:frames/time: non-finite frame time")
    assert not (tmp_path / "t.png").exists()


def _strict_json(text):
    def refuse(constant):
        raise ValueError(f"not JSON: {constant}")
    return json.loads(text, parse_constant=refuse)


def test_json_output_is_standard_json_with_null_for_nan(scanned, tmp_path):
    meshes, _, contacts = scanned
    copy = tmp_path / "c.h5"
    shutil.copy(contacts, copy)
    with h5py.File(copy, "r+") as f:
        f["contacts/point_x"][0] = np.nan
        f["contacts/point_y"][0] = np.inf
    document = _strict_json(run_cli("report", copy, "--format", "json").stdout)
    assert document["rows"][0]["point_x"] is None and document["rows"][0]["point_y"] is None
    lines = run_cli("report", copy, "--format", "jsonl").stdout.splitlines()
    assert [_strict_json(line)["point_x"] for line in lines] == [None]
    pairs = _strict_json(run_cli("report", copy, "--format", "json", "--what", "triangle-pairs").stdout)
    assert len(pairs["rows"]) == collide.read_contacts(copy).triangle_pairs["frame"].size
    assert _strict_json(run_cli("inspect", meshes, "--format", "json", "--split", "sah").stdout)


@pytest.mark.parametrize("args, fragment", [
    (["--leaf-size", "99999999999999999999999"], "--leaf-size"),
    (["--time-tol", "nan"], "'nan' is not a finite number"),
    (["--time-tol", "inf"], "--time-tol"),
    (["--workers", "100000"], "--workers"),
])
def test_out_of_range_options_are_usage_errors(scanned, tmp_path, args, fragment):
    meshes, traj, _ = scanned
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", *args)
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1 and fragment in proc.stderr, proc.stderr
    assert not (tmp_path / "c.h5").exists()


def test_diff_time_tol_nan_is_a_usage_error(scanned):
    _, _, contacts = scanned
    proc = run_cli("diff", contacts, contacts, "--time-tol", "nan")
    assert proc.returncode == 2 and "not a finite number" in proc.stderr


def test_control_characters_in_names_stay_on_one_line(scanned, tmp_path):
    meshes, traj, _ = scanned
    odd = tmp_path / "m"
    shutil.copytree(meshes, odd)
    (odd / "bad\nname\x1b[2J.obj").write_text("not a mesh\n")
    proc = run_cli("validate", traj, odd)
    assert_bad_input(proc, "bad\\nname\\x1b[2J.obj")


def test_unusable_paths_are_bad_input_with_what_was_expected(scanned, tmp_path):
    meshes, traj, contacts = scanned
    long_name = tmp_path / ("x" * 300 + ".h5")
    through_file = contacts / "inside.h5"
    for command, fragment in ((["validate", long_name], "file name too long"),
                              (["report", through_file], "not a directory"),
                              (["scan", meshes, traj, "-o", long_name], "file name too long"),
                              (["scan", meshes, traj, "-o", through_file], "output folder"),
                              (["inspect", long_name], "file name too long")):
        assert_bad_input(run_cli(*command), fragment)


def test_empty_paths_are_usage_errors(scanned):
    meshes, traj, contacts = scanned
    for command in (["report", ""], ["validate", "", meshes], ["scan", meshes, traj, "-o", ""]):
        proc = run_cli(*command)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "the path is empty" in proc.stderr
