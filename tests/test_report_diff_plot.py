"""report, diff, plot and determinism through real processes (issue: pipeline and CI commands)."""
import csv
import io
import json
import subprocess
import sys

import h5py
import numpy as np
import pytest
from conftest import identity_quaternions, run_cli, write_box, write_trajectory

import collide


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """Three boxes: 'mover' slides through 'left' and 'right' (two contact intervals with each
    neighbour pair), plus a swept-only crossing of a thin 'plate'."""
    tmp = tmp_path_factory.mktemp("scene")
    meshes = tmp / "meshes"
    meshes.mkdir()
    write_box(meshes / "left.stl", centre=(-3, 0, 0))
    write_box(meshes / "right.stl", centre=(3, 0, 0))
    write_box(meshes / "plate.stl", extents=(0.125, 4, 4), centre=(0, 10, 0))
    write_box(meshes / "mover.stl")
    write_box(meshes / "bullet.stl", extents=(0.25, 0.25, 0.25))
    n = 21
    pos = np.zeros((n, 2, 3))
    pos[:, 0, 0] = np.concatenate([np.linspace(-5, 5, 11), np.linspace(4, -5, 10)])
    pos[:, 1, 1] = 10
    pos[:, 1, 0] = np.where(np.arange(n) < 10, -4.0, 4.0)   # jumps through the plate between frames 9 and 10
    traj = write_trajectory(tmp / "traj.h5", np.arange(n) * 0.5, ["mover", "bullet"], pos,
                            identity_quaternions(n, 2))
    out = tmp / "contacts.h5"
    proc = run_cli("scan", meshes, traj, "-o", out, "--triangle-pairs")
    assert proc.returncode == 0, proc.stderr
    return meshes, traj, out, tmp


def test_report_csv_and_jsonl_rows_match_contacts(scene):
    _, _, out, _ = scene
    contacts = collide.read_contacts(out).contacts
    n = contacts["t_begin"].size
    assert n >= 5
    proc = run_cli("report", out, "--format", "csv")
    assert proc.returncode == 0, proc.stderr
    rows = list(csv.DictReader(io.StringIO(proc.stdout)))
    assert len(rows) == n
    assert {r["a"] for r in rows} | {r["b"] for r in rows} <= {"mover", "bullet", "left", "right", "plate"}
    assert [float(r["t_begin"]) for r in rows] == contacts["t_begin"].tolist()
    proc = run_cli("report", out, "--format", "jsonl")
    lines = [json.loads(line) for line in proc.stdout.splitlines()]
    assert len(lines) == n and all("a" in r and "b" in r for r in lines)
    assert [r["kind"] for r in lines].count("swept") == int((contacts["kind"] == 1).sum()) >= 1
    doc = json.loads(run_cli("report", out, "--format", "json").stdout)
    assert len(doc["rows"]) == n and doc["mode"] == "continuous"


def test_report_pairs_and_triangle_pairs_and_table(scene):
    _, _, out, _ = scene
    cf = collide.read_contacts(out)
    pairs = [json.loads(x) for x in run_cli("report", out, "--what", "pairs", "--format", "jsonl").stdout.split("\n")
             if x]
    by_name = {(p["a"], p["b"]): p for p in pairs}
    # mover passes right (x in [2, 4]) out and back: 2 intervals; left likewise
    assert by_name[("mover", "left")]["intervals"] == 2 and by_name[("mover", "right")]["intervals"] == 2
    total = sum(p["intervals"] for p in pairs)
    assert total == cf.contacts["t_begin"].size
    tri = run_cli("report", out, "--what", "triangle-pairs", "--format", "csv").stdout.splitlines()
    assert len(tri) - 1 == cf.triangle_pairs["frame"].size
    table = run_cli("report", out)
    assert table.returncode == 0 and "mover" in table.stdout and "time_in_contact" in table.stdout


