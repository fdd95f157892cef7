"""Issue 12, axis 2: many bodies in a box (seeded random walk), collide vs python-fcl.

    python benchmarks/bench_bodies.py [--bodies 100] [--frames 300] [--repeat 3] [--workers 1,2]
                                      [--modes discrete,continuous] [--out FOLDER]
    python benchmarks/bench_bodies.py --bodies 1000                # the issue's large case

Scene (deterministic, seed --seed, 100 Hz): K small bodies sharing four meshes through
``objects/mesh`` (two ellipsoids, icospheres of 320 triangles, semi-axes up to 0.5; two
boxes of 192 triangles, up to 0.8 long) in a cubic box of side 1.7 K^(1/3) (about 5 % of
it filled, at any K), whose six walls are static slabs (768 triangles each, not touching
each other). Every body does a random walk with momentum: velocity and angular velocity
follow AR(1) processes (typical speed 3 % of a body's size per frame, typical turn
3 deg per frame), reflected at 0.3 from the walls so that bodies graze them at times.
Bodies pass through each other (no physics): contacts between bodies come and go.

Measured, every configuration ``--repeat`` times interleaved (medians; ratios within a round):

- ``collide scan --format json`` discrete and continuous (screw), ``--workers`` 1 and 2:
  scan stage (``seconds.scan``), whole process, work counts (totals, per frame / step; the
  swept part of a continuous scan = continuous minus discrete);
- python-fcl: a DynamicAABBTreeCollisionManager over all bodies and walls (one OBBRSS
  model per object, built once, untimed), transforms set, ``update()`` and ``collide``
  per frame with a Python callback running ``fcl.collide`` (yes/no) on every broad-phase
  candidate pair (a loop over all K (K - 1) / 2 pairs is not run: ~500 000 pairs per frame
  at K = 1000);
- agreement: collide discrete vs python-fcl (frame, pair) contact sets; ``--workers 1`` vs
  ``2`` contacts columns byte-identical (every round).

Targets (issue 12): continuous scan <= 2x discrete and <= 1x python-fcl; discrete <= 1x
python-fcl at 1000 bodies; ``--workers 2`` >= 1.8x ``--workers 1`` whole process at 1000
bodies, same contacts.
"""
import argparse
import itertools
import sys
import tempfile
from pathlib import Path

import numpy as np
import trimesh
from benchlib import median, parse_workers, print_table, thread_headroom
from scalelib import (
    FclManager,
    ScanEnv,
    accept_continuous,
    accept_discrete_fcl,
    accept_workers,
    env_note,
    interleaved_scans,
    orthonormalize,
    poses_from,
    print_breakdown,
    report_scans_and_fcl,
    rotations,
    write_scene,
)

from collide.load import load_mesh

DT = 0.01
WALL_THICKNESS = 0.2
WALL_GAP = 0.05          #: walls stop this short of the box edges (so they never touch each other)
REFLECT = 0.3            #: body centres are reflected this far from the walls


def body_meshes():
    """The four shared body meshes (trimesh), centred at their origin."""
    ell_a = trimesh.creation.icosphere(subdivisions=2)
    ell_a.apply_scale([0.5, 0.4, 0.3])
    ell_b = trimesh.creation.icosphere(subdivisions=2)
    ell_b.apply_scale([0.45, 0.45, 0.25])
    box_a = trimesh.creation.box([0.8, 0.5, 0.4]).subdivide().subdivide()
    box_b = trimesh.creation.box([0.6, 0.6, 0.3]).subdivide().subdivide()
    return {"ell_a": ell_a, "ell_b": ell_b, "box_a": box_a, "box_b": box_b}


def wall_meshes(side):
    """Six static slabs just outside the cube [-side/2, side/2]^3, in world coordinates."""
    half = side / 2
    walls = {}
    for axis, name in enumerate("xyz"):
        for sign, label in ((-1, "lo"), (1, "hi")):
            extent = np.full(3, side - 2 * WALL_GAP)
            extent[axis] = WALL_THICKNESS
            slab = trimesh.creation.box(extent).subdivide().subdivide().subdivide()
            centre = np.zeros(3)
            centre[axis] = sign * (half + WALL_THICKNESS / 2)
            slab.apply_translation(centre)
            walls[f"wall_{name}{label}"] = slab
    return walls


