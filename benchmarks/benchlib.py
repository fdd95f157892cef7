"""Helpers shared by the scene benchmarks (bench_robot.py, bench_overlap.py).

- ``run_scan``: one ``collide scan ... --format json`` as a separate process: its wall
  time, exit code and JSON summary (``seconds``, ``work``, ``cache``);
- ``fcl_objects`` / ``fcl_frame_loop``: python-fcl's answer to the same question, frame by
  frame, for comparison (models built once, before timing);
- ``frame_pairs``: the (frame, object a, object b) set of a discrete contacts file;
- small things: medians, a plain-text table, the machine's load.
"""
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import NamedTuple

import h5py
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "tests"))

from fcl_poses import fcl_model  # noqa: E402

import collide  # noqa: E402


def collide_command():
    """The ``collide`` executable of this Python environment (or the one on PATH)."""
    local = Path(sys.executable).parent / "collide"
    return str(local) if local.exists() else shutil.which("collide") or "collide"


class Run(NamedTuple):
    """One collide process."""
    wall: float        #: whole process, seconds
    returncode: int
    summary: dict      #: the --format json summary (empty when none was printed)
    stderr: str


def run_scan(meshes, trajectory, output, *options, env=None):
    """Run ``collide scan MESHES TRAJECTORY -o OUTPUT --format json -q OPTIONS...`` and time it."""
    command = [collide_command(), "scan", str(meshes), str(trajectory), "-o", str(output), "--format", "json",
               "-q", *map(str, options)]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, env={**os.environ, **(env or {})})
    wall = time.perf_counter() - start
    if done.returncode not in (0, 1):
        raise RuntimeError(f"{' '.join(command)} exited {done.returncode}:\n{done.stderr}")
    lines = done.stdout.strip().splitlines()
    return Run(wall, done.returncode, json.loads(lines[-1]) if lines else {}, done.stderr)


def run_cli(*arguments):
    """Run ``collide ARGUMENTS...``; raise on failure; return its stdout."""
    done = subprocess.run([collide_command(), *map(str, arguments)], capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"collide {' '.join(map(str, arguments))} exited {done.returncode}:\n{done.stderr}")
    return done.stdout


def median(values):
    return statistics.median(values) if values else float("nan")


def parse_workers(text):
    """'1,2' -> [1, 2]."""
    return [int(w) for w in str(text).split(",") if w.strip()]


def machine_load():
    """The load averages (the machine is shared: read timings with them in mind)."""
    try:
        one, five, fifteen = os.getloadavg()
    except OSError:
        return "load average unknown"
    return f"load average {one:.2f}, {five:.2f}, {fifteen:.2f} ({os.cpu_count()} cores)"


def thread_headroom(seconds=0.5):
    """Speed-up of a trivially parallel numba loop (nogil) on two threads over one, now:
    about 2 on an idle 2-core machine, about 1 when other processes hold a core. Read
    the --workers 2 timings against it."""
    import threading

    from numba import njit

    @njit(nogil=True)
    def spin(n):
        s = 0.0
        for i in range(n):
            s += np.sin(i * 1e-9)
        return s

    spin(10)
    n = 1_000_000
    start = time.perf_counter()
    spin(n)
    n = int(n * seconds / max(time.perf_counter() - start, 1e-6))
    start = time.perf_counter()
    spin(n)
    one = time.perf_counter() - start
    threads = [threading.Thread(target=spin, args=(n // 2,)) for _ in range(2)]
    start = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return one / (time.perf_counter() - start)


def print_table(headers, rows):
    """Rows of strings/numbers as aligned columns (numbers right-aligned)."""
    text = [[c if isinstance(c, str) else f"{c:.4g}" for c in row] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in text)) for i, h in enumerate(headers)]
    print("  ".join(h.ljust(w) for h, w in zip(headers, widths)))
    for row, raw in zip(text, rows):
        print("  ".join(c.rjust(w) if not isinstance(x, str) else c.ljust(w)
                        for c, w, x in zip(row, widths, raw)))


def ratio(a, b):
    return a / b if b > 0 else float("inf")


# --- trajectories and results ---------------------------------------------------------------

def read_poses(trajectory):
    """(object names, poses float64 (T, N, 4, 4)) of a trajectory file (matrix or
    position + orientation form)."""
    with h5py.File(trajectory, "r") as f:
        names = list(f["objects/name"].asstr()[()])
        if "poses/matrix" in f:
            return names, f["poses/matrix"][()]
        position, q = f["poses/position"][()], f["poses/orientation"][()]
        order = f["poses/orientation"].attrs.get("quaternion_order", "wxyz")
    if isinstance(order, bytes):
        order = order.decode()
    w, x, y, z = np.moveaxis(q if order == "wxyz" else q[..., [3, 0, 1, 2]], -1, 0)
    poses = np.zeros(position.shape[:2] + (4, 4))
    poses[..., 0, :3] = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1)
    poses[..., 1, :3] = np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1)
    poses[..., 2, :3] = np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)
    poses[..., :3, 3] = position
    poses[..., 3, 3] = 1
    return names, poses


