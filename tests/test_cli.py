"""The command line: outputs, summaries, exit codes (run in the test process by
run_cli, checked against real processes in test_in_process_runs_match_real_processes)."""
import json
import os
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest
from conftest import default_sigint, run_cli, signal_when_scanning, write_box

import collide
from collide import config


def test_version_and_help():
    proc = run_cli("--version")
    assert proc.returncode == 0 and collide.__version__ in proc.stdout
    for cmd in ([], ["scan"], ["validate"], ["inspect"]):
        proc = run_cli(*cmd, "--help")
        assert proc.returncode == 0 and "Usage:" in proc.stdout, cmd
    proc = run_cli("scan", "--help")
    for option in ("--mode", "--split", "--leaf-size", "--triangle-pairs", "--frames", "--fail-on-contact",
                   "--workers", "--scheduler", "-q", "-v", "--output"):
        assert option in proc.stdout


def test_in_process_runs_match_real_processes(two_boxes, tmp_path):
    """run_cli's in-process runs (what most CLI tests use) give what the real program
    gives: exit code, stdout, stderr and output file, for a scan with findings, a report,
    a bad input and a bad command line."""
    from conftest import run_in_process
    meshes, traj = two_boxes
    commands = [("scan", meshes, traj, "-o", tmp_path / "{}.h5", "--mode", "discrete", "--triangle-pairs",
                 "--fail-on-contact", "--format", "json"),
                ("report", tmp_path / "xreal.h5", "--format", "csv"),
                ("scan", meshes, tmp_path / "missing.h5", "-o", tmp_path / "{}-bad.h5"),
                ("scan", meshes, traj, "--mode", "sideways", "-o", tmp_path / "{}-usage.h5")]
    for command in commands:
        real = run_cli(*(str(a).format("xreal") for a in command), process=True)
        here = run_in_process(*(str(a).format("xhere") for a in command))
        assert real.returncode == here.returncode and real.returncode in (0, 1, 2), (command, real.stderr)
        assert _same_output(real.stdout.replace("xreal", "xhere"), here.stdout), command
        assert real.stderr.replace("xreal", "xhere") == here.stderr, command
    process = collide.read_contacts(tmp_path / "xreal.h5").contacts
    inproc = collide.read_contacts(tmp_path / "xhere.h5").contacts
    assert process.keys() == inproc.keys()
    for key in process:
        assert np.array_equal(process[key], inproc[key]), key


def _same_output(a, b):
    """Equal outputs; for JSON summaries, apart from times and mesh-cache use."""
    try:
        a, b = json.loads(a), json.loads(b)
    except ValueError:
        return a == b
    return {k: v for k, v in a.items() if k not in ("seconds", "cache")} == \
        {k: v for k, v in b.items() if k not in ("seconds", "cache")}


def test_the_garbage_collector_is_off_only_while_the_program_starts(two_boxes, tmp_path):
    """As the program, collide scan collects garbage again (leaving the engine's modules out)
    once the engine is imported, so a long scan's memory is collected as usual; code that
    calls main in its own process finds its collector as it was, after a scan too."""
    import gc

    from conftest import run_in_process
    meshes, traj = two_boxes
    program = ("import atexit, gc, sys\n"
               "def report():\n"
               "    print('collector', gc.isenabled(), gc.get_freeze_count() > 0, file=sys.stderr)\n"
               "atexit.register(report)\n"
               "sys.argv[0] = 'collide'\n"
               "from collide_cli.main import main\nmain(sys.argv[1:])\n")
    proc = subprocess.run([sys.executable, "-c", program, "scan", str(meshes), str(traj), "-o",
                           str(tmp_path / "a.h5")], capture_output=True, text=True, timeout=300)
    assert proc.returncode in (0, 1), proc.stderr
    assert "collector True True" in proc.stderr, proc.stderr
    assert gc.isenabled()
    assert run_in_process("scan", meshes, traj, "-o", tmp_path / "b.h5").returncode in (0, 1)
    assert gc.isenabled()


