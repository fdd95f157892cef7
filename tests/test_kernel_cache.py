"""The kernel cache is keyed by content: copies of collide at other paths reuse compiled
kernels, and a changed source file never loads a stale one; helpers compiled without
reference counting (jit.njit_borrowing) are used as that allows."""
import ast
import importlib
import inspect
import json
import os
import pkgutil
import shutil
import subprocess
import sys
import textwrap
import time
import types as pytypes
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO, write_trajectory
from numba.core import types as numba_types
from numba.core.registry import CPUDispatcher

import collide
from collide.jit import EntryKernelCache

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


# compiles the given warm-up units' kernels and counts the compilations of each function
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
for unit in sys.argv[2:]:
    warmup.compile_unit(unit)
print(json.dumps(compiled))
"""


@pytest.mark.slow
def test_the_scans_compile_one_copy_of_each_descent(tmp_path):
    """A constant passed to a compiled function is typed as a literal, and each literal
    value compiles a copy of that function and of everything it calls: the copies of the
    frame descent made the step scan's compile about a third longer. Each descent
    function is compiled once for both scans. The contact searches that the warm-up
    compiles in a process of their own (swept.compile_contact_searches) are the ones the
    step scan calls: compiled there, the step scan's process loads them from the cache
    and compiles no copy of its own."""
    env = {"COLLIDE_KERNEL_CACHE_DIR": str(tmp_path / "kernels"), "PATH": "/usr/bin:/bin"}
    counts = []
    for units in (["searches"], ["discrete", "continuous"]):
        proc = subprocess.run([sys.executable, "-c", COMPILES, str(REPO), *units], env=env, capture_output=True,
                              text=True, timeout=900)
        assert proc.returncode == 0, proc.stderr
        counts.append(json.loads(proc.stdout))
    searches, scans = counts
    for name in ("compile_contact_searches", "_one_sided_window", "candidates_contact_window",
                 "triangle_pair_contact"):
        assert searches.get(name) == 1 and scans.get(name) is None, (name, searches.get(name), scans.get(name))
    for name in ("scan_frames", "scan_intervals", "_descent_hit", "overlapping_leaves", "swept_leaves",
                 "intersecting_triangles", "triangle_pair_count"):  # in either process, once
        assert searches.get(name, 0) + scans.get(name, 0) == 1, (name, searches.get(name), scans.get(name))
    for name in ("_pair_triangles", "pair_leaves"):  # inlined into their callers (inline="always")
        assert scans.get(name) is None and searches.get(name) is None, name


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
    assert given == [["continuous", "discrete", "lbvh", "searches", "setup"],
                     ["continuous", "discrete", "searches", "setup"], ["continuous", "discrete", "searches", "setup"],
                     ["discrete", "lbvh", "setup"]]


@pytest.mark.parametrize("mode, groups", [("continuous", [["searches", "discrete"], ["continuous"]]),
                                          ("discrete", [["discrete"]])])
def test_a_cold_scan_gives_every_unit_to_workers_says_so_and_stops_them_on_bad_input(
        two_boxes, tmp_path, monkeypatch, caplog, mode, groups):
    """On a cold kernel cache with two cores a scan starts one worker per core with every
    unit but the set-up kernels (its own process compiles those as it needs them), the
    step scan and its searches in different workers; it says at once that it compiles,
    and a bad input stops the workers (recorded here instead of started)."""
    import logging

    from collide import pipeline, warmup
    from collide.errors import InputError
    given, stopped = [], []

    class Recorder:
        def __init__(self, groups):
            given.append(groups)
            self.processes = groups

        def stop(self):
            stopped.append(True)

    monkeypatch.setattr(warmup, "start", Recorder)
    monkeypatch.setattr(warmup, "is_warm", lambda mode: False)
    monkeypatch.setattr(pipeline.os, "cpu_count", lambda: 2)
    meshes, _ = two_boxes
    with caplog.at_level(logging.WARNING, logger="collide"), pytest.raises(InputError):
        collide.scan(meshes, tmp_path / "missing.h5", mode=mode)
    assert given == [groups] and stopped == [True]
    count = len(groups)
    notes = [r.getMessage() for r in caplog.records if "compiling collide's numba kernels" in r.getMessage()]
    assert notes and notes[0].startswith(f"compiling collide's numba kernels for this machine in {count} worker "
                                         f"process{'es' if count > 1 else ''} (first run only"), notes


def _collide_dispatchers():
    """Every numba dispatcher defined in collide's modules."""
    found = {}
    for info in pkgutil.iter_modules(collide.__path__):
        module = importlib.import_module(f"collide.{info.name}")
        for value in vars(module).values():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == module.__name__:
                found[value.py_func.__module__ + "." + value.py_func.__qualname__] = value
    return found


