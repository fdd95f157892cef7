"""Compile collide's kernels before they are needed, several at a time (``collide warmup``).

A machine's first scan compiles the numba kernels it needs, one after another, on one
core; every later run loads them from the kernel cache (collide.jit). The kernels fall
into a few units: the frame scan (``discrete``), the step scan (``continuous``) and the
contact searches it calls (``searches``, compiled apart so that two processes share the
step scan's compile: see PAIRED), and the set-up kernels (BVH builder, motion summary,
contact point).
``start`` compiles units in separate Python processes (fresh interpreters, never
fork), each calling its kernels on a tiny scene in memory with no work to do: that
compiles exactly the specialisations a real scan uses and stores them in the shared
cache. A scan that finds the cache cold starts the workers at once (one per core),
validates its inputs meanwhile (so a bad input still fails at once, with its one-line
error, and stops the workers), compiles the set-up kernels itself as it needs them,
then waits for the workers and loads their kernels.

A marker file per mode and CPU in the kernel folder records that a scan of that mode
completed with warm kernels; without it, the next scan of that mode warms up first.

    python -m collide.warmup UNIT [UNIT ...]     # the worker: compile these units
"""
import functools
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

#: units of work and the kernels they compile
UNITS = {
    # the step scan in two parts (see PAIRED): its contact searches (with the CCD below
    # them), and scan_intervals itself, which loads them from the cache when it reaches
    # them, if the searches' process has cached them by then
    "searches": ("contact_searches",),
    "continuous": ("scan_intervals",),
    "discrete": ("scan_frames", "smallest_touching_pairs"),
    "setup": ("bvh", "motion", "contact_point"),
    "lbvh": ("lbvh",),
}
#: which units a scan of each mode needs (``lbvh``: only scans with ``--split lbvh``)
MODE_UNITS = {"discrete": ("discrete", "setup"), "continuous": ("searches", "continuous", "discrete", "setup")}
#: seconds each unit takes to compile (2-core machine, numba 0.68, 2026-12-07; the step
#: scan with its searches cached; for the discrete unit a planning figure between 28 s
#: alone and 7 s after the step scan, which compiles the kernels both share): for sharing
#: units among processes so that the longest process ends first possible
COMPILE_SECONDS = {"continuous": 70.0, "searches": 49.0, "discrete": 20.0, "setup": 15.0, "lbvh": 4.0}
#: the step scan's two parts. With two processes or more they start the first two: the
#: step scan reaches the searches about 45 s in, the searches' process has usually cached
#: them by then (else the step scan compiles them too), and the warm-up takes about 80 s
#: instead of 95 s on two cores. With one process, the searches go first.
PAIRED = ("searches", "continuous")


def plan(units, processes):
    """Share ``units`` among ``processes`` processes, longest unit first to the least
    loaded process (each process compiles its units one after another: a unit never
    waits for a core). With two processes or more the PAIRED units go to the first two,
    one each, before the others are shared; "continuous" is then moved last in its
    process (what goes before it gives its searches more time). Returns one list of
    units per process, in order."""
    def seconds(job):
        return sum(COMPILE_SECONDS.get(u, 1.0) for u in job)

    groups = [[] for _ in range(max(1, processes))]
    load = [0.0] * len(groups)
    jobs = [[u] for u in units if u not in PAIRED]
    paired = [u for u in PAIRED if u in units]
    if len(paired) == 2 and len(groups) >= 2:
        for i, unit in enumerate(paired):
            groups[i].append(unit)
            load[i] += seconds([unit])
    elif paired:
        jobs.append(paired)
    for job in sorted(jobs, key=lambda j: -seconds(j)):
        least = min(range(len(groups)), key=lambda i: (load[i], i))
        groups[least].extend(job)
        load[least] += seconds(job)
    return [sorted(group, key=lambda u: u == "continuous") for group in groups]


# --- is the cache warm? ------------------------------------------------------------------------

@functools.lru_cache(maxsize=1)
def cpu_key():
    """A short key of this machine's CPU as numba's cache sees it (name and features).
    Asked once per process, with stop signals held: llvmlite frees the strings it gets
    from LLVM twice when a Ctrl-C lands between its two steps (the process aborts)."""
    import llvmlite.binding as llvm
    from numba.core import config

    from .output import signals_held
    with signals_held():
        name = config.CPU_NAME or llvm.get_host_cpu_name()
        features = config.CPU_FEATURES if config.CPU_NAME else llvm.get_host_cpu_features().flatten()
    return hashlib.sha256(f"{name}|{features}".encode()).hexdigest()[:12]


def _marker(mode):
    from .jit import kernel_cache_dir
    return kernel_cache_dir() / f"warm-{mode}-{cpu_key()}.json"


def is_warm(mode):
    """A scan of this mode has completed on this CPU with the current kernel folder."""
    try:
        return _marker(mode).is_file()
    except OSError:
        return False


def mark_warm(mode):
    """Record that the kernels of ``mode`` are in the cache (best effort)."""
    try:
        _marker(mode).write_text(json.dumps({"mode": mode, "cpu": cpu_key()}))
    except OSError:
        pass


# --- worker processes --------------------------------------------------------------------------

