"""A fast command line and truthful start-up messages.

--help, --version's first line and shell completion must not import the engine's heavy
libraries (checked through sys.modules, not with a stopwatch); the compile notice
appears exactly when numba compiles (numba's compile events), never on warm runs.
"""
import io
import json
import logging
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

import collide
from collide import jit_events

HEAVY = ("numba", "llvmlite", "h5py", "trimesh", "matplotlib", "scipy")
COMMANDS = ("scan", "validate", "report", "diff", "plot", "inspect", "urdf")


def _python(code, env=None):
    """Run ``code`` in a fresh interpreter; returns CompletedProcess (text)."""
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, **(env or {})))


def test_help_and_completion_import_no_heavy_module():
    """Importing the CLI, --help of the program and of every command, and shell completion
    leave numba, llvmlite, h5py, trimesh, matplotlib and scipy unimported."""
    code = f"""
import contextlib, io, json, os, sys
import collide_cli.main as m
after_import = sorted(n for n in {HEAVY!r} if n in sys.modules)
helps = {{}}
for args in [["--help"], ["-h"]] + [[c, "--help"] for c in {COMMANDS!r}]:
    with contextlib.redirect_stdout(io.StringIO()) as out:
        code = m._run(args)
    helps[" ".join(args)] = [code, "Usage:" in out.getvalue()]
os.environ.update(_COLLIDE_COMPLETE="bash_complete", COMP_WORDS="collide scan --mo", COMP_CWORD="2")
out = io.TextIOWrapper(io.BytesIO(), write_through=True)  # click writes completions as bytes
with contextlib.redirect_stdout(out):
    m._run([])
print(json.dumps({{"after_import": after_import, "helps": helps, "completion": out.buffer.getvalue().decode(),
                  "heavy": sorted(n for n in {HEAVY!r} if n in sys.modules)}}))
"""
    proc = _python(code)
    assert proc.returncode == 0, proc.stderr
    found = json.loads(proc.stdout)
    assert found["after_import"] == [] and found["heavy"] == [], found
    assert all(v == [0, True] for v in found["helps"].values()), found["helps"]
    assert "plain,--mode" in found["completion"].splitlines()


def test_import_collide_is_light_and_the_api_still_works():
    """collide's public names load the engine on first use (PEP 562)."""
    code = f"""
import json, sys
import collide
light = sorted(n for n in {HEAVY!r} if n in sys.modules)
names = dir(collide)
from collide import scan, ScanResult, read_contacts, write_contacts
from collide.ccd import vertex_face_toi
import collide as c2
print(json.dumps({{"light": light, "dir": names, "same": c2.scan is scan and collide.read_contacts is read_contacts,
                  "modules": [scan.__module__, ScanResult.__module__, read_contacts.__module__,
                              write_contacts.__module__], "ccd": collide.ccd.vertex_face_toi is vertex_face_toi,
                  "loaded": "numba" in sys.modules}}))
"""
    proc = _python(code)
    assert proc.returncode == 0, proc.stderr
    found = json.loads(proc.stdout)
    assert found["light"] == []
    assert set(collide.__all__) <= set(found["dir"])
    assert found["same"] and found["ccd"]
    assert found["modules"] == ["collide.pipeline", "collide.result", "collide.output", "collide.output"]
    assert found["loaded"]
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        collide.no_such_name  # noqa: B018
    assert not hasattr(collide, "__no_such_dunder__")


