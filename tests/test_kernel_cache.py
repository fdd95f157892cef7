"""The kernel cache is keyed by content: copies of collide at other paths reuse compiled
kernels, and a changed source file never loads a stale one."""
import json
import shutil
import subprocess
import sys

import pytest
from conftest import REPO

# compiles one small kernel (the pair filter) and reports how many functions numba compiled
PROBE = """
import json, sys
sys.path.insert(0, sys.argv[1])
import numba.core.event as event
compiled = []
class Count(event.Listener):
    def on_start(self, e): compiled.append(e.data["dispatcher"].py_func.__qualname__)
    def on_end(self, e): pass
event.register("numba:compile", Count())
import collide
from collide.filters import build_filters, pair_selected
from collide.jit import kernel_cache_dir
assert collide.__file__.startswith(sys.argv[1]), collide.__file__
pair_selected(build_filters(["a", "b", "c"], ["a:b"]).kernel_filter(), 0, 1)
print(json.dumps({"compiled": compiled, "folder": str(kernel_cache_dir())}))
"""


def probe(package_parent, kernel_dir):
    env = {"COLLIDE_KERNEL_CACHE_DIR": str(kernel_dir), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run([sys.executable, "-c", PROBE, str(package_parent)], env=env, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def copy_package(target):
    shutil.copytree(REPO / "collide", target / "collide", ignore=shutil.ignore_patterns("__pycache__"))
    return target


def test_a_copy_at_another_path_reuses_the_compiled_kernels(tmp_path):
    kernels = tmp_path / "kernels"
    first = probe(copy_package(tmp_path / "one"), kernels)
    assert "pair_selected" in first["compiled"]
    second = probe(copy_package(tmp_path / "elsewhere" / "two"), kernels)
    assert second["compiled"] == [] and second["folder"] == first["folder"]


def test_a_changed_source_file_compiles_afresh(tmp_path):
    kernels = tmp_path / "kernels"
    first = probe(copy_package(tmp_path / "one"), kernels)
    changed = copy_package(tmp_path / "two")
    with open(changed / "collide" / "predicates.py", "a") as f:   # not even the kernel's own file
        f.write("\n# an edit\n")
    second = probe(changed, kernels)
    assert second["folder"] != first["folder"] and "pair_selected" in second["compiled"]


# compiles both scans' kernels and counts the compilations of each function
COMPILES = """
import collections, json, sys
sys.path.insert(0, sys.argv[1])
import numba.core.event as event
compiled = collections.Counter()
class Count(event.Listener):
    def on_start(self, e): compiled[e.data["dispatcher"].py_func.__qualname__] += 1
    def on_end(self, e): pass
event.register("numba:compile", Count())
from collide import warmup
for unit in ("discrete", "continuous"):
    warmup.compile_unit(unit)
print(json.dumps(compiled))
"""


@pytest.mark.slow
def test_the_scans_compile_one_copy_of_each_descent(tmp_path):
    """A constant passed to a compiled function is typed as a literal, and each literal
    value compiles a copy of that function and of everything it calls: the copies of the
    frame descent made the step scan's compile about a third longer. Each descent
    function is compiled once for both scans."""
    env = {"COLLIDE_KERNEL_CACHE_DIR": str(tmp_path / "kernels"), "PATH": "/usr/bin:/bin"}
    proc = subprocess.run([sys.executable, "-c", COMPILES, str(REPO)], env=env, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr
    compiled = json.loads(proc.stdout)
    for name in ("scan_frames", "scan_intervals", "_pair_triangles", "_descent_hit", "pair_leaves",
                 "overlapping_leaves", "swept_leaves", "intersecting_triangles", "triangle_pair_count"):
        assert compiled.get(name) == 1, (name, compiled.get(name))


def test_warmup_command_adds_the_lbvh_builder_only_when_asked(monkeypatch):
    """`collide warmup --split lbvh` also compiles the lbvh builder's unit; without it,
    or with a rule that shares the default builder, the unit is left out (the worker
    processes are replaced by a recorder: this checks what they would be given)."""
    from conftest import run_cli

    from collide import warmup
    given = []

    class Recorder:
        def __init__(self, groups):
            given.append(sorted(unit for group in groups for unit in group))

        def finish(self, progress=None):
            return {}, 0.0

    monkeypatch.setattr(warmup, "start", Recorder)
    monkeypatch.setattr(warmup, "mark_warm", lambda mode: None)  # nothing was compiled
    for args in (["--split", "lbvh"], [], ["--split", "median"], ["--mode", "discrete", "--split", "lbvh"]):
        assert run_cli("warmup", *args).returncode == 0
    assert given == [["continuous", "discrete", "lbvh", "setup"], ["continuous", "discrete", "setup"],
                     ["continuous", "discrete", "setup"], ["discrete", "lbvh", "setup"]]