def frame_pairs(contacts):
    """{(frame, a, b)} (names, a < b by object index) of a discrete scan's contacts file."""
    result = collide.read_contacts(contacts)
    names, c = result.object_names, result.contacts
    out = set()
    for a, b, f0, f1 in zip(c["object_a"], c["object_b"], c["frame_begin"], c["frame_end"]):
        out.update((int(f), names[a], names[b]) for f in range(f0, f1 + 1))
    return out


def contact_pairs(contacts):
    """{(a, b): number of intervals} of a contacts file (names)."""
    result = collide.read_contacts(contacts)
    names, c = result.object_names, result.contacts
    pairs = {}
    for a, b in zip(c["object_a"], c["object_b"]):
        pairs[(names[a], names[b])] = pairs.get((names[a], names[b]), 0) + 1
    return pairs


# --- python-fcl -------------------------------------------------------------------------------

def fcl_objects(meshes):
    """{name: fcl.CollisionObject} of {name: collide Mesh} (OBBRSS BVH models, python-fcl's
    default), all at the identity. Returns (objects, build seconds)."""
    import fcl
    start = time.perf_counter()
    objects = {name: fcl.CollisionObject(fcl_model(fcl, mesh), fcl.Transform()) for name, mesh in meshes.items()}
    return objects, time.perf_counter() - start


def fcl_frame_loop(objects, names, poses, pairs, max_contacts=1):
    """python-fcl, frame by frame: set every moving object's transform, then
    ``fcl.collide`` each object pair in ``pairs`` (name pairs). Pairs of objects that
    never move (at the identity at every frame) are tested once, as collide does.

    names: the objects of poses (T, N, 4, 4); objects missing from names stay at the identity.
    With max_contacts == 1 the answer is yes/no (``num_max_contacts=1``, no contact
    details); otherwise every contact up to max_contacts is asked for.
    Returns (seconds, hits {(frame, a, b)}, contacts {(frame, a, b): [(tri_a, tri_b), ...]}).
    """
    import fcl
    index = {n: i for i, n in enumerate(names)}
    identity = np.eye(4)
    moves = {n: n in index and not np.all(poses[:, index[n]] == identity) for n in objects}
    moving = [n for n in objects if moves[n]]
    still_pairs = [p for p in pairs if not (moves[p[0]] or moves[p[1]])]
    moving_pairs = [p for p in pairs if moves[p[0]] or moves[p[1]]]
    rotation = {n: np.ascontiguousarray(poses[:, index[n], :3, :3]) for n in moving}
    translation = {n: np.ascontiguousarray(poses[:, index[n], :3, 3]) for n in moving}
    request = fcl.CollisionRequest(num_max_contacts=max_contacts, enable_contact=max_contacts > 1)
    n_frames = poses.shape[0]
    hits, contacts = set(), {}

    def collide_pair(frame, a, b):
        result = fcl.CollisionResult()
        if fcl.collide(objects[a], objects[b], request, result):
            hits.add((frame, a, b))
            if max_contacts > 1:
                contacts[(frame, a, b)] = [(c.b1, c.b2) for c in result.contacts]

    start = time.perf_counter()
    for n in objects:
        if not moves[n]:
            objects[n].setTransform(fcl.Transform())
    for a, b in still_pairs:
        collide_pair(0, a, b)
    for frame in range(n_frames):
        for n in moving:
            objects[n].setTransform(fcl.Transform(rotation[n][frame], translation[n][frame]))
        for a, b in moving_pairs:
            collide_pair(frame, a, b)
    seconds = time.perf_counter() - start
    for frame0, a, b in [h for h in hits if (h[1], h[2]) in still_pairs]:
        hits.update((f, a, b) for f in range(n_frames))
    return seconds, hits, contacts
