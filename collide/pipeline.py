"""The main job, wired stage by stage: load -> build BVHs -> broad + narrow phase per
chunk of frames (in parallel) -> contact intervals -> result (-> file).
"""
import datetime
import hashlib
import os
import platform
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field

import numpy as np

from . import config
from ._version import __version__
from .closest import contact_point
from .contacts import (TRIANGLE_PAIR_COLUMNS, columns_from_rows, intervals_from_hits,
                       sort_columns)
from .discrete import ONLY_STATIC_PAIRS, SKIP_STATIC_PAIRS, scan_frames
from .errors import UsageError
from .load import load_scene
from .packed import pack_scene, world_vertices

MODES = ("continuous", "discrete")


@dataclass
class ScanResult:
    """What a scan found; ``contacts`` and ``triangle_pairs`` are dicts of numpy columns (SPEC §4)."""
    object_names: list
    object_meshes: list
    object_triangles: np.ndarray
    frame_time: np.ndarray
    frame_index: np.ndarray
    contacts: dict
    triangle_pairs: dict
    mode: str
    interpolation: str
    provenance: dict
    versions: dict
    stats: dict = field(default_factory=dict)


def parse_frames(frames, n_frames):
    """Frame indices selected by ``frames``: None, a slice, or "START:STOP[:STEP]"."""
    if frames is None:
        return np.arange(n_frames)
    if isinstance(frames, str):
        parts = frames.split(":")
        if len(parts) not in (2, 3):
            raise UsageError(f"--frames {frames!r}: expected START:STOP (Python slice, e.g. 0:100 or -50:)")
        try:
            frames = slice(*(int(p) if p.strip() else None for p in parts))
        except ValueError:
            raise UsageError(f"--frames {frames!r}: expected integers in START:STOP") from None
    if frames.step is not None and frames.step <= 0:
        raise UsageError("frames: the step must be positive")
    index = np.arange(n_frames)[frames]
    if index.size == 0:
        raise UsageError(f"frames {frames.start}:{frames.stop} selects no frame of the {n_frames} in the trajectory")
    return index


def versions():
    import h5py
    import numba
    import trimesh
    return {"collide": __version__, "python": platform.python_version(), "numpy": np.__version__,
            "numba": numba.__version__, "trimesh": trimesh.__version__, "h5py": h5py.__version__}