def _called_dispatchers(dispatcher):
    """The dispatchers a kernel's source calls: by name, or as module.name."""
    names = dispatcher.py_func.__globals__
    called = []
    for node in ast.walk(ast.parse(textwrap.dedent(inspect.getsource(dispatcher.py_func)))):
        if not isinstance(node, ast.Call):
            continue
        target = None
        if isinstance(node.func, ast.Name):
            target = names.get(node.func.id)
        elif isinstance(node.func, ast.Attribute) and isinstance(node.func.value, ast.Name):
            owner = names.get(node.func.value.id)
            if isinstance(owner, pytypes.ModuleType):
                target = getattr(owner, node.func.attr, None)
        if isinstance(target, CPUDispatcher):
            called.append(target)
    return called


def _compiled_return_types(dispatcher):
    """Return types of every compiled version of ``dispatcher``: loaded in this process, or
    stored in the kernel cache for this source (callees of a kernel loaded from the cache
    are not loaded one by one)."""
    found = [cres.signature.return_type for cres in dispatcher.overloads.values()]
    cache = dispatcher._cache
    for key in cache._cache_file._load_index():
        cres = cache.load_overload(key[0], dispatcher.targetctx)
        if cres is not None:
            found.append(cres.signature.return_type)
    return found


def _holds_array(numba_type):
    if isinstance(numba_type, numba_types.Array):
        return True
    return isinstance(numba_type, numba_types.BaseTuple) and any(_holds_array(t) for t in numba_type.types)


def _turning_mover(traj):
    """two_boxes' trajectory with the mover also turning about z, a quarter turn over the
    run (screw motion between frames): written next to it."""
    n = 13
    angle = np.linspace(0.0, 0.5 * np.pi, n)
    orientation = np.zeros((n, 1, 4))
    orientation[:, 0, 0], orientation[:, 0, 3] = np.cos(0.5 * angle), np.sin(0.5 * angle)
    position = np.zeros((n, 1, 3))
    position[:, 0, 0] = np.linspace(-3.0, 3.0, n)
    return write_trajectory(traj.parent / "turning.h5", np.arange(n) * 0.1, ["mover"], position, orientation)


# scans twice (continuous, discrete, discrete with every triangle pair), the second time with
# numba's allocation statistics counted: what it allocated and freed
ALLOCATIONS = """
import gc, json, sys
sys.path.insert(0, sys.argv[1])
import collide
from numba.core.runtime import rtsys
def scans():
    for mode, pairs in (("continuous", False), ("discrete", False), ("discrete", True)):
        collide.scan(sys.argv[2], sys.argv[3], mode=mode, workers=1, triangle_pairs=pairs)
    gc.collect()
scans()
before = rtsys.get_allocation_stats()
scans()
after = rtsys.get_allocation_stats()
print(json.dumps({k: getattr(after, k) - getattr(before, k) for k in ("alloc", "free", "mi_alloc", "mi_free")}))
"""