def test_shell_completion_of_the_installed_program():
    """What bash's completion script runs: the program prints the matching command."""
    program = shutil.which("collide", path=str(Path(sys.executable).parent))
    command = [program] if program else [sys.executable, "-m", "collide_cli.main"]
    env = dict(os.environ, _COLLIDE_COMPLETE="bash_complete", COMP_WORDS="collide sc", COMP_CWORD="1")
    proc = subprocess.run(command, env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.splitlines() == ["plain,scan"], (proc.stdout, proc.stderr)
    env = dict(os.environ, _COLLIDE_COMPLETE="zsh_complete", COMP_WORDS="collide report x --format j",
               COMP_CWORD="4")
    proc = subprocess.run(command, env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and {"json", "jsonl"} <= set(proc.stdout.splitlines()), proc.stdout
    proc = subprocess.run(command, env=dict(os.environ, _COLLIDE_COMPLETE="bash_source"),
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and "_COLLIDE_COMPLETE=bash_complete" in proc.stdout


def test_version_names_libraries_and_the_kernel_cache(tmp_path):
    proc = run_cli("--version", env={"COLLIDE_KERNEL_CACHE_DIR": str(tmp_path / "k")})
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == f"collide {collide.__version__}"
    for name in ("Python", "numpy", "numba", "llvmlite", "trimesh", "h5py"):
        assert any(line.startswith(name + " ") and "not importable" not in line for line in lines), proc.stdout
    cache = [line for line in lines if line.startswith("numba kernel cache: ")]
    assert len(cache) == 1 and f"{tmp_path / 'k'}{os.sep}{collide.__version__}-" in cache[0], cache
    assert "collide's kernel cache" in cache[0]
    # numba's own variable, when collide's is not set: a folder inside it
    env = {k: v for k, v in os.environ.items() if k != "COLLIDE_KERNEL_CACHE_DIR"}
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")
    proc = subprocess.run([sys.executable, "-m", "collide_cli.main", "--version"], env=env,
                          capture_output=True, text=True, timeout=300)
    assert f"numba kernel cache: {tmp_path / 'numba' / 'collide-kernels'}{os.sep}" in proc.stdout, proc.stdout


# --- compile notices ---------------------------------------------------------------------------

def _fresh_kernels():
    """Two new numba functions (never compiled, not cached): ``outer`` calls ``inner``."""
    from numba import njit

    @njit
    def inner(x):
        return x + 1

    @njit
    def outer(x):
        return inner(x) * 2

    return outer, inner


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_live_progress_names_the_kernel_and_counts_top_level_compiles(monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    outer, inner = _fresh_kernels()
    other, _ = _fresh_kernels()
    screen = _Terminal()
    jit_events.report_to(screen, live=True)
    try:
        with jit_events.compile_notice([outer, other]):
            assert outer(1) == 4  # compiles outer, and inner inside it (not counted)
        shown = screen.getvalue()
        with jit_events.compile_notice([outer, other]):
            assert outer(2) == 6  # compiled already: nothing shown
    finally:
        jit_events.report_to(None)
    assert screen.getvalue() == shown
    assert "\rcollide: compiling kernel 1 of 2 (first run only): " \
           "test_cli_speed._fresh_kernels.<locals>.outer, 0 s" in shown
    assert "inner" not in shown and "kernel 2 of 2" not in shown
    assert shown.endswith("\n") and shown.count("\n") == 1
    assert shown.rsplit("\r", 1)[1].startswith("collide: compiled numba kernels in ")


def test_one_notice_per_compiling_block_and_none_when_warm(caplog):
    outer, _ = _fresh_kernels()
    other, _ = _fresh_kernels()
    stream = io.StringIO()
    jit_events.report_to(stream)
    try:
        with jit_events.compile_notice([outer, other]):
            outer(1)
            other(1)
        with jit_events.compile_notice([outer, other]):
            outer(1)
            other(1)
    finally:
        jit_events.report_to(None)
    lines = stream.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("collide: compiling collide's numba kernels") and \
        "first run only" in lines[0]
    # library use: the collide log, once
    outer, _ = _fresh_kernels()
    with caplog.at_level(logging.WARNING, logger="collide"):
        with jit_events.compile_notice([outer]):
            outer(1)
            outer(1.5)  # a second signature of the same kernel: still one notice
        with jit_events.compile_notice([outer]):
            outer(1)
    notes = [r for r in caplog.records if "compiling" in r.getMessage()]
    assert len(notes) == 1 and notes[0].levelno == logging.WARNING


@pytest.mark.slow
def test_first_scan_announces_compiling_and_warm_scan_says_nothing(two_boxes, tmp_path):
    """A real first run (empty kernel cache) compiles the discrete kernels and says so on
    stderr (not a terminal), naming the cache; the next run with that cache prints no
    notice. (Slow: a real cold compile.)"""
    meshes, traj = two_boxes
    env = {"COLLIDE_KERNEL_CACHE_DIR": str(tmp_path / "kernels")}
    cold = run_cli("scan", meshes, traj, "-o", tmp_path / "a.h5", "--mode", "discrete", env=env)
    assert cold.returncode == 0, cold.stderr
    notes = [line for line in cold.stderr.splitlines() if "compil" in line]
    assert notes and notes[0].startswith("collide: compiling collide's numba kernels"), cold.stderr
    assert str(tmp_path / "kernels") in notes[0] and "WARNING" not in cold.stderr
    assert any((tmp_path / "kernels").rglob("*.nbi"))
    warm = run_cli("scan", meshes, traj, "-o", tmp_path / "b.h5", "--mode", "discrete", env=env)
    assert warm.returncode == 0 and "compil" not in warm.stderr, warm.stderr


def test_warm_up_plan_shares_units_nearly_as_well_as_the_best_split(monkeypatch):
    """plan (longest unit first to the least loaded process) gives every unit once, and
    its longest process is within Graham's 4/3 of the best split found by trying every
    assignment."""
    import itertools

    import numpy as np

    from collide import warmup
    rng = np.random.default_rng(3)
    for _ in range(40):
        n_units, processes = int(rng.integers(1, 7)), int(rng.integers(1, 4))
        costs = {f"u{i}": float(rng.integers(1, 100)) for i in range(n_units)}
        monkeypatch.setattr(warmup, "COMPILE_SECONDS", costs)
        groups = warmup.plan(list(costs), processes)
        assert len(groups) == processes and sorted(sum(groups, [])) == sorted(costs)
        longest = max(sum(costs[u] for u in g) for g in groups)
        best = min(max(sum(c for c, p in zip(costs.values(), owner) if p == k) for k in range(processes))
                   for owner in itertools.product(range(processes), repeat=n_units))
        assert longest <= best * 4 / 3 + 1e-9, (costs, groups)


def test_warm_up_plan_starts_the_step_scan_and_its_searches_in_two_processes(monkeypatch):
    """The step scan ("continuous") and its contact searches ("searches") each start a
    process of their own when there are two or more, the step scan last in its process;
    with one process the searches go before the step scan; every unit is given once."""
    from collide import warmup
    monkeypatch.setattr(warmup, "COMPILE_SECONDS", {"continuous": 70.0, "searches": 49.0, "discrete": 20.0,
                                                    "setup": 15.0, "lbvh": 4.0})
    units = ["searches", "continuous", "discrete", "setup", "lbvh"]
    assert warmup.plan(units, 2) == [["searches", "discrete", "setup"], ["lbvh", "continuous"]]
    assert warmup.plan(units[:3], 2) == [["searches", "discrete"], ["continuous"]]
    assert warmup.plan(units[:3], 3) == [["searches"], ["continuous"], ["discrete"]]
    assert warmup.plan(units, 1) == [["searches", "discrete", "setup", "lbvh", "continuous"]]
    for processes in (1, 2, 3, 4, 6):
        for n_units in range(1, len(units) + 1):
            given = units[:n_units]
            groups = warmup.plan(given, processes)
            assert len(groups) == processes and sorted(sum(groups, [])) == sorted(given)
            if "continuous" not in given:
                continue
            holder = next(g for g in groups if "continuous" in g)
            assert holder[-1] == "continuous"
            if "searches" in holder:
                assert processes == 1
            else:
                assert next(g for g in groups if "searches" in g)[0] == "searches"


def test_mesh_suffixes_are_kept_per_trimesh_version(tmp_path, monkeypatch):
    """The suffix list read from the cache folder is trimesh's own; a missing or damaged
    file is replaced by trimesh's answer."""
    import trimesh

    from collide import load
    monkeypatch.setenv("COLLIDE_CACHE_DIR", str(tmp_path))
    expected = {"." + e.lower() for e in trimesh.exchange.load.mesh_formats() if e != "xyz"}
    path = load._suffix_file()
    assert path.parent == tmp_path and trimesh.__version__ in path.name
    for damage in (None, b"", b"\xff\x00", b'{"a": 1}', b'[".stl", "../x"]', b"[]"):
        if damage is not None:
            path.write_bytes(damage)
        assert load._mesh_suffixes() == expected
        assert set(json.loads(path.read_text())) == expected  # written (again)
    assert load._mesh_suffixes() == expected  # and read back


def test_warm_scan_does_not_import_trimesh(two_boxes, tmp_path):
    """With the meshes and BVHs in the cache, a scan never imports trimesh (half a
    second of every run's start-up)."""
    meshes, traj = two_boxes
    script = ("import sys\nfrom collide_cli.main import main\ntry:\n    main(sys.argv[1:])\nexcept SystemExit:\n"
              "    pass\nprint('trimesh imported' if 'trimesh' in sys.modules else 'no trimesh')\n")
    runs = [subprocess.run([sys.executable, "-c", script, "scan", str(meshes), str(traj), "-o",
                            str(tmp_path / f"{i}.h5"), "--mode", "discrete"], capture_output=True, text=True)
            for i in range(2)]
    assert all(r.returncode == 0 for r in runs), runs[0].stderr
    assert runs[1].stdout.strip().endswith("no trimesh"), runs[1].stdout


def test_the_program_skips_numba_s_blas_probe(two_boxes, tmp_path):
    """As the program, a warm scan (both modes) never imports scipy.linalg: numba would, to
    probe for a BLAS that collide's kernels do not use (about 0.15 s of every run with
    SciPy installed). The scan's contacts are those of a scan in a process that probed."""
    pytest.importorskip("scipy.linalg")
    meshes, traj = two_boxes
    script = ("import sys\nsys.argv[0] = 'collide'\nfrom collide_cli.main import main\ntry:\n"
              "    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
              "print('scipy.linalg imported' if 'scipy.linalg' in sys.modules else 'no scipy.linalg')\n")
    for mode in ("discrete", "continuous"):
        # in this process, which has imported scipy.linalg; it also puts the meshes in the
        # cache (parsing them imports SciPy)
        probed = collide.scan(meshes, traj, mode=mode).contacts
        out = tmp_path / f"{mode}.h5"
        run = subprocess.run([sys.executable, "-c", script, "scan", str(meshes), str(traj), "-o", str(out),
                              "--mode", mode], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        assert run.stdout.strip().endswith("no scipy.linalg"), run.stdout
        written = collide.read_contacts(out).contacts
        assert probed["t_begin"].size > 0
        for column in probed:
            np.testing.assert_array_equal(written[column], probed[column])


THREADS_AFTER_NUMPY = """
import os, sys
sys.argv[0] = 'collide'
if sys.argv[1] == 'program':
    import collide_cli.main
import numpy
print(len(os.listdir('/proc/self/task')), os.environ.get('OPENBLAS_NUM_THREADS'))
"""


@pytest.mark.skipif(not os.path.isdir("/proc/self/task") or (os.cpu_count() or 1) < 2, reason="needs /proc, 2 cores")
def test_the_program_starts_no_blas_threads_unless_asked():
    """numpy's OpenBLAS starts a spinning thread per core as it loads (0.1 s of CPU each);
    collide's work needs none: as the program, numpy loads without them, unless the user
    set OPENBLAS_NUM_THREADS."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}

    def threads(how, **extra):
        run = subprocess.run([sys.executable, "-c", THREADS_AFTER_NUMPY, how], env={**env, **extra},
                             capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        count, setting = run.stdout.split()
        return int(count), setting
    assert threads("program") == (1, "1")
    assert threads("library")[0] > 1  # numpy alone starts them: the check above can fail
    assert threads("program", OPENBLAS_NUM_THREADS="2") == (2, "2")


def test_a_single_item_runs_in_the_calling_thread_and_more_are_shared_out(monkeypatch):
    """Starting worker threads costs 0.2-0.5 ms: a run of one item (a scan's one contact,
    through the smallest-pair search and the contact points) calls its kernel in the
    calling thread whatever --workers says; two items with two workers use the threads."""
    import threading

    from collide import pipeline
    threads = []

    def kernel(start, stop):
        threads.append(threading.current_thread())
        return stop - start
    assert pipeline._run_chunks(kernel, (), (), 1, 2, None) == [1]
    assert threads == [threading.current_thread()]
    threads.clear()
    assert sum(pipeline._run_chunks(kernel, (), (), 2, 2, None)) == 2
    assert threads and threading.current_thread() not in threads


def test_with_two_workers_the_last_chunks_share_what_is_left(monkeypatch):
    """Chunk sizes follow the measured cost per item (here a fake 1 µs, so a chunk of
    CHUNK_SECONDS would hold more items than the run has): one probe per worker first,
    then what is not finished is split between the workers instead of going to one
    chunk that runs alone."""
    from collide import pipeline
    monkeypatch.setattr(pipeline, "_timed_call",
                        lambda kernel, shared, start, stop, extra: (1e-6 * (stop - start), (start, stop)))
    chunks = pipeline._run_chunks(None, (), (), 2000, 2, None)
    assert [start for start, _ in chunks] == [0] + [stop for _, stop in chunks[:-1]] and chunks[-1][1] == 2000
    assert [stop - start for start, stop in chunks] == [125, 125, 938, 812]