def random_walk(bodies, frames, side, seed):
    """Poses (T, K, 4, 4): AR(1) velocity and angular velocity, reflected at the walls."""
    rng = np.random.default_rng(seed)
    lim = side / 2 - REFLECT
    position = rng.uniform(-lim, lim, (bodies, 3))
    rotation = orthonormalize(rotations(rng.normal(size=(bodies, 3)), rng.uniform(0, np.pi, bodies)))
    speed, turn, keep = 0.025, np.radians(3.0), 0.95
    velocity = rng.normal(scale=speed / np.sqrt(3), size=(bodies, 3))
    omega = rng.normal(scale=turn / np.sqrt(3), size=(bodies, 3))
    noise_v, noise_w = np.sqrt(1 - keep ** 2), np.sqrt(1 - keep ** 2)
    poses = np.empty((frames, bodies, 4, 4))
    for k in range(frames):
        poses[k] = poses_from(rotation, position)
        velocity = keep * velocity + noise_v * rng.normal(scale=speed / np.sqrt(3), size=(bodies, 3))
        omega = keep * omega + noise_w * rng.normal(scale=turn / np.sqrt(3), size=(bodies, 3))
        position = position + velocity
        out = np.abs(position) > lim
        position = np.where(out, np.sign(position) * (2 * lim - np.abs(position)), position)
        velocity = np.where(out, -velocity, velocity)
        angle = np.linalg.norm(omega, axis=1)
        axis = np.where(angle[:, None] > 0, omega, [[1.0, 0.0, 0.0]])
        rotation = orthonormalize(rotations(axis, angle) @ rotation)
    return poses


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", type=int, default=100)
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--seed", type=int, default=12)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--workers", default="1,2", help="comma-separated thread counts (1 is always run)")
    parser.add_argument("--modes", default="discrete,continuous")
    parser.add_argument("--breakdown-frames", type=int, help="section 3 on the first N frames only (0: skip it)")
    parser.add_argument("--breakdown-repeat", type=int, default=3)
    parser.add_argument("--out", help="folder for the scene and results (default: a temporary folder, removed)")
    args = parser.parse_args(argv)
    workers_list = sorted(set(parse_workers(args.workers)) | {1})
    modes = [m for m in ("discrete", "continuous") if m in args.modes.split(",")]
    k, n = args.bodies, args.frames
    side = 1.7 * k ** (1 / 3)
    with tempfile.TemporaryDirectory(prefix="bench-bodies-") as tmp:
        folder = Path(args.out or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"machine: {env_note()}; two-thread headroom now {thread_headroom():.2f}x")
        shapes = body_meshes()
        walls = wall_meshes(side)
        shape_names = sorted(shapes)
        names = [f"body{i:04d}" for i in range(k)]
        mesh_of = [shape_names[i % len(shape_names)] for i in range(k)]
        poses = random_walk(k, n, side, args.seed)
        meshes_dir, traj = write_scene(folder, {**shapes, **walls}, names, poses, mesh_of=mesh_of, dt=DT)
        tris = sum(len(shapes[m].faces) for m in mesh_of) + sum(len(w.faces) for w in walls.values())
        print(f"scene in {folder}: {k} bodies ({', '.join(f'{s} {len(shapes[s].faces)}' for s in shape_names)} "
              f"triangles) + 6 static walls ({len(walls['wall_xlo'].faces)} each) in a box of side {side:.2f}; "
              f"{tris} triangles in all; {n} frames at {1 / DT:.0f} Hz")

        meshes = {p.stem: load_mesh(p) for p in sorted(meshes_dir.glob("*.ply"))}
        manager = FclManager(meshes, {**dict(zip(names, mesh_of)), **{w: w for w in walls}})
        fcl_times = {"manager": []}
        fcl_hits = {}

        def fcl_round(_):
            seconds, hits = manager.run(names, poses)
            fcl_times["manager"].append(seconds)
            fcl_hits["manager"] = hits
            print(f"  python-fcl manager {seconds:.2f} s ({env_note()})", file=sys.stderr, flush=True)

        scan_env = ScanEnv(folder)
        configs = list(itertools.product(modes, workers_list))
        runs, identical = interleaved_scans(scan_env, meshes_dir, traj, configs, args.repeat, between=fcl_round)
        peer_name, peer = report_scans_and_fcl(args.repeat, n, runs, fcl_times, fcl_hits, manager.build_s, folder,
                                               modes)
        wall_hits = {p for h in fcl_hits["manager"] for p in [h[1:]] if p[0].startswith("wall") or
                     p[1].startswith("wall")}
        print(f"   contacts involve {len({h[1:] for h in fcl_hits['manager']})} object pairs "
              f"({len(wall_hits)} with a wall); python-fcl manager per frame: "
              f"{1e6 * median(fcl_times['manager']) / n:.0f} us")
        if args.breakdown_frames != 0:
            print_breakdown(meshes_dir, traj, modes, n, args.breakdown_repeat, print_table, args.breakdown_frames)
        print("\n4. acceptance")
        accept_continuous(runs, modes, peer_name, peer)
        accept_discrete_fcl(runs, modes, peer_name, peer, fcl_hits, folder, target_applies=k >= 1000,
                            scene="1000 bodies")
        accept_workers(runs, identical, modes, workers_list, target_applies=k >= 1000, scene="1000 bodies")
        print(f"machine after: {env_note()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
