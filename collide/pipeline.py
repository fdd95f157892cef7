"""The main job, wired stage by stage: load -> build BVHs -> broad + narrow phase per
chunk of frames (in parallel) -> contact intervals -> result (-> file).
"""
import datetime
import functools
import hashlib
import importlib
import logging
import os
import platform
import time
from collections import deque
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, nullcontext
from typing import NamedTuple

import numpy as np

from . import config
from ._version import __version__
from .bvh import builder_kernels
from .closest import contact_points
from .contacts import (
    CONTACT_COLUMNS,
    KIND_SWEPT,
    TRIANGLE_PAIR_COLUMNS,
    columns_from_rows,
    intervals_from_hits,
    intervals_from_steps,
    merge_contacts,
    sort_columns,
)
from .discrete import scan_frames, smallest_touching_pairs
from .errors import InputError, UsageError, stop_request
from .files import parse_size
from .filters import build_filters, describe
from .jit import kernel_cache_dir, thread_limit
from .jit_events import announce, compile_notice
from .load import MEMORY_TRAJECTORY, input_files, load_scene
from .meshcache import MeshCache
from .motion import INTERPOLATIONS, motion_summary
from .output import TrianglePairWriter, atomic_hdf5, check_output_path, signals_held, write_result
from .packed import pack_scene
from .result import ScanResult
from .rows import (
    COUNT_NAMES,
    COUNT_WIDTH,
    HIT_A,
    HIT_B,
    HIT_FRAME,
    HIT_TRI_A,
    HIT_TRI_B,
    HIT_WIDTH,
    PAIR_FRAME,
    PAIR_WIDTH,
    SWEPT_A,
    SWEPT_B,
    SWEPT_STEP,
    SWEPT_TRI_A,
    SWEPT_TRI_B,
    SWEPT_WIDTH,
    T_END,
    TIMES_WIDTH,
)
from .swept import scan_intervals

log = logging.getLogger("collide")

#: log level of notes: facts a user should see by default that are not warnings
NOTE = 25
logging.addLevelName(NOTE, "note")

MODES = ("continuous", "discrete")


def versions():
    import h5py
    import numba

    from .load import trimesh_version
    return {"collide": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba.__version__, "trimesh": trimesh_version(), "h5py": h5py.__version__}