def test_report_into_closed_pipe_is_quiet(scene):
    """``| head -1``: no traceback, and collide's own exit status is 0 (not 1, "findings")."""
    _, _, out, _ = scene
    for what in ("triangle-pairs", "contacts"):
        proc = subprocess.run(f"{sys.executable} -m collide_cli.main report {out} --what {what} --format csv"
                              " | head -c 1 >/dev/null; echo ${PIPESTATUS[0]}",
                              shell=True, executable="/bin/bash", capture_output=True, text=True)
        assert "Traceback" not in proc.stderr and proc.stderr == ""
        assert proc.stdout.strip() == "0"


@pytest.mark.parametrize("value, why", [(None, "is missing"), ("other", "is 'other', not 'contacts'")])
def test_a_file_of_another_format_is_named_so(scene, tmp_path, value, why):
    _, _, out, _ = scene
    bad = tmp_path / "bad.h5"
    bad.write_bytes(out.read_bytes())
    with h5py.File(bad, "r+") as f:
        if value is None:
            del f.attrs["collide_format"]
        else:
            f.attrs["collide_format"] = value
    proc = run_cli("report", bad)
    assert proc.returncode == 2 and proc.stderr == (
        f"collide: error: {bad}: not a collide contacts file (attribute collide_format {why}); "
        "expected a collide contacts file (from collide scan)\n"), proc.stderr


def test_report_of_a_column_with_the_wrong_dtype_is_bad_input(scene, tmp_path):
    _, _, out, _ = scene
    bad = tmp_path / "bad.h5"
    bad.write_bytes(out.read_bytes())
    with h5py.File(bad, "r+") as f:
        del f["contacts/t_begin"]
        f["contacts/t_begin"] = np.array([b"x"] * f["contacts/t_end"].shape[0])
    for command in (("report", bad), ("diff", out, bad)):
        proc = run_cli(*command)
        assert proc.returncode == 2 and proc.stderr.startswith(f"collide: error: {bad}:contacts/t_begin: "), \
            proc.stderr
    proc = run_cli("report", tmp_path)
    assert proc.returncode == 2 and "is a folder" in proc.stderr


def test_output_files_get_the_usual_permissions(scene, tmp_path):
    """Temporary files are private (0o600); the renamed result is not."""
    import os
    meshes, traj, _, _ = scene
    out = tmp_path / "perm.h5"
    assert run_cli("scan", meshes, traj, "-o", out, "--mode", "discrete").returncode == 0
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask
    out.chmod(0o640)
    assert run_cli("scan", meshes, traj, "-o", out, "--mode", "discrete").returncode == 0
    assert out.stat().st_mode & 0o777 == 0o640


def test_report_of_empty_result(tmp_path):
    meshes = tmp_path / "m"
    meshes.mkdir()
    write_box(meshes / "a.stl")
    write_box(meshes / "b.stl", centre=(9, 0, 0))
    traj = write_trajectory(tmp_path / "t.h5", [0.0, 1.0], ["b"], np.full((2, 1, 3), 9.0),
                            identity_quaternions(2, 1))
    out = tmp_path / "c.h5"
    assert run_cli("scan", meshes, traj, "-o", out).returncode == 0
    assert run_cli("report", out, "--format", "csv").stdout.count("\n") == 1
    assert run_cli("report", out, "--format", "jsonl").stdout == ""
    assert json.loads(run_cli("report", out, "--format", "json").stdout)["rows"] == []
    assert run_cli("report", out).returncode == 0
    assert run_cli("plot", out, "-o", tmp_path / "t.png").returncode == 0