def test_scan_writes_spec_file_and_summary(two_boxes, tmp_path):
    meshes, traj = two_boxes
    out = tmp_path / "contacts.h5"
    proc = run_cli("scan", meshes, traj, "-o", out, "--mode", "discrete", "--triangle-pairs",
                   "--format", "json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["contacts"] == 1 and summary["frames"] == 13 and summary["objects"] == 2
    with h5py.File(out, "r") as f:
        assert f.attrs["collide_format"] == "contacts" and f.attrs["format_version"] == 1
        assert f.attrs["mode"] == "discrete"
        assert [s.decode() for s in f["objects/name"][()]] == ["mover", "fixed"]
        assert f["objects/triangles"][()].tolist() == [12, 12]
        assert f["frames/time"].shape == (13,)
        assert f["contacts/object_a"].dtype == np.int32 and f["contacts/t_begin"].dtype == np.float64
        assert f["contacts/kind"].dtype == np.uint8 and f["contacts/frame_begin"].dtype == np.int64
        assert f["contacts/frame_begin"][()].tolist() == [4]
        assert f["triangle_pairs/frame"].dtype == np.int64
        for key in ("command", "created_utc", "inputs", "parameters", "versions"):
            assert key in f["provenance"].attrs
        inputs = json.loads(f["provenance"].attrs["inputs"])
        assert len(inputs["trajectory"]["sha256"]) == 64
        assert inputs["meshes_folder"] == str(meshes) and set(inputs["meshes"]) == {"fixed.stl", "mover.obj"}
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_text_summary_and_fail_on_contact(two_boxes, tmp_path):
    meshes, traj = two_boxes
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete", "--fail-on-contact")
    assert proc.returncode == 1, proc.stderr
    assert "1 contact intervals" in proc.stdout
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete", "--fail-on-contact",
                   "--frames", "0:3")
    assert proc.returncode == 0, proc.stderr
    assert "0 contact intervals" in proc.stdout


def test_usage_errors_exit_2(two_boxes, tmp_path):
    meshes, traj = two_boxes
    for args in (["scan", meshes, traj, "--split", "middle"], ["scan", meshes, traj, "--frames", "5:2"],
                 ["scan", meshes, traj, "--frames", "x"], ["scan", meshes], ["frobnicate"], [],
                 ["scan", meshes, traj, "--frames", "::-1"], ["scan", meshes, traj, "--frames", "99999:"],
                 ["scan", meshes, traj, "--ignore", "nosuch:fixed"],
                 ["scan", meshes, traj, "-o", tmp_path / "no" / "such" / "dir.h5", "--mode", "discrete"],
                 ["scan", meshes, traj, "-o", tmp_path, "--mode", "discrete"]):
        proc = run_cli(*args)
        assert proc.returncode == 2, (args, proc.stderr)
        assert "Traceback" not in proc.stderr
        lines = proc.stderr.splitlines()
        assert len(lines) == 1 and lines[0].startswith("collide: error: "), (args, proc.stderr)
        # what is wrong, then what is expected (or where the command line is described)
        assert "; expected " in lines[0] or "; see 'collide" in lines[0], (args, lines[0])
        assert "None" not in lines[0] and "np." not in lines[0], lines[0]


def test_validate_and_inspect(two_boxes):
    meshes, traj = two_boxes
    proc = run_cli("validate", traj, meshes)
    assert proc.returncode == 0 and proc.stdout.startswith("ok:")
    proc = run_cli("validate", traj)
    assert proc.returncode == 0 and "13 frames" in proc.stdout
    proc = run_cli("inspect", meshes, "--format", "json")
    assert proc.returncode == 0, proc.stderr
    rows = json.loads(proc.stdout)
    assert {(r["mesh"], r["split"]) for r in rows} == {(m, s) for m in ("fixed.stl", "mover.obj")
                                                       for s in config.SPLIT_RULES}
    assert all(r["triangles"] == 12 and r["nodes"] >= 3 for r in rows)
    assert all(r["sah_cost"] > 0 for r in rows)
    table = run_cli("inspect", meshes, "--split", "sah", "--split", "lbvh")
    assert table.returncode == 0 and "SAH cost" in table.stdout and "median" not in table.stdout
    assert sorted(line.split()[2] for line in table.stdout.splitlines()[1:]) == ["lbvh", "lbvh", "sah", "sah"]


def test_internal_error_exit_3_traceback_only_with_v(two_boxes, tmp_path):
    """An unexpected exception becomes exit 3 with a one-line message (traceback with -v)."""
    meshes, traj = two_boxes
    out = tmp_path / "c.h5"
    program = ("import sys, collide.pipeline as s\n"
               "def boom(*a, **k):\n    raise RuntimeError('simulated bug')\n"
               "s.intervals_from_hits = boom\n"
               "from collide_cli.main import main\nmain(sys.argv[1:])\n")
    for flags, traceback_expected in (([], False), (["-v"], True)):
        proc = subprocess.run([sys.executable, "-c", program, "scan", str(meshes), str(traj), "-o", str(out),
                               "--mode", "discrete", *flags], capture_output=True, text=True, timeout=300)
        assert proc.returncode == 3, proc.stderr
        assert "simulated bug" in proc.stderr
        assert ("Traceback" in proc.stderr) == traceback_expected
        assert not out.exists() and list(tmp_path.glob(".c.h5*")) == []


