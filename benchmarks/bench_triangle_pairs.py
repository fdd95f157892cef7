"""Many contacts: two coplanar grids rubbing, every intersecting triangle pair written.

    python benchmarks/bench_triangle_pairs.py [--frames 100 1000] [--grid 40] [--workers 1]

Two flat square grids (2 x grid^2 triangles each) lie in one plane, one sliding slowly
over the other, so every frame has about the same (large) number of intersecting
triangle pairs. For each frame count, ``collide scan --mode discrete --triangle-pairs``
runs as a separate process: peak resident memory (ru_maxrss of the child), rows
written, and CPU time per written row. Memory should stay flat as the rows grow
(they stream to the file); the CPU per row is what --triangle-pairs costs.
"""
import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import trimesh


def grid(n, size=1.0):
    """A flat n x n grid of squares (2 n^2 triangles) in the z = 0 plane, side ``size``."""
    xs = np.linspace(0.0, size, n + 1)
    x, y = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=-1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c, d = a + 1, a + n + 1, a + n + 2
    faces = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)])
    return trimesh.Trimesh(vertices, faces, process=False)


def scene(folder, n_grid, n_frames):
    meshes = folder / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    grid(n_grid).export(meshes / "base.ply")
    grid(n_grid).export(meshes / "slider.ply")
    matrix = np.tile(np.eye(4), (n_frames, 1, 1, 1))
    matrix[:, 0, 0, 3] = np.linspace(0.0, 0.25, n_frames)  # slides a quarter of its size, never leaving
    with h5py.File(folder / "traj.h5", "w") as f:
        f["time"] = np.arange(n_frames) * 0.01
        f.create_dataset("objects/name", data=["slider"], dtype=h5py.string_dtype())
        f["poses/matrix"] = matrix
    return meshes, folder / "traj.h5"


def run(meshes, traj, out, workers):
    """(seconds, child CPU seconds, peak RSS MiB, rows) of one scan in a fresh process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "collide_cli.main", "scan", str(meshes), str(traj), "-o", str(out),
                           "--mode", "discrete", "--triangle-pairs", "--workers", str(workers), "-q"],
                          capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        raise SystemExit(proc.stderr)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    with h5py.File(out, "r") as f:
        rows = f["triangle_pairs/frame"].shape[0]
    return wall, cpu, after.ru_maxrss / 1024, rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, nargs="+", default=[100, 1000])
    parser.add_argument("--grid", type=int, default=40)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        meshes, traj = scene(tmp / "warm", args.grid, 2)
        run(meshes, traj, tmp / "warm.h5", args.workers)   # kernels and meshes cached
        print(f"{'frames':>7} {'rows':>11} {'wall s':>8} {'cpu s':>8} {'peak RSS MiB':>13} {'us cpu/row':>11}")
        for n in args.frames:
            meshes, traj = scene(tmp / f"f{n}", args.grid, n)
            wall, cpu, rss, rows = run(meshes, traj, tmp / f"c{n}.h5", args.workers)
            print(f"{n:7d} {rows:11d} {wall:8.2f} {cpu:8.2f} {rss:13.0f} {1e6 * cpu / max(rows, 1):11.2f}")
            os.unlink(tmp / f"c{n}.h5")
    print("(peak RSS is the largest child so far: a later, larger run that stays level shows flat memory)")


if __name__ == "__main__":
    sys.exit(main())