def test_diff_exit_codes(scene, tmp_path):
    _, _, out, _ = scene
    assert run_cli("diff", out, out).returncode == 0
    changed = tmp_path / "changed.h5"
    changed.write_bytes(out.read_bytes())
    with h5py.File(changed, "r+") as f:
        f["contacts/t_begin"][1] += 1e-3
    proc = run_cli("diff", out, changed)
    assert proc.returncode == 1 and "moved" in proc.stdout
    assert "mover" in proc.stdout
    assert run_cli("diff", out, changed, "--time-tol", "0.01").returncode == 0
    assert run_cli("diff", out, tmp_path / "missing.h5").returncode == 2
    not_ours = tmp_path / "other.h5"
    with h5py.File(not_ours, "w") as f:
        f["x"] = 1
    proc = run_cli("diff", out, not_ours)
    assert proc.returncode == 2 and proc.stderr.startswith("collide: error:")


def test_diff_reports_appeared_and_disappeared(scene, tmp_path):
    meshes, traj, out, _ = scene
    fewer = tmp_path / "fewer.h5"
    assert run_cli("scan", meshes, traj, "-o", fewer, "--frames", "0:8").returncode == 0
    proc = run_cli("diff", out, fewer)
    assert proc.returncode == 1 and "disappeared" in proc.stdout
    proc = run_cli("diff", fewer, out)
    assert proc.returncode == 1 and "appeared" in proc.stdout


def test_workers_do_not_change_results(scene, tmp_path):
    meshes, traj, out, _ = scene
    single = tmp_path / "single.h5"
    assert run_cli("scan", meshes, traj, "-o", single, "--triangle-pairs", "--workers", "1").returncode == 0
    assert run_cli("diff", out, single, "--time-tol", "0").returncode == 0
    with h5py.File(out) as a, h5py.File(single) as b:
        for group in ("contacts", "objects", "frames", "triangle_pairs"):
            for name in a[group]:
                assert np.array_equal(a[group][name][()], b[group][name][()]), (group, name)


def test_fail_on_contact_exit_1(scene, tmp_path):
    meshes, traj, _, _ = scene
    proc = run_cli("scan", meshes, traj, "-o", tmp_path / "x.h5", "--fail-on-contact", "-q")
    assert proc.returncode == 1


def test_plot_writes_png_with_bars(scene, tmp_path):
    pytest.importorskip("matplotlib")
    _, _, out, _ = scene
    png = tmp_path / "timeline.png"
    proc = run_cli("plot", out, "-o", png)
    assert proc.returncode == 0, proc.stderr
    from matplotlib.image import imread
    image = imread(png)
    assert image.shape[0] > 100 and image.shape[1] > 500
    red = (image[..., 0] > 0.7) & (image[..., 1] < 0.3) & (image[..., 2] < 0.3)   # swept-only bars
    blue = (image[..., 2] > 0.6) & (image[..., 0] < 0.3)                           # frame contact bars
    assert red.sum() > 50 and blue.sum() > 200
    few = tmp_path / "few.png"
    assert run_cli("plot", out, "-o", few, "--max-pairs", "1").returncode == 0
    assert imread(few).shape[0] < image.shape[0]  # fewer rows drawn


@pytest.mark.parametrize("suffix, magic", [(".pdf", b"%PDF-"), (".svg", b"<?xml"), (".PNG", b"\x89PNG"),
                                           ("", b"\x89PNG")])
def test_plot_writes_the_format_its_file_name_says(scene, tmp_path, suffix, magic):
    pytest.importorskip("matplotlib")
    _, _, out, _ = scene
    image = tmp_path / f"timeline{suffix}"
    proc = run_cli("plot", out, "-o", image)
    assert proc.returncode == 0, proc.stderr
    assert image.read_bytes().startswith(magic)


def test_plot_refuses_a_suffix_of_another_format(scene, tmp_path):
    pytest.importorskip("matplotlib")
    _, _, out, _ = scene
    proc = run_cli("plot", out, "-o", tmp_path / "timeline.jpeg")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert ".jpeg is not an image format written here; expected a file name ending in .png, .pdf" in proc.stderr
    assert not (tmp_path / "timeline.jpeg").exists()
