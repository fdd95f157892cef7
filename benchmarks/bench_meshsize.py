"""Issue 12, axis 3: two big meshes rubbing (load, BVH build, scan), collide vs python-fcl.

    python benchmarks/bench_meshsize.py [--triangles 100000] [--frames 50] [--repeat 3] [--workers 1,2]
                                        [--modes discrete,continuous] [--out FOLDER]
    python benchmarks/bench_meshsize.py --triangles 1000000       # the issue's large case
    python benchmarks/bench_meshsize.py --lift 0.04               # contact made and broken every frame

Scene (deterministic, seed --seed): two rough terrain patches of T triangles each (height
fields on a regular grid: a few seeded smooth waves plus fine seeded ripples; binary PLY,
float64). ``ground`` (side 10) is static; ``slab`` (side 6, its own terrain, facing down)
slides 2.4 over it in 50 frames while turning 6 deg about the vertical, at the height that
keeps its deepest point 0.2 % of the side (0.02) inside the ground at every frame (computed
from the height functions), so the two surfaces touch in a few small, changing patches all
the time: sliding contact. With ``--lift L`` the slab is raised by L at every odd frame
(0.04: 0.02 clear of the ground), so contact is made and broken at every step: chattering
contact, where each continuous step must find when contact begins or ends over the whole
patch.

Measured, every configuration ``--repeat`` times interleaved (medians):

- ``collide scan --format json`` discrete and continuous (screw), ``--workers`` 1 and 2:
  scan stage (``seconds.scan``), whole process, work counts; load (``seconds.load``:
  trajectory + both meshes) and BVH build (``seconds.build``, both meshes) from the mesh
  cache (warm), and with ``--no-cache`` (cold: parse the PLY files, build the BVHs; the
  discrete scan, workers 1);
- python-fcl: BVHModel build of both meshes (OBBRSS, from the arrays collide loaded) and a
  frame loop (``fcl.collide``, yes/no) over the 50 frames;
- agreement: collide discrete vs python-fcl (frame, pair) sets; ``--workers 1`` vs ``2``
  contacts columns byte-identical.

Targets (issue 12): continuous scan <= 2x discrete and <= 1x the python-fcl loop; load + BVH
build of a 1M-triangle mesh <= 5 s (here: half of the two meshes' cold load + build,
``--no-cache``; both meshes are the same size).
"""
import argparse
import itertools
import sys
import tempfile
from pathlib import Path

import numpy as np
import trimesh
from benchlib import fcl_objects, median, parse_workers, print_table, thread_headroom
from scalelib import (
    ScanEnv,
    accept_continuous,
    accept_discrete_fcl,
    accept_workers,
    acceptance,
    env_note,
    fcl_pair_loop,
    interleaved_scans,
    poses_from,
    print_breakdown,
    report_scans_and_fcl,
    rotations,
    write_scene,
)

from collide.load import load_mesh

DT = 0.01
GROUND, SLAB = 10.0, 6.0
DEPTH = 0.02


class Terrain:
    """A seeded height function h(x, y): smooth waves (amplitude ~0.3) + ripples (~0.02)."""

    def __init__(self, rng, size):
        self.k = rng.normal(size=(6, 2)) * (2 * np.pi / size) * np.array([[1.5]] * 3 + [[12.0]] * 3)
        self.phase = rng.uniform(0, 2 * np.pi, 6)
        self.amp = np.array([0.15, 0.1, 0.08, 0.008, 0.006, 0.005])

    def __call__(self, x, y):
        z = np.zeros(np.broadcast(x, y).shape)
        for (kx, ky), p, a in zip(self.k, self.phase, self.amp):
            z += a * np.sin(kx * x + ky * y + p)
        return z


def height_field(h, size, triangles, sign=1.0):
    """A trimesh of about ``triangles`` triangles: z = sign * h(x, y) on [-size/2, size/2]^2."""
    n = max(2, int(round(np.sqrt(triangles / 2))))
    xs = np.linspace(-size / 2, size / 2, n + 1)
    x, y = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), sign * h(x, y).ravel()], axis=-1)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c, d = a + 1, a + n + 1, a + n + 2
    faces = np.concatenate([np.stack([a, c, b], -1), np.stack([b, c, d], -1)])
    return trimesh.Trimesh(vertices, faces, process=False)