def test_interrupt_exits_130_and_leaves_no_file(tmp_path):
    """SIGINT during a long scan: exit 130, no output file, no temporary file."""
    meshes = tmp_path / "m"
    meshes.mkdir()
    import trimesh
    trimesh.creation.icosphere(subdivisions=4).export(meshes / "a.stl")
    trimesh.creation.icosphere(subdivisions=4).export(meshes / "b.stl")
    n = 4000
    pos = np.zeros((n, 1, 3))
    pos[:, 0, 0] = np.linspace(-0.5, 0.5, n)
    q = np.zeros((n, 1, 4))
    q[..., 0] = 1
    from conftest import write_trajectory
    traj = write_trajectory(tmp_path / "t.h5", np.arange(n, dtype=float), ["b"], pos, q)
    out = tmp_path / "c.h5"
    proc = subprocess.Popen([sys.executable, "-m", "collide_cli.main", "scan", str(meshes), str(traj),
                             "-o", str(out), "--mode", "discrete", "--workers", "1", "--triangle-pairs"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    assert signal_when_scanning(proc, tmp_path, signal.SIGINT), proc.communicate()[1]
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert list(tmp_path.glob(".c.h5*")) == [] and not out.exists()


def test_interrupt_while_writing_keeps_the_old_output(two_boxes, tmp_path, monkeypatch, request):
    """Ctrl-C that arrives while the file is being written (h5py would swallow it in a
    cleanup callback) still ends the write: no new file, no temporary file, old output kept."""
    import collide.output as output
    meshes, traj = two_boxes
    out = tmp_path / "c.h5"
    out.write_bytes(b"old")
    real_columns = output._write_columns

    def interrupted_columns(*args):
        os.kill(os.getpid(), signal.SIGINT)  # delivered in the middle of the write
        return real_columns(*args)

    monkeypatch.setattr(output, "_write_columns", interrupted_columns)
    # Ctrl-C must reach Python even where this test process was started with SIGINT
    # ignored (a background job of a non-interactive shell)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    request.addfinalizer(lambda: signal.signal(signal.SIGINT, previous))
    with pytest.raises(KeyboardInterrupt):
        collide.scan(meshes, traj, mode="discrete", output=out)
    assert out.read_bytes() == b"old" and list(tmp_path.glob(".c.h5*")) == []
    monkeypatch.setattr(output, "_write_columns", real_columns)
    collide.scan(meshes, traj, mode="discrete", output=out)  # the handler is restored: works again
    assert collide.read_contacts(out).contacts["t_begin"].size == 1


def test_existing_output_replaced_only_by_complete_file(two_boxes, tmp_path):
    meshes, traj = two_boxes
    out = tmp_path / "c.h5"
    out.write_bytes(b"old")
    proc = run_cli("scan", meshes, traj, "-o", out, "--mode", "discrete")
    assert proc.returncode == 0
    assert collide.read_contacts(out).contacts["t_begin"].size == 1


def test_large_rotation_between_frames_warns_once(tmp_path):
    from conftest import write_trajectory
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_box(meshes / "spinner.stl")
    write_box(meshes / "far.stl", centre=(50, 0, 0))
    angle = np.radians([0.0, 5.0, 130.0, 135.0])         # 125 degrees between frames 1 and 2
    q = np.zeros((4, 1, 4))
    q[:, 0, 0], q[:, 0, 3] = np.cos(angle / 2), np.sin(angle / 2)
    traj = write_trajectory(tmp_path / "t.h5", np.arange(4.0), ["spinner"], np.zeros((4, 1, 3)), q)
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5")
    assert proc.returncode == 0, proc.stderr
    warnings = [line for line in proc.stderr.splitlines() if "WARNING" in line and "compiling" not in line]
    assert len(warnings) == 1 and "'spinner' turns by 125.0 degrees between frames 1 and 2" in warnings[0]
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--interpolation", "linear-vertex")
    warnings = [line for line in proc.stderr.splitlines() if "WARNING" in line and "compiling" not in line]
    assert len(warnings) == 1 and "'spinner': between frames 1 and 2" in warnings[0], proc.stderr
    assert "length units" in warnings[0]
    quiet = run_cli("scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", "discrete")
    assert "turns" not in quiet.stderr and "depart" not in quiet.stderr


@pytest.mark.parametrize("mode", ["discrete", "continuous"])
def test_no_colour_codes_on_a_terminal(two_boxes, tmp_path, mode):
    """Standard output on a terminal holds the summary and nothing else (numba would have
    colorama write a colour reset there at exit)."""
    import pty
    meshes, traj = two_boxes
    master, slave = pty.openpty()
    try:
        proc = subprocess.run(["collide", "scan", meshes, traj, "-o", tmp_path / "c.h5", "--mode", mode],
                              stdout=slave, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    finally:
        os.close(slave)
    out = b""
    while True:
        try:
            chunk = os.read(master, 4096)
        except OSError:  # the terminal's other end is closed: all read
            break
        if not chunk:
            break
        out += chunk
    os.close(master)
    assert proc.returncode == 0
    assert b"contact intervals" in out and b"\x1b" not in out, out