def test_scans_free_every_array_numba_allocates(two_boxes):
    """With numba's allocation statistics on (NUMBA_NRT_STATS=1), scans of a turning body
    free every array numba allocates: one that a helper compiled without reference
    counting (jit.njit_borrowing) got back from a call would never be freed."""
    meshes, traj = two_boxes
    env = dict(os.environ, NUMBA_NRT_STATS="1")
    proc = subprocess.run([sys.executable, "-c", ALLOCATIONS, str(REPO), str(meshes), str(_turning_mover(traj))],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    counted = json.loads(proc.stdout)
    assert counted["mi_alloc"] > 100  # the statistics were on, and the scans allocated
    assert counted["mi_free"] == counted["mi_alloc"] and counted["free"] == counted["alloc"], counted


def test_borrowing_helpers_are_given_no_array_back(two_boxes):
    """A helper compiled by jit.njit_borrowing keeps no reference count: an array it
    returned, or was returned by a helper it calls, would be counted once too few or too
    many (freed while in use, or never freed). So no helper it reaches, marked or not,
    returns one, in any version compiled for the scans (numba itself refuses to compile
    an allocation in them)."""
    meshes, traj = two_boxes
    turning = _turning_mover(traj)
    for trajectory, mode in ((traj, "discrete"), (turning, "continuous"), (turning, "discrete")):
        assert collide.scan(meshes, trajectory, mode=mode, workers=1).contacts["object_a"].size > 0

    dispatchers = _collide_dispatchers()
    borrowing = [d for d in dispatchers.values() if d.targetoptions.get("_nrt") is False]
    assert len(borrowing) > 100
    reached, todo = {}, list(borrowing)
    while todo:
        d = todo.pop()
        if id(d) not in reached:
            reached[id(d)] = d
            todo.extend(_called_dispatchers(d))
    # each says which it is (inlined ones become part of their caller), else numba compiles it
    # as its first caller is compiled: without the runtime, an allocation fails, or not, by order
    unmarked = sorted(d.py_func.__qualname__ for d in reached.values()
                      if "_nrt" not in d.targetoptions and d.targetoptions.get("inline") != "always")
    assert unmarked == []
    checked = 0
    for d in reached.values():
        for return_type in _compiled_return_types(d):
            assert not _holds_array(return_type), (d.py_func.__qualname__, return_type)
            checked += 1
    assert checked > 100  # the scans compiled (or loaded) most of them


def _names_dispatchers(dispatcher):
    """Every dispatcher a kernel's source names (called or not): by name, or as module.name."""
    names = dispatcher.py_func.__globals__
    found = []
    for node in ast.walk(ast.parse(textwrap.dedent(inspect.getsource(dispatcher.py_func)))):
        target = None
        if isinstance(node, ast.Name):
            target = names.get(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            owner = names.get(node.value.id)
            if isinstance(owner, pytypes.ModuleType):
                target = getattr(owner, node.attr, None)
        if isinstance(target, CPUDispatcher):
            found.append(target)
    return found


def _entry_kernels():
    return {name: d for name, d in _collide_dispatchers().items() if isinstance(d._cache, EntryKernelCache)}


def test_no_kernel_names_an_entry_kernel():
    """An njit_entry kernel's cache entry holds trapping stubs where numba keeps the code it
    would inline into a caller: a kernel that called (or was handed) one would trap."""
    entries = _entry_kernels()
    assert {"collide.swept.scan_intervals", "collide.discrete.scan_frames", "collide.discrete.smallest_touching_pairs",
            "collide.closest.contact_points"} <= set(entries)
    entry_ids = {id(d) for d in entries.values()}
    naming = sorted((name, other.py_func.__qualname__) for name, d in _collide_dispatchers().items()
                    for other in _names_dispatchers(d) if id(other) in entry_ids and other is not d)
    assert naming == []


def _trap_only(function):
    return [i.opcode for block in function.blocks for i in block.instructions] == ["call", "unreachable"]


def test_entry_kernels_are_stored_as_machine_code_and_symbol_names(two_boxes):
    """Each stored version of an entry kernel: the machine code, and in place of numba's
    bitcode a module of trapping stubs defining its entry points' names (which numba looks
    up after loading). Every scan of the suite runs the loaded kernels."""
    meshes, traj = two_boxes
    assert collide.scan(meshes, _turning_mover(traj), mode="continuous", workers=1).contacts["object_a"].size > 0
    checked = 0
    for name, dispatcher in _entry_kernels().items():
        cache = dispatcher._cache
        for key in cache._cache_file._load_index():
            cres = cache.load_overload(key[0], dispatcher.targetctx)
            module = cres.library._get_module_for_linking()
            defined = {f.name: f for f in module.functions if not f.is_declaration}
            assert defined and all(_trap_only(f) for f in defined.values()), name
            assert {cres.fndesc.llvm_func_name, cres.fndesc.llvm_cpython_wrapper_name} <= set(defined), name
            checked += 1
    assert checked >= 4


def test_symbol_stubs_name_what_other_modules_see_and_trap():
    """symbol_stubs keeps every visible definition's name (quotes, backslashes, non-ASCII
    bytes included) as a trapping function, and drops declarations and internal names."""
    import llvmlite.binding as llvm

    from collide.jit import symbol_stubs
    source = r"""
@"glob\22al" = common global i64 0
@hidden = internal global i64 0
define i64 @"f\5Cx"() { ret i64 1 }
define linkonce_odr i64 @"caf\C3\A9"() { ret i64 2 }
define internal i64 @inner() { ret i64 3 }
declare i64 @elsewhere()
"""
    stubs = llvm.parse_bitcode(symbol_stubs(llvm.parse_assembly(source).as_bitcode()))
    defined = {f.name: f for f in stubs.functions if not f.is_declaration}
    assert set(defined) == {'glob"al', "f\\x", "café"}
    assert all(_trap_only(f) for f in defined.values())
    assert not any(not g.is_declaration for g in stubs.global_variables)


def test_a_new_kernel_folder_prunes_old_folders_of_its_python_and_numba(tmp_path):
    """Making a kernel folder deletes the folders next to it of the same Python and numba
    versions beyond the KEEP_KERNEL_FOLDERS most recently used (modification times)
    that were not used within KEEP_RECENT_SECONDS; folders of another Python or numba
    (other environments), recently used ones and other entries stay, and a run that
    finds its folder deletes nothing and marks it used."""
    from collide.jit import KEEP_KERNEL_FOLDERS, KEEP_RECENT_SECONDS, kernel_cache_dir
    kernels = tmp_path / "kernels"
    tag = kernel_cache_dir().name.split("-", 2)[2]  # py<X.Y>-numba<version>
    old = [kernels / f"0.0.{k}-{k:016x}-{tag}" for k in range(KEEP_KERNEL_FOLDERS + 2)]
    for age, folder in enumerate(old):  # old[0] used last, all of them long ago
        folder.mkdir(parents=True)
        (folder / "kernel.nbi").write_bytes(b"compiled")
        os.utime(folder, (1e9 - 1000 * age, 1e9 - 1000 * age))
    recent = [kernels / f"0.1.{k}-{k + 20:016x}-{tag}" for k in range(KEEP_KERNEL_FOLDERS)]
    for hours, folder in enumerate(recent, 1):  # the last one beyond the kept number, but used hours ago
        folder.mkdir()
        os.utime(folder, (time.time() - 3600 * hours, time.time() - 3600 * hours))
    strangers = ["notes", f"0.0.9-not-a-digest-{tag}", f"0.0.6-{6:016x}-py2.7-numba0.1.0",
                 f"0.0.5-{5:016x}-{tag}.bak"]
    for name in strangers:
        (kernels / name).mkdir()
        os.utime(kernels / name, (1.0, 1.0))
    (kernels / f"0.0.8-{8:016x}-{tag}").write_text("a file, not a folder")
    new = Path(probe(copy_package(tmp_path / "one"), kernels)["folder"])
    assert new.parent == kernels and new.name.endswith(tag)
    # kept: the new folder and the recent ones (used within KEEP_RECENT_SECONDS); every old one goes
    assert 3600 * len(recent) < KEEP_RECENT_SECONDS
    assert sorted(p.name for p in kernels.iterdir()) == sorted(
        [new.name, *(f.name for f in recent), *strangers, f"0.0.8-{8:016x}-{tag}"])
    for folder in recent:
        shutil.rmtree(folder)

    for folder in old:  # old ones back, more recent than the new folder
        folder.mkdir()
        os.utime(folder, (1e9, 1e9))
    os.utime(new, (1e9 - 10_000, 1e9 - 10_000))  # the oldest now; this run finds it
    probe(copy_package(tmp_path / "two"), kernels)
    assert all(folder.is_dir() for folder in old) and new.is_dir()
    assert new.stat().st_mtime > 1e9 + 1000  # marked used


def test_pruning_never_deletes_the_folder_in_use(tmp_path):
    """The current folder stays even when others look more recently used (a clock ahead,
    a restored cache); only the old folders beyond the kept number go."""
    from collide.jit import KEEP_KERNEL_FOLDERS, prune_kernel_folders
    tag = "py3.11-numba0.68.1"
    current = tmp_path / f"0.2.0-{1:016x}-{tag}"
    current.mkdir()
    os.utime(current, (1e9, 1e9))
    future = [tmp_path / f"0.3.{k}-{k:016x}-{tag}" for k in range(KEEP_KERNEL_FOLDERS)]
    older = tmp_path / f"0.1.0-{2:016x}-{tag}"
    for folder in future:
        folder.mkdir()
        os.utime(folder, (4e9, 4e9))
    older.mkdir()
    os.utime(older, (1e6, 1e6))
    assert prune_kernel_folders(current) == [str(older)]
    assert current.is_dir() and all(f.is_dir() for f in future) and not older.exists()