def slab_poses(frames, ground_h, slab_mesh):
    """Poses (T, 1, 4, 4) of the slab (its terrain faces down: z_body = -h_slab): slides
    2.4 along x and turns 6 deg about z; height so that its lowest point relative to the
    ground is DEPTH inside it (evaluated on a subsample of its vertices)."""
    s = np.linspace(0.0, 1.0, frames)
    rotation = rotations(np.broadcast_to([0.0, 0.0, 1.0], (frames, 3)), np.radians(6.0) * s)
    xy = np.stack([-1.2 + 2.4 * s, 0.3 * np.sin(np.pi * s)], -1)
    body = np.asarray(slab_mesh.vertices)
    sample = body[:: max(1, body.shape[0] // 200_000)]
    z = np.empty(frames)
    for k in range(frames):
        world = sample @ rotation[k].T
        world[:, :2] += xy[k]
        gap = world[:, 2] - ground_h(world[:, 0], world[:, 1])   # slab point above the ground, at z offset 0
        z[k] = -gap.min() - DEPTH
    return poses_from(rotation, np.concatenate([xy, z[:, None]], -1))[:, None]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, default=100_000, help="triangles per body")
    parser.add_argument("--frames", type=int, default=50)
    parser.add_argument("--seed", type=int, default=12)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--workers", default="1,2", help="comma-separated thread counts (1 is always run)")
    parser.add_argument("--modes", default="discrete,continuous")
    parser.add_argument("--breakdown-frames", type=int, help="section 3 on the first N frames only (0: skip it)")
    parser.add_argument("--breakdown-repeat", type=int, default=3)
    parser.add_argument("--lift", type=float, default=0.0,
                        help="raise the slab by this much at odd frames (contact made and broken every step)")
    parser.add_argument("--out", help="folder for the scene and results (default: a temporary folder, removed)")
    args = parser.parse_args(argv)
    workers_list = sorted(set(parse_workers(args.workers)) | {1})
    modes = [m for m in ("discrete", "continuous") if m in args.modes.split(",")]
    n = args.frames
    with tempfile.TemporaryDirectory(prefix="bench-meshsize-") as tmp:
        folder = Path(args.out or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"machine: {env_note()}; two-thread headroom now {thread_headroom():.2f}x")
        rng = np.random.default_rng(args.seed)
        ground_h, slab_h = Terrain(rng, GROUND), Terrain(rng, SLAB)
        ground = height_field(ground_h, GROUND, args.triangles)
        slab = height_field(slab_h, SLAB, args.triangles, sign=-1.0)
        poses = slab_poses(n, ground_h, slab)
        poses[1::2, :, 2, 3] += args.lift
        meshes_dir, traj = write_scene(folder, {"ground": ground, "slab": slab}, ["slab"], poses, dt=DT)
        size_mb = sum(p.stat().st_size for p in meshes_dir.glob("*.ply")) / 1e6
        print(f"scene in {folder}: ground {len(ground.faces)} and slab {len(slab.faces)} triangles "
              f"(binary PLY, {size_mb:.0f} MB), {n} frames; slab 0.02 deep in the ground at every frame"
              + (f" but the odd ones, raised by {args.lift}" if args.lift else ""))

        scan_env = ScanEnv(folder)
        cold = []

        meshes = {p.stem: load_mesh(p) for p in sorted(meshes_dir.glob("*.ply"))}
        objects, _ = fcl_objects(meshes)   # untimed warm-up of python-fcl
        fcl_times = {"pair loop": []}
        fcl_builds = []
        fcl_hits = {}

        def round_extra(r):
            # cold load + build: --no-cache (discrete, workers 1); and python-fcl
            cold.append(scan_env.scan(meshes_dir, traj, folder / "cold.h5", "--mode", "discrete", "--workers", 1,
                                      "--no-cache"))
            nonlocal objects
            objects, build_s = fcl_objects(meshes)
            fcl_builds.append(build_s)
            seconds, hits = fcl_pair_loop(objects, ["slab"], poses, [("ground", "slab")])
            fcl_times["pair loop"].append(seconds)
            fcl_hits["pair loop"] = hits
            print(f"  cold collide load {cold[-1].summary['seconds']['load']:.2f} s + build "
                  f"{cold[-1].summary['seconds']['build']:.2f} s; python-fcl build {build_s:.2f} s, loop "
                  f"{seconds:.3f} s ({env_note()})", file=sys.stderr, flush=True)

        configs = list(itertools.product(modes, workers_list))
        runs, identical = interleaved_scans(scan_env, meshes_dir, traj, configs, args.repeat, between=round_extra)
        peer_name, peer = report_scans_and_fcl(args.repeat, n, runs, fcl_times, fcl_hits, median(fcl_builds),
                                               folder, modes)

        print("\n   load and build (both meshes; median; load includes the trajectory)")
        warm = runs[(modes[0], 1)]
        rows = []
        for label, rs in ((f"collide, mesh cache warm ({modes[0]} scans)", warm),
                          ("collide, --no-cache (cold: parse PLY + build)", cold)):
            load = median([r.summary["seconds"]["load"] for r in rs])
            build = median([r.summary["seconds"]["build"] for r in rs])
            c = rs[-1].summary["cache"]
            rows.append([label, load, build, load + build, median([r.wall for r in rs]),
                         f"{c['mesh_hits']}/{c['bvh_hits']}"])
        rows.append(["python-fcl BVHModel build (OBBRSS, from arrays)", "", median(fcl_builds), median(fcl_builds), "",
                     ""])
        print_table(["", "load s", "build s", "load+build s", "wall s", "mesh/BVH hits"], rows)
        cold_total = median([r.summary["seconds"]["load"] + r.summary["seconds"]["build"] for r in cold])

        if args.breakdown_frames != 0:
            print_breakdown(meshes_dir, traj, modes, n, args.breakdown_repeat, print_table, args.breakdown_frames)
        print("\n4. acceptance")
        accept_continuous(runs, modes, peer_name, peer)
        per_mesh = cold_total / 2
        target = "<= 5 s" if args.triangles >= 1_000_000 else "<= 5 s at 1M triangles; reported"
        acceptance(f"cold load + BVH build per {args.triangles}-triangle mesh (half of both, --no-cache)", per_mesh,
                   target, per_mesh <= 5, unit=" s")
        accept_discrete_fcl(runs, modes, peer_name, peer, fcl_hits, folder, target_applies=False,
                            scene="1000 bodies (bench_bodies)")
        accept_workers(runs, identical, modes, workers_list, target_applies=False,
                       scene="the 1000-body and 100 000-frame scenes")
        print(f"machine after: {env_note()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