class Workers:
    """Worker processes, each compiling a group of units one after another; ``finish``
    waits for them, ``stop`` ends them."""

    def __init__(self, groups):
        package_parent = str(Path(__file__).resolve().parent.parent)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package_parent, env.get("PYTHONPATH")) if p)
        self.start = time.perf_counter()
        self.groups = [list(group) for group in groups if group]
        self.processes = [subprocess.Popen([sys.executable, "-m", "collide.warmup", *group], env=env,
                                           stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                           stderr=subprocess.DEVNULL, text=True)
                          for group in self.groups]

    def finish(self, progress=None):
        """Wait for every worker; progress(units, seconds) as each ends ("a+b" for a
        group). Returns {units: seconds} (None for a worker that failed: the scan then
        compiles what it lacks itself) and the wall time."""
        seconds = {}
        try:
            for group, process in zip(self.groups, self.processes):
                out, _ = process.communicate()
                name = "+".join(group)
                seconds[name] = float(out.split()[-1]) if process.returncode == 0 and out.split() else None
                if progress is not None:
                    progress(name, seconds[name])
        except BaseException:
            self.stop()
            raise
        return seconds, time.perf_counter() - self.start

    def stop(self):
        """End the workers at once (the scan failed or was interrupted)."""
        for process in self.processes:
            if process.poll() is None:
                process.kill()
            process.wait()


def start(groups):
    """Workers compiling ``groups`` (lists of names of UNITS), one process per group."""
    return Workers(groups)


def warm_up(modes=("discrete", "continuous"), workers=None, progress=None, extra=()):
    """Compile (or load) the kernels that scans of ``modes`` need, and the ``extra``
    units: shared among ``workers`` processes (default: one per core) by ``plan``.
    Returns ({units: seconds}, wall seconds)."""
    units = [u for u in UNITS if u in extra or any(u in MODE_UNITS[mode] for mode in modes)]
    processes = min(len(units), max(1, workers or os.cpu_count() or 1))
    started = time.perf_counter()
    seconds, _ = start(plan(units, processes)).finish(progress)
    if all(s is not None for s in seconds.values()):
        for mode in modes:
            mark_warm(mode)
    return seconds, time.perf_counter() - started


# --- what a worker does ------------------------------------------------------------------------

def compile_unit(unit):
    """Compile (or load) the kernels of one unit on a tiny scene; returns seconds."""
    import numpy as np

    from .bvh import BVH, build_mesh_bvh
    from .filters import build_filters
    from .load import Mesh
    from .packed import pack_scene
    started = time.perf_counter()
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]], dtype=np.int64)
    meshes = [Mesh("a", None, vertices, faces), Mesh("b", None, vertices + 0.5, faces)]

    def one_leaf(v, f, split, leaf_size):  # a valid BVH without compiling the builder
        corners = v[f]
        return BVH(corners.min(axis=(0, 1))[None], corners.max(axis=(0, 1))[None], np.zeros(1, np.int64),
                   np.array([f.shape[0]], np.int64), np.arange(f.shape[0], dtype=np.int64))
    ps, _ = pack_scene(meshes, np.array([0, 1]), build_bvh=build_mesh_bvh if "bvh" in UNITS[unit] else one_leaf)
    poses = np.zeros((2, 2, 3, 4))
    poses[..., :3] = np.eye(3)
    static = np.zeros(2, dtype=bool)
    pairs = build_filters(["a", "b"]).kernel_filter()
    for kernel in UNITS[unit]:
        _KERNELS[kernel](ps, poses, static, pairs)
    return time.perf_counter() - started


def _scan_frames(ps, poses, static, pairs):
    from .discrete import scan_frames
    scan_frames(ps, poses, static, pairs, 0, 0, False, True)


def _smallest_touching_pairs(ps, poses, static, pairs):
    import numpy as np

    from .discrete import smallest_touching_pairs
    smallest_touching_pairs(ps, poses, static, np.zeros(0, np.int64), np.zeros((0, 2), np.int64), 0, 0)


def _scan_intervals(ps, poses, static, pairs):
    import numpy as np

    from . import config
    from .swept import scan_intervals
    scan_intervals(ps, poses, static, pairs, np.zeros(0, np.int64), np.zeros((0, 2), np.int64), 0, 0, True, 1, 1e-6,
                   1e-9, config.ONE_SIDED_LEAVES, config.PROBED_FACES, config.PROBE_LEAF_PAIRS)


def _contact_searches(ps, poses, static, pairs):
    from .swept import compile_contact_searches
    compile_contact_searches(ps, poses, static, 1e-6, 1e-9)


def _bvh(ps, poses, static, pairs):
    # compile_unit's pack_scene has built the BVHs with the real builder; the mesh
    # cache's check of a stored BVH runs this kernel
    from .bvh import in_smallest_id_order
    in_smallest_id_order(ps.node_first, ps.node_count, ps.prim_ids)


def _lbvh(ps, poses, static, pairs):
    import numpy as np

    from .bvh import build_bvh
    lo = np.arange(12.0).reshape(4, 3)
    build_bvh(lo, lo + 1.0, lo + 0.5, split="lbvh", leaf_size=1)


def _motion(ps, poses, static, pairs):
    import numpy as np

    from .motion import motion_summary
    motion_summary(poses, np.ascontiguousarray(ps.centre), np.ascontiguousarray(ps.sphere_radius),
                   np.empty((1, 2, 2)))


def _contact_point(ps, poses, static, pairs):
    from .pipeline import compile_result_kernels
    compile_result_kernels(ps, poses)


_KERNELS = {"scan_frames": _scan_frames, "smallest_touching_pairs": _smallest_touching_pairs,
            "scan_intervals": _scan_intervals, "contact_searches": _contact_searches, "bvh": _bvh, "lbvh": _lbvh,
            "motion": _motion, "contact_point": _contact_point}


if __name__ == "__main__":
    # a worker process (see start): its only output, on the pipe its parent reads, is
    # the compile time in seconds
    total = 0.0
    for name in sys.argv[1:]:
        total += compile_unit(name)
    sys.stdout.write(f"{total:.3f}\n")