def _sha256(path):
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _frame_chunks(n_frames, workers):
    size = max(1, min(64, -(-n_frames // (8 * workers))))
    return [(s, min(s + size, n_frames)) for s in range(0, n_frames, size)]


def _run_discrete(ps, poses, static, collect_pairs, workers, progress):
    """Frame hits and triangle pairs of all frames, chunks run in parallel threads."""
    n_frames = poses.shape[0]
    chunks = _frame_chunks(n_frames, workers)
    results = [None] * len(chunks)
    done = 0
    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(scan_frames, ps, poses, static, s, e, SKIP_STATIC_PAIRS,
                               collect_pairs): i for i, (s, e) in enumerate(chunks)}
        try:
            for future in as_completed(futures):
                i = futures[future]
                results[i] = future.result()
                done += chunks[i][1] - chunks[i][0]
                if progress is not None:
                    progress(done, n_frames)
        except BaseException:
            for future in futures:
                future.cancel()
            raise
    hits = [r[0] for r in results]
    pairs = [r[1] for r in results]
    if static.sum() >= 2:  # static pairs: test once, then repeat for every frame
        s_hits, s_pairs = scan_frames(ps, poses, static, 0, 1, ONLY_STATIC_PAIRS, collect_pairs)
        hits.append(_repeat_over_frames(s_hits, n_frames))
        pairs.append(_repeat_over_frames(s_pairs, n_frames))
    return np.concatenate(hits).reshape(-1, 6), np.concatenate(pairs).reshape(-1, 5)


def _repeat_over_frames(rows, n_frames):
    """Rows of frame 0 (first column = frame) repeated for every frame."""
    out = np.repeat(rows[None, :, :], n_frames, axis=0)
    out[:, :, 0] = np.arange(n_frames)[:, None]
    return out.reshape(-1, rows.shape[1])


def _fill_contact_points(contacts, scene, poses):
    """World contact point of each contact's (tri_a, tri_b) at its first frame."""
    for k in range(contacts["object_a"].shape[0]):
        f = contacts["frame_begin"][k]
        tris = []
        for side, tri in (("object_a", "tri_a"), ("object_b", "tri_b")):
            o = contacts[side][k]
            mesh = scene.meshes[scene.object_mesh[o]]
            corners = mesh.vertices[mesh.faces[contacts[tri][k]]]
            tris.append(world_vertices(corners, poses[f, o]))
        point, _ = contact_point(tris[0], tris[1])
        contacts["point_x"][k], contacts["point_y"][k], contacts["point_z"][k] = point


def scan(meshes, trajectory, mode="continuous", split="sah", leaf_size=None,
         triangle_pairs=False, frames=None, workers=None, scheduler=None,
         time_tol=config.TIME_TOL, output=None, progress=None, command=None):
    """Find when, where and for how long the meshes touch along the trajectory.

    Parameters mirror ``collide scan`` (SPEC §1). ``progress(done, total)`` is
    called as frames complete. With ``output`` the result is also written there
    (atomically). Returns a ScanResult.
    """
    if mode not in MODES:
        raise UsageError(f"unknown mode {mode!r}; expected one of {', '.join(MODES)}")
    if mode == "continuous":
        raise UsageError("--mode continuous is not available yet in this version; use --mode discrete")
    if scheduler is not None:
        raise UsageError("--scheduler (Dask) is not available yet in this version")
    workers = (os.cpu_count() or 1) if workers is None else int(workers)
    if workers < 1:
        raise UsageError(f"workers must be >= 1, got {workers}")
    timings = {}
    start = time.perf_counter()
    scene = load_scene(meshes, trajectory)
    index = parse_frames(frames, scene.time.shape[0])
    poses = np.ascontiguousarray(scene.poses[index])
    frame_time = scene.time[index]
    timings["load_s"] = time.perf_counter() - start

    ps, timings["build_s"] = pack_scene(scene.meshes, scene.object_mesh, split, leaf_size)

    start = time.perf_counter()
    hits, pair_rows = _run_discrete(ps, poses, scene.static, triangle_pairs, workers, progress)
    contacts = intervals_from_hits(hits, frame_time)
    _fill_contact_points(contacts, scene, poses)
    pairs = None
    if triangle_pairs:
        pairs = sort_columns(columns_from_rows(pair_rows, TRIANGLE_PAIR_COLUMNS),
                             list(TRIANGLE_PAIR_COLUMNS))
    timings["scan_s"] = time.perf_counter() - start

    parameters = {"mode": mode, "split": split, "leaf_size": leaf_size or config.DEFAULT_LEAF_SIZE,
                  "triangle_pairs": bool(triangle_pairs), "frames": None if frames is None else str(frames),
                  "workers": workers, "time_tol": time_tol}
    result = ScanResult(
        object_names=list(scene.names),
        object_meshes=[scene.meshes[m].path.name for m in scene.object_mesh],
        object_triangles=np.array([scene.meshes[m].faces.shape[0] for m in scene.object_mesh]),
        frame_time=frame_time, frame_index=index, contacts=contacts, triangle_pairs=pairs,
        mode=mode, interpolation="linear-vertex" if mode == "continuous" else "none",
        provenance={}, versions=versions(),
        stats={**timings, "frames": int(index.size), "objects": len(scene.names),
               "contacts": int(contacts["object_a"].size), "frames_in_contact": int(np.unique(hits[:, 0]).size),
               "triangle_pairs": int(hits[:, 3].sum())},
    )
    result.provenance = {
        "command": command or f"collide.scan({str(meshes)!r}, {str(trajectory)!r}, mode={mode!r})",
        "created_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "inputs": {"trajectory": {"path": str(trajectory), "sha256": _sha256(scene.trajectory_path)},
                   "meshes": {m.path.name: _sha256(m.path) for m in scene.meshes}},
        "parameters": parameters,
        "versions": result.versions,
    }
    if output is not None:
        from .output import write_contacts
        write_contacts(output, result)
    return result