def _sha256(path):
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _arrays_sha256(*arrays):
    """sha256 of arrays' shapes, dtypes and bytes (inputs given in memory)."""
    digest = hashlib.sha256()
    for array in arrays:
        array = np.ascontiguousarray(array)
        digest.update(f"{array.dtype.str}{array.shape}".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def _api_call(meshes, trajectory, mode):
    """How a Python caller's scan is recorded in provenance/command."""
    def text(x):
        return "<in memory>" if isinstance(x, Mapping) else repr(str(x))
    return f"collide.scan({text(meshes)}, {text(trajectory)}, mode={mode!r})"


def mesh_label(mesh):
    """A mesh's file name, or its name when it was given in memory."""
    return mesh.name if mesh.path is None else mesh.path.name


def _inputs(scene, meshes_in, trajectory, digests):
    """Provenance of the inputs: paths (or "<in memory>") and sha256 of each (digests:
    {path: sha256} already computed); meshes by file name, with the folder they are in."""
    if scene.trajectory_path == MEMORY_TRAJECTORY:
        traj = {"path": "<in memory>", "sha256": _arrays_sha256(scene.time, scene.poses.array)}
    else:
        traj = {"path": str(trajectory), "sha256": _sha256(scene.trajectory_path)}
    meshes = {mesh_label(m): _arrays_sha256(m.vertices, m.faces) if m.path is None
              else digests.get(m.path) or _sha256(m.path) for m in scene.meshes}
    folder = str(meshes_in) if isinstance(meshes_in, (str, os.PathLike)) else "<in memory>"
    return {"trajectory": traj, "meshes_folder": folder, "meshes": meshes}


def _chunks(n_items, workers, max_size=64):
    """(start, stop) chunks of range(n_items): about 8 per worker, at most max_size items."""
    size = _chunk_size(n_items, workers, max_size, None)
    return [(s, min(s + size, n_items)) for s in range(0, n_items, size)]


#: seconds of work a local chunk is made to last at least, once the first chunks have
#: measured what an item costs: a kernel call costs a little on its own (its buffers, and
#: the pages of the meshes' size it touches first), which short scans of big meshes would
#: otherwise pay once per 1/8 of the work
CHUNK_SECONDS = 0.02
#: the same with one worker, which has no share of the work to balance with another: a
#: chunk then only paces the progress display (0.02 s chunks cost 3-8 % of a continuous
#: scan of 100 bodies or of 10 000 frames)
CHUNK_SECONDS_ONE_WORKER = 0.1
#: items of a one-worker scan's first chunk (untimed) at least: a short scan then makes one
#: kernel call, not two (a call of the step scan costs 0.1-0.3 ms on its own on two 100k-
#: triangle meshes, and the chunk's first frame test as much again)
FIRST_CHUNK_ONE_WORKER = 64


def _chunk_size(n_items, workers, max_size, seconds_per_item, left=None):
    """Items in the next chunk of range(n_items): about 1/8 of a worker's share (one
    worker's first: at least FIRST_CHUNK_ONE_WORKER), or more when items are cheap
    (CHUNK_SECONDS, or CHUNK_SECONDS_ONE_WORKER, at seconds_per_item, once measured), but
    with several workers at most an equal share of the ``left`` items not yet finished
    (the last chunks then run side by side, not one alone); at most max_size (None: no
    limit)."""
    size = -(-n_items // (8 * workers))
    if seconds_per_item is None and workers == 1:
        size = max(size, FIRST_CHUNK_ONE_WORKER)
    elif seconds_per_item is not None:
        seconds = CHUNK_SECONDS if workers > 1 else CHUNK_SECONDS_ONE_WORKER
        size = max(size, int(seconds / max(seconds_per_item, 1e-9)))
        if workers > 1 and left is not None:
            size = min(size, -(-left // workers))
    return max(1, size if max_size is None else min(max_size, size))


class _Progress:
    """Reports finished work to ``callback(done, total)`` in work units, so that the share
    done (and an ETA from it) follows time rather than item counts: a frame is one unit,
    a motion step (continuous mode) weighs what a step has cost so far per frame's cost
    (STEP_WEIGHT before both have been timed). Time between two reports is charged to
    the kind of item the second one reports. ``done`` never decreases and ends equal to
    ``total``; ``total`` is an estimate until then and may change as it improves.
    When the swept kernel runs the frame tests itself (_run_steps), only steps are
    counted (a step includes its last frame's test)."""

    #: the cost of a motion step in frames before any is timed (swept tests cost 1.5-3
    #: frame tests on the benchmark scenes: benchmarks/bench_frames.py, bench_bodies.py)
    STEP_WEIGHT = 2.0

    def __init__(self, n_frames, n_steps, callback, clock=time.perf_counter):
        self.left = {"frames": n_frames, "steps": n_steps}
        self.items = {"frames": 0, "steps": 0}
        self.seconds = {"frames": 0.0, "steps": 0.0}
        self.done = 0.0
        self.callback, self.clock = callback, clock
        self.last = clock()

    def step_weight(self):
        """Estimated cost of a motion step, in frames."""
        if self.items["frames"] and self.items["steps"] and self.seconds["frames"] > 0:
            return (self.seconds["steps"] / self.items["steps"]) / (self.seconds["frames"] / self.items["frames"])
        return self.STEP_WEIGHT

    def frames(self, n):
        """n more frames tested."""
        self._add("frames", n)

    def steps(self, n):
        """n more motion steps tested."""
        self._add("steps", n)

    def _add(self, kind, n):
        now = self.clock()
        self.seconds[kind] += now - self.last
        self.last = now
        self.items[kind] += n
        self.left[kind] -= n
        self.done += n * (1.0 if kind == "frames" else self.step_weight())
        if self.callback is not None:
            left = self.left["frames"] + self.left["steps"] * self.step_weight()
            self.callback(self.done, self.done + left)


def _run_chunks(kernel, shared, extra, n_items, workers, progress, scheduler=None):
    """kernel(*shared, start, stop, *extra) for chunks of range(n_items), in parallel: the
    list of results, in chunk order (see _chunk_results)."""
    return [result for _, result in _chunk_results(kernel, shared, extra, n_items, workers, progress, scheduler)]


def _chunk_results(kernel, shared, extra, n_items, workers, progress, scheduler=None, max_size=None):
    """Yield ((start, stop), kernel(*shared, start, stop, *extra)) for chunks of
    range(n_items), in chunk order, computed in parallel.

    Locally in ``workers`` threads (the kernels release the GIL, so threads use every
    core; one worker runs them in this thread, see _InThisThread, and a one-worker run
    of at most FIRST_CHUNK_ONE_WORKER items is a single call), chunks sized by
    _chunk_size from the time the finished ones took, at most 2 x workers chunks ahead
    of the one yielded, so a caller that streams results out (--triangle-pairs to a
    file) holds a bounded number of them.
    With ``scheduler`` (an address) as tasks on a Dask distributed cluster, with the
    shared arrays sent to the workers once (all results are gathered first). The order
    does not depend on scheduling.
    """
    if scheduler is not None:
        yield from _run_chunks_dask(kernel, shared, extra, n_items, progress, scheduler)
        return
    if n_items <= 1:
        workers = 1  # nothing to share out (a scan's one contact): no thread to start
    if workers == 1 and 0 < n_items <= min(FIRST_CHUNK_ONE_WORKER, max_size or n_items):
        with signals_held():  # one chunk, in this thread: the call itself (as _InThisThread makes it)
            result = kernel(*shared, 0, n_items, *extra)
        if progress is not None:
            progress(n_items)
        yield (0, n_items), result
        return
    ahead = 2 * workers if workers > 1 else 1
    items_done, seconds_done = 0, 0.0
    with ThreadPoolExecutor(max_workers=workers) if workers > 1 else _InThisThread() as pool:
        pending = deque()
        start = 0
        try:
            while start < n_items or pending:
                # before any chunk is timed, one per worker: a short scan then makes fewer calls
                while start < n_items and len(pending) < (ahead if items_done else workers):
                    rate = seconds_done / items_done if items_done else None
                    stop = min(n_items, start + _chunk_size(n_items, workers, max_size, rate, n_items - items_done))
                    pending.append(((start, stop), pool.submit(_timed_call, kernel, shared, start, stop, extra)))
                    start = stop
                (chunk_start, chunk_stop), future = pending.popleft()
                seconds, result = future.result()
                items_done += chunk_stop - chunk_start
                seconds_done += seconds
                if progress is not None:
                    progress(chunk_stop - chunk_start)
                yield (chunk_start, chunk_stop), result
        finally:
            for _, future in pending:
                future.cancel()


class _InThisThread:
    """A ThreadPoolExecutor's submit for one worker: the call runs in this thread when its
    result is asked for (no thread to start, no hand-over per chunk: in A/B runs of
    one-worker scans of 100 bodies a worker thread cost 2-13 % discrete and 1-2 %
    continuous, on a noisy machine)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        return False

    def submit(self, function, *args):
        return _Deferred(function, args)


class _Deferred(NamedTuple):
    function: object
    args: tuple

    def result(self):
        """The call's result. Stop signals are held back while it runs and delivered after
        (output.signals_held): in the main thread, Python would otherwise run their
        handlers while numba converts the kernel's result to Python objects, and the
        stop request would come out wrapped in numba's SystemError."""
        with signals_held():
            return self.function(*self.args)

    def cancel(self):
        return True


def _timed_call(kernel, shared, start, stop, extra):
    """(seconds, kernel(*shared, start, stop, *extra))."""
    began = time.perf_counter()
    result = kernel(*shared, start, stop, *extra)
    return time.perf_counter() - began, result


def _call_kernel(kernel, shared, start, stop, extra):
    return kernel(*shared, start, stop, *extra)


class KernelByName(NamedTuple):
    """A chunk kernel as Dask tasks carry it: by module and name, so that a worker
    imports it, compiled kernels cache included. A numba dispatcher pickled as such
    comes out on the worker as a copy without a cache, compiled afresh in every worker
    process (about 30 s for the frame tests)."""
    module: str
    name: str

    @classmethod
    def of(cls, kernel):
        """The reference to ``kernel`` (a module-level function or numba dispatcher)."""
        return cls(kernel.__module__, kernel.__name__)

    def __call__(self, *args):
        return getattr(importlib.import_module(self.module), self.name)(*args)


def _run_chunks_dask(kernel, shared, extra, n_items, progress, scheduler):
    """The Dask version of _chunk_results, as a list (collide must be installed on the
    workers)."""
    try:
        from distributed import Client
        from distributed import as_completed as dask_as_completed
    except ImportError:
        raise UsageError("--scheduler needs Dask distributed; install it with: pip install 'collide[dask]'") \
            from None
    try:
        client = Client(scheduler, timeout="10s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise UsageError(f"cannot reach the Dask scheduler at {scheduler!r} ({exc}); expected the address of "
                         "a running scheduler, e.g. tcp://host:8786") from None
    with client:
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        chunks = _chunks(n_items, 2 * n_workers)
        shared_future = client.scatter({"shared": shared}, broadcast=True, hash=False)["shared"]
        futures = [client.submit(_call_kernel, KernelByName.of(kernel), shared_future, s, e, extra, pure=False)
                   for s, e in chunks]
        index = {f.key: i for i, f in enumerate(futures)}
        results = [None] * len(chunks)
        for future in dask_as_completed(futures, loop=client.loop):
            i = index[future.key]
            results[i] = future.result()
            if progress is not None:
                progress(chunks[i][1] - chunks[i][0])
    return list(zip(chunks, results))


def _run_discrete(ps, poses, n_frames, offset, static, filters, pair_sink, workers, progress, scheduler=None):
    """Frame hits (H, HIT_WIDTH) (rows.py) and work counts of frames [0, n_frames) of a
    block of poses (T, N, 3, 4), for the object pairs filters.Filters selects; with a
    pair_sink (TrianglePairs), every intersecting triangle pair too, handed over chunk by
    chunk in output order. Frame numbers in the rows count from ``offset``, the block's
    first selected frame.

    Without pair_sink each object pair's search stops at its first intersecting
    triangle pair (see smallest_pairs_at_frames for the reported pair). Pairs of static
    objects are tested once and repeated for every frame.
    """
    collect = pair_sink is not None
    static_hits, static_pairs, counts = _static_hits(ps, poses, static, filters, collect)
    hits = []
    for (start, stop), (chunk_hits, chunk_pairs, chunk_counts) in _chunk_results(
            scan_frames, (ps, poses, static, filters.kernel_filter(extra_ignore=static)), (collect, not collect),
            n_frames, workers, progress, scheduler, max_size=config.PAIR_CHUNK_FRAMES if collect else None):
        hits.append(chunk_hits)
        counts.append(chunk_counts)
        if collect:
            chunk_pairs[:, PAIR_FRAME] += offset
            pair_sink.add(chunk_pairs, np.arange(start, stop) + offset, static_pairs)
    if static_hits is not None:
        hits.append(_repeat_over_frames(static_hits, np.arange(n_frames)))
    hits = _joined(hits, HIT_WIDTH)
    hits[:, HIT_FRAME] += offset
    return hits, _total_counts(counts)


def _static_hits(ps, poses, static, filters, collect):
    """The frame test of the pairs of static objects, at the first frame only (they never
    move): (hits, triangle pairs if collect, [work counts]), (None, None, []) when fewer
    than two objects are static."""
    if np.count_nonzero(static) < 2:
        return None, None, []
    hits, pairs, counts = scan_frames(ps, poses, static, filters.kernel_filter(only_within=static), 0, 1, collect,
                                      not collect)
    return hits, pairs, [counts]


def _scan_blocks(ps, poses, static, filters, pair_sink, continuous, interpolation, time_tol, dist_tol, workers,
                 progress, scheduler=None):
    """The frame tests and, when ``continuous``, the swept tests of every frame and motion
    step, a block of poses (PoseSource) at a time: each block also holds the next one's
    first frame, for the step in between. Without a pair_sink, continuous scans run
    the frame tests inside the swept kernel (_run_steps). Returns (hits (H,
    HIT_WIDTH), swept ids (R, SWEPT_WIDTH), swept fractions (R, TIMES_WIDTH), work
    counts), frames and steps numbered from the first selected frame. progress:
    callback(done, total) (_Progress; the steps count the frame tests they run)."""
    together = continuous and pair_sink is None
    n = poses.n_frames
    progress = _Progress(0 if together else n, max(n - 1, 0) if continuous else 0, progress)
    hits, ids, fractions, counts = [], [], [], []
    for offset, block in poses.blocks(overlap=1 if continuous else 0):
        own = min(poses.block, block.shape[0])  # frames of this block; the rest is the next one's first
        if together and block.shape[0] > 1:
            block_hits, block_ids, block_fractions, block_counts = _run_steps(
                ps, block, own, static, filters, interpolation, time_tol, dist_tol, workers, progress.steps,
                scheduler)
            hits.append(block_hits + _frame_shift(offset) if offset else block_hits)
            counts.append(block_counts)
        else:
            block_hits, block_counts = _run_discrete(ps, block, own, offset, static, filters, pair_sink, workers,
                                                     None if together else progress.frames, scheduler)
            hits.append(block_hits)
            counts.append(block_counts)
            if not continuous or block.shape[0] == 1:
                continue
            known = block_hits
            if block.shape[0] > own:  # what touches at the next block's first frame: only whether it does
                next_hits, _, _ = scan_frames(ps, block, static, filters.kernel_filter(extra_ignore=static), own,
                                              own + 1, False, True)
                known = np.concatenate([block_hits, next_hits.reshape(-1, HIT_WIDTH) + _frame_shift(offset)])
            block_ids, block_fractions, block_counts = _run_swept(
                ps, block, static, filters, known - _frame_shift(offset), interpolation, time_tol, dist_tol,
                workers, progress.steps, scheduler)
            counts.append(block_counts)
        if offset:
            block_ids[:, SWEPT_STEP] += offset
        ids.append(block_ids)
        fractions.append(block_fractions)
    return (_joined(hits, HIT_WIDTH), _joined(ids or [np.zeros((0, SWEPT_WIDTH), np.int64)], SWEPT_WIDTH),
            _joined(fractions or [np.zeros((0, TIMES_WIDTH))], TIMES_WIDTH), _total_counts(counts))


def _run_steps(ps, poses, n_frames, static, filters, interpolation, time_tol, dist_tol, workers, progress,
               scheduler=None):
    """Frame hits of frames [0, n_frames) of a block of poses (T, N, 3, 4) and the swept
    contacts of its T - 1 steps, the frame tests run by the swept kernel (each chunk
    of steps tests its first frame, then each step's last frame with the step):
    (hits (H, HIT_WIDTH), ids (R, SWEPT_WIDTH), fractions (R, TIMES_WIDTH), counts),
    numbered from the block's first frame."""
    static_hits, _, counts = _static_hits(ps, poses, static, filters, False)
    results = _run_chunks(_scan_steps, (ps, poses, static, filters.kernel_filter(extra_ignore=static)),
                          (n_frames, INTERPOLATIONS[interpolation], time_tol, dist_tol, config.ONE_SIDED_LEAVES,
                           config.PROBED_FACES, config.PROBE_LEAF_PAIRS),
                          poses.shape[0] - 1, workers, progress, scheduler)
    hits = [r[0] for r in results]
    if static_hits is not None:
        hits.append(_repeat_over_frames(static_hits, np.arange(n_frames)))
    return (_joined(hits, HIT_WIDTH), _joined([r[1] for r in results], SWEPT_WIDTH),
            _joined([r[2] for r in results], TIMES_WIDTH), _total_counts(counts + [r[3] for r in results]))


def _scan_steps(ps, poses, static, pairs, start, stop, n_frames, interpolation, time_tol, dist_tol, one_sided_leaves,
                probed_faces, probe_leaf_pairs):
    """The chunk of _run_steps for steps [start, stop): scan_intervals running the frame
    tests itself, frame start's first. Returns (hits of frames (start if start == 0,
    else start + 1: the chunk before reports frame start) to min(stop, n_frames - 1),
    ids, fractions, counts)."""
    hits, ids, fractions, counts = scan_intervals(ps, poses, static, pairs, _NO_KEYS, _NO_TRIS, start, stop, True,
                                                  interpolation, time_tol, dist_tol, one_sided_leaves, probed_faces,
                                                  probe_leaf_pairs)
    if start == 0 and stop < n_frames:  # every frame it tested is its own
        return hits, ids, fractions, counts
    frame = hits[:, HIT_FRAME]
    return hits[(frame < n_frames) & ((frame > start) | (start == 0))], ids, fractions, counts


#: scan_intervals' ``touching`` and ``touching_tris`` when it runs the frame tests itself
_NO_KEYS = np.zeros(0, np.int64)
_NO_TRIS = np.zeros((0, 2), np.int64)


def _joined(parts, width):
    """The rows of the arrays ``parts`` one after another, as (rows, width): the one
    non-empty part itself when there is only one (no copy)."""
    filled = [part for part in parts if part.size]
    if len(filled) == 1:
        return filled[0].reshape(-1, width)
    return np.concatenate(parts).reshape(-1, width)


def _frame_shift(offset):
    """int64 (HIT_WIDTH,): adds ``offset`` to a hit row's frame."""
    shift = np.zeros(HIT_WIDTH, np.int64)
    shift[HIT_FRAME] = offset
    return shift


def _total_counts(counts):
    """Sum of the kernels' work counts (int64 (COUNT_WIDTH,) arrays)."""
    total = np.zeros(COUNT_WIDTH, np.int64)
    for count in counts:  # np.sum of a list first copies it into one array: slower for the few here
        total += count
    return total


def smallest_pairs_at_frames(contacts, where, ps, poses, static, workers=1):
    """Set each contact's (tri_a, tri_b) that came from a frame hit holding the first pair
    found (Where.first_found: hits found without collecting pairs, which depends on
    the BVH and the chunks) to the smallest intersecting pair at that frame: a
    branch-and-bound search (discrete.smallest_touching_pairs) per such contact, in
    ``workers`` threads. poses: PoseSource (read a block of those frames at a time)."""
    steps, _, first_found = where
    rows = np.flatnonzero(first_found)
    if not rows.size:
        return
    rows = rows[np.argsort(steps[rows], kind="stable")]  # by frame: a frame's contacts share its placed vertices
    frames = np.ascontiguousarray(steps[rows], dtype=np.int64)
    for at, block, pose_rows, _ in _contact_blocks(frames, frames, poses):
        items = rows[at]
        pose_rows = np.ascontiguousarray(pose_rows, dtype=np.int64)
        wanted = np.empty((items.size, 2), np.int64)  # (a few numpy calls cheaper than np.stack on a first call)
        wanted[:, 0] = contacts["object_a"][items]
        wanted[:, 1] = contacts["object_b"][items]
        smallest = _joined([np.zeros((0, 2), np.int64)] + _run_chunks(
            smallest_touching_pairs, (ps, block, static, pose_rows, wanted), (), items.size, workers, None), 2)
        worst = smallest[:, 0].argmin()  # -1 where a contact has no intersecting pair (argmin: cheaper than any)
        if smallest[worst, 0] < 0:
            raise AssertionError(f"frame {steps[items[worst]]}: a contact found at this frame has no intersecting "
                                 f"triangle pair")
        contacts["tri_a"][items] = smallest[:, 0]
        contacts["tri_b"][items] = smallest[:, 1]


def _run_swept(ps, poses, static, filters, hits, interpolation, time_tol, dist_tol, workers, progress,
               scheduler=None):
    """Swept contacts (ids (R, SWEPT_WIDTH), fractions (R, TIMES_WIDTH); rows.py) of every
    motion step and work counts (static pairs excluded: they never move). The frame
    contacts ``hits`` (H, HIT_WIDTH) tell which ends of a step are known to touch."""
    n_steps = poses.shape[0] - 1
    if n_steps < 1:
        return np.zeros((0, SWEPT_WIDTH), np.int64), np.zeros((0, TIMES_WIDTH)), np.zeros(COUNT_WIDTH, np.int64)
    touching, touching_tris = frame_contacts(hits, static, poses.shape[1])
    results = _run_chunks(scan_intervals, (ps, poses, static, filters.kernel_filter(extra_ignore=static), touching,
                                           touching_tris),
                          (False, INTERPOLATIONS[interpolation], time_tol, dist_tol, config.ONE_SIDED_LEAVES,
                           config.PROBED_FACES, config.PROBE_LEAF_PAIRS),
                          n_steps, workers, progress, scheduler)
    return (_joined([r[1] for r in results], SWEPT_WIDTH), _joined([r[2] for r in results], TIMES_WIDTH),
            _total_counts([r[3] for r in results]))


def frame_contacts(hits, static, n_objects):
    """What the frame tests found, as scan_intervals looks it up: an object pair touching
    at both frames of a step touches over the whole step (a step's window runs from its
    earliest to its latest contact), one touching at one frame needs only the other
    end searched.

    hits int64 (H, HIT_WIDTH). Returns (keys, tris): keys int64 (K,) sorted
    swept.step_pair_key(frame, a, b) of the frame contacts of pairs not both static,
    tris int64 (K, 2) the triangle pair of each.
    """
    frame, a, b = hits[:, HIT_FRAME], hits[:, HIT_A], hits[:, HIT_B]
    moving = np.flatnonzero(~(static[a] & static[b]))
    keys, first = np.unique((frame[moving] * n_objects + a[moving]) * n_objects + b[moving], return_index=True)
    rows = hits[moving[first]]
    return (np.ascontiguousarray(keys, dtype=np.int64),
            np.ascontiguousarray(rows[:, [HIT_TRI_A, HIT_TRI_B]], dtype=np.int64))


def _static_steps(hits, static, n_steps):
    """Swept contacts (ids, fractions) of pairs of static objects: touching at frame 0 means
    touching throughout (the swept kernel skips them since they never move)."""
    first = hits[(hits[:, HIT_FRAME] == 0) & static[hits[:, HIT_A]] & static[hits[:, HIT_B]]]
    if not first.shape[0]:  # the usual case: no numpy calls for nothing
        return np.zeros((0, SWEPT_WIDTH), np.int64), np.zeros((0, TIMES_WIDTH))
    ids = np.zeros((first.shape[0] * n_steps, SWEPT_WIDTH), np.int64)
    for column, source in ((SWEPT_A, HIT_A), (SWEPT_B, HIT_B), (SWEPT_TRI_A, HIT_TRI_A), (SWEPT_TRI_B, HIT_TRI_B)):
        ids[:, column] = np.repeat(first[:, source], n_steps)
    ids[:, SWEPT_STEP] = np.tile(np.arange(n_steps), first.shape[0])
    fractions = np.zeros((ids.shape[0], TIMES_WIDTH))
    fractions[:, T_END] = 1.0
    return ids, fractions


def _repeat_over_frames(rows, frames):
    """Rows of frame 0 (hits or triangle pairs: column HIT_FRAME = PAIR_FRAME is the frame)
    repeated for each of ``frames`` (int64 (F,))."""
    out = np.repeat(rows[None, :, :], frames.shape[0], axis=0)
    out[:, :, HIT_FRAME] = frames[:, None]
    return out.reshape(-1, rows.shape[1])


class TrianglePairs:
    """Where a scan's intersecting triangle pairs go, chunk by chunk of frames, in output
    order (sorted by frame, object_a, object_b, tri_a, tri_b): to a writer (streamed
    into the output file: memory does not grow with the number of rows) or, without
    one, into memory (``columns()``)."""

    def __init__(self, writer=None):
        self.writer = writer
        self.kept = []
        self.count = 0

    def add(self, rows, frames, static_rows=None):
        """rows int64 (P, PAIR_WIDTH) of the consecutive frames (int64 (F,)); static_rows:
        the static pairs' rows of frame 0, to repeat for those frames."""
        if static_rows is not None and static_rows.shape[0]:
            rows = np.concatenate([rows, _repeat_over_frames(static_rows, frames)])
        columns = sort_columns(columns_from_rows(rows, TRIANGLE_PAIR_COLUMNS), list(TRIANGLE_PAIR_COLUMNS))
        self.count += rows.shape[0]
        if self.writer is not None:
            self.writer(columns)
        else:
            self.kept.append(columns)

    def columns(self):
        """All rows kept in memory, as output columns (None when they went to a writer)."""
        if self.writer is not None:
            return None
        if not self.kept:
            return columns_from_rows(np.zeros((0, PAIR_WIDTH), np.int64), TRIANGLE_PAIR_COLUMNS)
        return {name: np.concatenate([c[name] for c in self.kept]) for name in TRIANGLE_PAIR_COLUMNS}


def scene_size(ps, poses):
    """Diagonal of a box holding every object at every analysed frame (length units);
    poses: PoseSource."""
    centre = ps.centre[ps.object_mesh][None, :, None, :]                  # (1, N, 1, 3)
    radius = ps.sphere_radius[ps.object_mesh][:, None]                    # (N, 1)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for _, block in poses.blocks():
        # R centre + p, column by column (einsum took 5x as long on (T, N, 3, 3) blocks)
        world = (block[..., 0] * centre[..., 0] + block[..., 1] * centre[..., 1] + block[..., 2] * centre[..., 2]
                 + block[..., 3])                                         # (T, N, 3)
        # each object's extremes over the frames first: -r and +r do not change which is smallest
        lo = np.minimum(lo, (world.min(axis=0) - radius).min(axis=0))
        hi = np.maximum(hi, (world.max(axis=0) + radius).max(axis=0))
    return float(np.linalg.norm(hi - lo))


class _Worst(NamedTuple):
    """The largest value met so far of a per-(step, object) measure, where, and the
    screw's turn angle (radians) and linear deviation (length units) there."""
    value: float
    step: int
    obj: int
    angle: float
    deviation: float


def _motion_summaries(ps, poses):
    """Yield (first step, angle (K, N), deviation (K, N)) block by block of poses
    (PoseSource): each object's screw turn angle per step (radians; -1 for half a turn)
    and the largest distance between its straight vertex paths and its screw motion
    (motion.motion_summary)."""
    centres = np.ascontiguousarray(ps.centre[ps.object_mesh])
    radii = np.ascontiguousarray(ps.sphere_radius[ps.object_mesh])
    for start, block in poses.blocks(overlap=1):
        if block.shape[0] < 2:
            continue
        summary = np.empty((block.shape[0] - 1, block.shape[1], 2))
        motion_summary(block, centres, radii, summary)
        yield start, summary[..., 0], summary[..., 1]


def check_motion(scene, ps, poses, frame_index, interpolation, warn_angle):
    """Check how objects turn between frames (poses: PoseSource): raise InputError for a
    half turn under the screw motion (its axis is ambiguous); warn (once, the worst case)
    when a screw turns more than warn_angle degrees per frame, or when linear vertex
    paths depart from the rigid motion by more than config.LINEAR_DEVIATION_WARN_REL of
    the object's size."""
    names = scene.names
    size = 2.0 * ps.sphere_radius[ps.object_mesh]

    def frames(step):
        return f"frames {frame_index[step]} and {frame_index[step + 1]}"

    worst, above = None, 0
    for start, angle, deviation in _motion_summaries(ps, poses):
        if interpolation == "screw":
            if (angle < 0).any():
                step, obj = np.argwhere(angle < 0)[0]
                raise InputError(scene.trajectory_path, f"object {names[obj]!r} turns half a turn (180 degrees) "
                                 f"between {frames(start + step)}, so the direction of the turn is ambiguous",
                                 "less than half a turn per frame (sample the trajectory more finely)",
                                 dataset="poses")
            value = np.degrees(angle)
            above += int((value > warn_angle).sum())
        else:
            value = np.where(angle < 0, np.inf, deviation / np.maximum(size, np.finfo(float).tiny))
        step, obj = np.unravel_index(int(np.argmax(value)), value.shape)
        if worst is None or value[step, obj] > worst.value:
            worst = _Worst(value[step, obj], start + step, obj, angle[step, obj], deviation[step, obj])
    if worst is None:
        return
    if interpolation == "screw":
        if worst.value > warn_angle:
            log.warning("object %r turns by %.1f degrees between %s (%d steps above %g degrees); the "
                        "trajectory is probably under-sampled: sample it more finely", names[worst.obj],
                        worst.value, frames(worst.step), above, warn_angle)
        return
    if worst.value > config.LINEAR_DEVIATION_WARN_REL:
        how = "by half a turn" if worst.angle < 0 else f"up to {worst.deviation:.3g} length units"
        log.warning("object %r: between %s its straight vertex paths (--interpolation linear-vertex) depart "
                    "from its rigid motion %s (its size is %.3g; warning above %g of it); use "
                    "--interpolation screw or sample the trajectory more finely", names[worst.obj],
                    frames(worst.step), how, size[worst.obj], config.LINEAR_DEVIATION_WARN_REL)


def _fill_contact_points(contacts, where, ps, poses, interpolation, workers=1):
    """World contact point of each contact's (tri_a, tri_b) at its first moment
    (closest.contact_points, in ``workers`` threads).

    where = (step, u): the moment is fraction u of the step from frame step to
    step+1 (u = 0: the frame itself), where objects move as ``interpolation`` says.
    poses: PoseSource, read for a block's worth of frames at a time.
    """
    steps, fractions, _ = where
    if not steps.size:
        return
    point = np.zeros((steps.size, 3))
    fractions = np.ascontiguousarray(fractions, dtype=np.float64)
    steps = np.ascontiguousarray(steps, dtype=np.int64)
    next_frames = np.minimum(steps + 1, poses.n_frames - 1)
    for rows, block, row0, row1 in _contact_blocks(steps, next_frames, poses):
        _run_chunks(contact_points, (ps, np.ascontiguousarray(block, dtype=np.float64), rows, row0, row1, fractions,
                                     contacts["object_a"], contacts["object_b"], contacts["tri_a"], contacts["tri_b"],
                                     point), (interpolation == "screw",), rows.size, workers, None)
    contacts["point_x"][:], contacts["point_y"][:], contacts["point_z"][:] = point.T


def _contact_blocks(steps, next_frames, poses):
    """Yield (rows, poses, row0, row1) a block of frames at a time: the contacts ``rows``
    whose frames (steps, next_frames: int64 (C,)) that block holds (PoseSource.at), and
    the rows of each one's two frames in it. Usually every pose is in memory, one block
    in which frame f is row f: then one group, with no numpy call to find it."""
    if poses.n_frames <= poses.block:
        yield np.arange(steps.size), poses.read(0, poses.n_frames), steps, next_frames
        return
    frames = np.unique(np.concatenate([steps, next_frames]))
    if frames.size <= poses.block:
        groups = [(np.arange(steps.size), frames)]
    else:
        groups = _contact_groups(steps, next_frames, poses.block)
    for rows, group_frames in groups:
        block, block_rows = poses.at(group_frames)
        yield (rows, block, block_rows[np.searchsorted(group_frames, steps[rows])],
               block_rows[np.searchsorted(group_frames, next_frames[rows])])


def _contact_groups(steps, next_frames, block):
    """Yield (rows int64, frames int64 sorted): the contacts (rows of steps, next_frames:
    int64 (C,)) in groups whose frames (their steps and the frames after them) fit in a
    block of ``block`` frames, by step."""
    order = np.argsort(steps, kind="stable")
    sorted_steps = steps[order]
    unique_steps = np.unique(steps)
    per_group = max(1, block // 2)  # a group's steps and the frames after them fill a block
    for group in range(0, unique_steps.size, per_group):
        group_steps = unique_steps[group:group + per_group]
        first = np.searchsorted(sorted_steps, group_steps[0], side="left")
        last = np.searchsorted(sorted_steps, group_steps[-1], side="right")
        rows = order[first:last]
        yield rows, np.unique(np.concatenate([group_steps, next_frames[rows]]))


def _compile_note(continuous):
    """Announce on stderr when numba really compiles (a machine's first run: about a
    minute), never on warm runs (collide.jit_events); "n of m" counts the top-level
    kernels that _compile_kernels prepares."""
    return compile_notice([scan_frames, smallest_touching_pairs, contact_points, merge_contacts]
                          + ([scan_intervals] if continuous else []))


def _start_warm_up(mode):
    """On a machine whose kernel cache does not hold this mode's kernels yet, start
    compiling them (collide.warmup) in worker processes while the scan loads its
    inputs, one per core. The scan's own process compiles the set-up kernels as it
    needs them (BVH builder, motion summary, contact points: about 15 s, so that a bad
    input is still reported early) and nothing else: with every worker free from the
    start, the step scan and its contact searches compile side by side
    (warmup.PAIRED). Says so at once (the first run is slow). Returns the workers, or
    None when the cache is warm or there is one core only."""
    from . import warmup
    processes = os.cpu_count() or 1
    if warmup.is_warm(mode) or processes < 2:
        return None
    units = [u for u in warmup.MODE_UNITS[mode] if u != "setup"]
    workers = warmup.start(warmup.plan(units, min(processes, len(units))))
    count = len(workers.processes)
    try:
        announce(f"compiling collide's numba kernels for this machine in {count} worker "
                 f"process{'es' if count > 1 else ''} (first run only: a minute or two; later runs load them "
                 f"from {kernel_cache_dir()})")
    except BaseException:  # a stop signal in between: no worker left running
        workers.stop()
        raise
    return workers


def _finish_warm_up(workers):
    """Wait for the warm-up workers."""
    if workers is None:
        return
    _, seconds = workers.finish()
    announce(f"compiled the kernels in {seconds:.0f} s")


def _prepare(meshes, trajectory, mode, split, leaf_size, frames, time_tol, interpolation, warn_angle, ignore, only,
             glob, max_memory, allow_external_data, cache, compiling, workers, stage):
    """Load and check the inputs, build the BVHs, make the kernels ready (compiling, or
    waiting for the warm-up workers ``compiling``, on a first run). Returns (scene,
    packed scene, poses (load.PoseSource), frame index, filters, dist_tol, timings)."""
    timings = {}
    start = time.perf_counter()
    mesh_cache = MeshCache(enabled=cache)
    stage("loading inputs")
    scene = load_scene(meshes, trajectory, allow_external=allow_external_data, max_memory=max_memory,
                       glob=glob, mesh_loader=mesh_cache.load_mesh, frames=frames)
    filters = build_filters(scene.names, ignore, only, scene.ignore, scene.trajectory_path)
    index, poses = scene.frame_index, scene.poses
    timings["load_s"] = time.perf_counter() - start
    continuous = mode == "continuous"
    stage(f"building BVHs ({len(scene.meshes)} meshes)")
    # a parallel builder (lbvh) uses at most the scan's threads. A rule's first use on a
    # warm cache compiles its builder: say so (on a cold first run the warm-up says it all)
    with thread_limit(workers), compile_notice(builder_kernels(split)) if compiling is None else nullcontext():
        ps, timings["build_s"] = pack_scene(scene.meshes, scene.object_mesh, split, leaf_size,
                                            build_bvh=mesh_cache.build_mesh_bvh, workers=workers)
    start = time.perf_counter()
    stage("preparing kernels")
    dist_tol = config.DIST_TOL_REL * scene_size(ps, poses)
    if continuous:
        check_motion(scene, ps, poses, index, interpolation, warn_angle)
    no_poses = np.zeros((1, poses.n_objects, 3, 4))  # a block's type, to compile or load the kernels with
    if compiling is not None:
        compile_result_kernels(ps, no_poses)  # here, while the workers compile the big kernels
    _finish_warm_up(compiling)
    with _compile_note(continuous):
        _compile_kernels(ps, no_poses, scene.static, filters, continuous, interpolation, time_tol, dist_tol)
    _mark_warm(mode)
    timings["jit_s"] = time.perf_counter() - start
    timings["cache"] = {"enabled": bool(cache), **mesh_cache.stats.as_dict(), "digests": mesh_cache.digests}
    return scene, ps, poses, index, filters, dist_tol, timings


def _mark_warm(mode):
    """Record that the kernels of this mode, and of every mode whose kernels it includes
    (a continuous scan prepares the discrete ones too), are ready."""
    from . import warmup
    for other, units in warmup.MODE_UNITS.items():
        if set(units) <= set(warmup.MODE_UNITS[mode]):
            warmup.mark_warm(other)


def _compile_kernels(ps, poses, static, filters, continuous, interpolation, time_tol, dist_tol):
    """Call every kernel of a scan once on no work, so that compiling (first run) or
    loading them from numba's cache happens here, before the progress bar."""
    pair_filter = filters.kernel_filter()
    scan_frames(ps, poses, static, pair_filter, 0, 0, False, True)
    if continuous:
        scan_intervals(ps, poses, static, pair_filter, np.zeros(0, np.int64), np.zeros((0, 2), np.int64), 0, 0, True,
                       INTERPOLATIONS[interpolation], time_tol, dist_tol, config.ONE_SIDED_LEAVES, config.PROBED_FACES,
                       config.PROBE_LEAF_PAIRS)
    smallest_touching_pairs(ps, poses, static, np.zeros(0, np.int64), np.zeros((0, 2), np.int64), 0, 0)
    compile_result_kernels(ps, poses)


def compile_result_kernels(ps, poses):
    """Compile (or load) the kernels that turn a scan's rows into contacts, the merge into
    intervals and the contact points (warm-up unit "setup" with the BVH builder
    and the motion checks, which run before this), on no contacts."""
    merge_contacts(np.zeros((0, SWEPT_WIDTH), np.int64), np.zeros((0, TIMES_WIDTH)), np.zeros((0, HIT_WIDTH), np.int64),
                   np.zeros(1), False)
    none = np.zeros(0, np.int64)
    ids = np.zeros(0, CONTACT_COLUMNS["object_a"])
    contact_points(ps, np.ascontiguousarray(poses, dtype=np.float64), none, none, none, np.zeros(0), ids, ids, ids, ids,
                   np.zeros((0, 3)), 0, 0, True)


def _check_options(mode, interpolation, workers, split, leaf_size, time_tol, warn_angle, frames, max_memory):
    """scan's options checked as the command line checks them (UsageError naming the
    option); returns (workers, leaf_size, time_tol, warn_angle) as int and float, so that
    kernels compile once whatever numeric types come in."""
    if mode not in MODES:
        raise UsageError(f"unknown mode {mode!r}; expected one of {', '.join(MODES)}")
    if interpolation not in INTERPOLATIONS:
        raise UsageError(f"unknown interpolation {interpolation!r}; expected one of {', '.join(INTERPOLATIONS)}")
    if split not in config.SPLIT_RULES:
        raise UsageError(f"unknown split {split!r}; expected one of {', '.join(config.SPLIT_RULES)}")
    workers = (os.cpu_count() or 1) if workers is None else \
        _whole("workers", workers, 1, config.MAX_WORKERS)
    if leaf_size is not None:
        leaf_size = _whole("leaf_size", leaf_size, 1, config.MAX_LEAF_SIZE)
    time_tol = _real("time_tol", time_tol, 0.0, 1.0, "a fraction of the frame interval in (0, 1]", open_low=True)
    warn_angle = _real("warn_angle", warn_angle, 0.0, 180.0, "degrees per frame in [0, 180]")
    if not (frames is None or isinstance(frames, str) or (isinstance(frames, slice) and all(
            v is None or _is_whole(v) for v in (frames.start, frames.stop, frames.step)))):
        raise UsageError(f"frames {frames!r}: not a slice of frame indices; expected None, a slice of integers "
                         "or 'START:STOP[:STEP]'")
    if max_memory is not None:
        try:
            parse_size(max_memory)
        except ValueError as exc:
            raise UsageError(f"max_memory: {exc}; expected bytes or a size like 4G or 512M") from None
    return workers, leaf_size, time_tol, warn_angle


def _is_whole(value):
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _whole(name, value, low, high):
    """value as an int in [low, high], or UsageError."""
    if not _is_whole(value) or not low <= value <= high:
        raise UsageError(f"{name} {value!r}: expected a whole number from {low} to {high}")
    return int(value)


def _real(name, value, low, high, expected, open_low=False):
    """value as a float in [low, high] ((low, high] when open_low), or UsageError."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    number = float(value) if ok else np.nan
    if not (ok and (low < number if open_low else low <= number) and number <= high):
        raise UsageError(f"{name} {value!r}: expected {expected}")
    return number


def _stop_requests_unwrapped(function):
    """A Ctrl-C (or collide's Terminated) that lands while numba hands a kernel's result
    back comes out of numba as a SystemError around it (errors.stop_request): raise the
    stop request itself, so that callers of the API see KeyboardInterrupt."""
    @functools.wraps(function)
    def unwrapped(*args, **kwargs):
        try:
            return function(*args, **kwargs)
        except SystemError as exc:
            stop = stop_request(exc)
            if stop is None:
                raise
            raise stop from None
    return unwrapped


@_stop_requests_unwrapped
def scan(meshes, trajectory, mode="continuous", split="sah", leaf_size=None,
         triangle_pairs=False, frames=None, workers=None, scheduler=None,
         time_tol=config.TIME_TOL, interpolation="screw", warn_angle=config.SCREW_WARN_DEG,
         ignore=(), only=(), glob=None, output=None, progress=None, stage=None, command=None, max_memory=None,
         allow_external_data=False, cache=True):
    """Find when, where and for how long the meshes touch along the trajectory.

    Parameters mirror ``collide scan``; ``time_tol`` is a fraction of the frame
    interval; ``interpolation`` ("screw" or "linear-vertex") the motion between
    frames in continuous mode; ``warn_angle`` (degrees per frame) where screw
    motion warns of under-sampling; ``ignore`` and ``only``: object pairs to skip,
    or to check alone, as 'A:B' name globs or (A, B) pairs (added to the
    trajectory's filters/ignore); ``glob``: which files of the meshes folder are
    meshes. ``progress(done, total)`` is called as work completes, in work units
    (floats): a frame is one unit, a motion step (continuous mode) weighs what steps
    have cost per frame's cost so far; ``total`` is an estimate that may change until
    ``done`` reaches it; ``stage(text)`` as each stage begins ("loading inputs",
    "building BVHs (N meshes)", "preparing kernels", "scanning", "contact points"). With
    ``output`` the result is also written there (atomically; never over an input), and
    triangle pairs (``triangle_pairs=True``) go only there, as frames finish: the
    returned result's triangle_pairs is then None (read_contacts(output) has them).
    Options are checked as the command line checks them (UsageError); a Ctrl-C raises
    KeyboardInterrupt.
    ``max_memory`` and ``allow_external_data``: see load.load_trajectory. ``cache=False``
    parses every mesh and builds every BVH afresh (see collide.meshcache). Returns a
    ScanResult.
    """
    workers, leaf_size, time_tol, warn_angle = _check_options(mode, interpolation, workers, split, leaf_size,
                                                              time_tol, warn_angle, frames, max_memory)
    ignore, only = ([p] if isinstance(p, str) else p for p in (ignore, only))  # one 'A:B' text: one pattern
    if glob is not None and isinstance(meshes, Mapping):
        raise UsageError(f"glob {glob!r}: chooses files of a meshes folder, but the meshes are in memory; "
                         "expected glob=None (every mesh given is used)")
    inputs = input_files(meshes, trajectory, glob) if output is not None else []
    if output is not None:
        check_output_path(output, inputs)  # fail before the work, not after
    compiling = _start_warm_up(mode) if scheduler is None else None
    stage = stage or (lambda text: None)
    try:
        scene, ps, poses, index, filters, dist_tol, timings = _prepare(
            meshes, trajectory, mode, split, leaf_size, frames, time_tol, interpolation, warn_angle, ignore, only,
            glob, max_memory, allow_external_data, cache, compiling, workers, stage)
    finally:
        if compiling is not None:
            compiling.stop()
    frame_time = scene.time[index]
    continuous = mode == "continuous"
    cache_stats = timings.pop("cache")
    with ExitStack() as stack:
        # with an output file, triangle pairs stream into it as frames finish
        h5 = stack.enter_context(atomic_hdf5(output, inputs, defer_signals=False)) if output is not None else None
        if scene.unlisted:  # once the inputs are good and the output is open: errors stay one line
            log.log(NOTE, "%d mesh%s not in the trajectory, static at %s mesh coordinates: %s",
                    len(scene.unlisted), "es" if len(scene.unlisted) > 1 else "",
                    "their" if len(scene.unlisted) > 1 else "its", ", ".join(scene.unlisted))
        pair_sink = None
        if triangle_pairs:
            pair_sink = TrianglePairs(TrianglePairWriter(h5) if h5 is not None else None)
        start = time.perf_counter()
        stage("scanning")
        hits, ids, fractions, counts = _scan_blocks(ps, poses, scene.static, filters, pair_sink, continuous,
                                                    interpolation, time_tol, dist_tol, workers, progress, scheduler)
        if continuous:
            static_ids, static_fractions = _static_steps(hits, scene.static, index.size - 1)
            contacts, where = intervals_from_steps(_joined([ids, static_ids], SWEPT_WIDTH),
                                                   _joined([fractions, static_fractions], TIMES_WIDTH), hits,
                                                   frame_time)
        else:
            contacts, where = intervals_from_hits(hits, frame_time)
        stage("contact points")
        if not triangle_pairs:
            smallest_pairs_at_frames(contacts, where, ps, poses, scene.static, workers)
        _fill_contact_points(contacts, where, ps, poses, interpolation, workers)
        timings["scan_s"] = time.perf_counter() - start
        result = _result(scene, meshes, trajectory, mode, split, leaf_size, triangle_pairs, frames, workers,
                         scheduler, time_tol, interpolation, glob, filters, command, index, frame_time, contacts,
                         pair_sink, hits, counts, timings, cache_stats)
        if h5 is not None:
            write_result(h5, result)
    return result


def _result(scene, meshes, trajectory, mode, split, leaf_size, triangle_pairs, frames, workers, scheduler,
            time_tol, interpolation, glob, filters, command, index, frame_time, contacts, pair_sink, hits, counts,
            timings, cache_stats):
    """The ScanResult of a scan: its findings, statistics and provenance."""
    parameters = {"mode": mode, "split": split, "leaf_size": leaf_size or config.DEFAULT_LEAF_SIZE,
                  "triangle_pairs": bool(triangle_pairs), "frames": None if frames is None else str(frames),
                  "workers": workers, "scheduler": scheduler, "time_tol": time_tol,
                  "interpolation": interpolation, "glob": glob, "filters": describe(filters)}
    result = ScanResult(
        object_names=list(scene.names),
        object_meshes=[mesh_label(scene.meshes[m]) for m in scene.object_mesh],
        object_triangles=np.array([scene.meshes[m].faces.shape[0] for m in scene.object_mesh]),
        frame_time=frame_time, frame_index=index, contacts=contacts,
        triangle_pairs=pair_sink.columns() if pair_sink is not None else None,
        mode=mode, interpolation=interpolation,
        provenance={}, versions=versions(),
        stats={**timings, "frames": int(index.size), "objects": len(scene.names),
               "contacts": int(contacts["object_a"].size),
               "swept_only_contacts": int((contacts["kind"] == KIND_SWEPT).sum()),
               "frames_in_contact": int(np.unique(hits[:, HIT_FRAME]).size),
               "triangle_pairs": pair_sink.count if pair_sink is not None else None,
               "static_objects": list(scene.unlisted), "filters": describe(filters),
               "work": {name: int(n) for name, n in zip(COUNT_NAMES, counts)},
               "cache": {k: v for k, v in cache_stats.items() if k != "digests"}},
    )
    result.provenance = {
        "command": command or _api_call(meshes, trajectory, mode),
        "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "inputs": _inputs(scene, meshes, trajectory, cache_stats["digests"]),
        "parameters": parameters,
        "versions": result.versions,
    }
    return result
