"""Issue 12, a lever weighed: how far apart are the object pairs a continuous scan searches?

A time-coherent shortcut (a lower bound on two objects' distance, kept while their motion
since then cannot have closed it, so that their swept test is skipped) pays only if the
pairs the swept test searches stay apart by several steps' worth of motion. This script
measures that on a scene folder (``meshes/`` and ``traj.h5``, e.g. written by
``bench_bodies.py --out``):

    python benchmarks/bench_bodies.py --bodies 1000 --frames 300 --repeat 1 --out b1000
    python benchmarks/clearance.py b1000 [--every 15]

At every ``--every``-th step, the pairs a continuous scan would search are approximated as
those whose world boxes (over both frames' vertices) overlap and whose bounding spheres
can meet over the step. For each such pair apart at the step's start: python-fcl's exact
distance at the start, divided by the pair's motion over the step (each object's longest
vertex chord, summed). Prints the quantiles of that ratio and the share of pairs a
distance certificate would spare for at least K steps (ratio > K, at this step's pace).
Static meshes (not in the trajectory) stand at their mesh coordinates. Needs python-fcl
(the bench extra).
"""
import argparse
import collections
from pathlib import Path

import fcl
import h5py
import numpy as np
import trimesh


def load(folder):
    """Meshes by name, the mesh name of each object (moving objects first, then static
    meshes), and the poses (T, objects, 4, 4) with identity rows for the static ones."""
    meshes = {p.stem: trimesh.load(p, force="mesh") for p in sorted((folder / "meshes").iterdir())}
    with h5py.File(folder / "traj.h5", "r") as f:
        moving = [m.decode() for m in f["objects/mesh"][:]]
        matrix = f["poses/matrix"][:]
    static = [name for name in meshes if name not in moving]
    poses = np.tile(np.eye(4), (matrix.shape[0], len(moving) + len(static), 1, 1))
    poses[:, :len(moving)] = matrix
    return meshes, moving + static, poses, len(moving)


def fcl_object(model, pose):
    return fcl.CollisionObject(model, fcl.Transform(pose[:3, :3], pose[:3, 3]))


def step_ratios(meshes, models, names, poses, n_moving, k):
    """(distance / motion, pair kind) of the searched pairs apart at step k's start; and
    how many searched pairs touch there."""
    world = [[meshes[n].vertices @ poses[f, o, :3, :3].T + poses[f, o, :3, 3] for o, n in enumerate(names)]
             for f in (k, k + 1)]
    motion = np.array([np.linalg.norm(w1 - w0, axis=1).max() for w0, w1 in zip(*world)])
    lo = np.array([np.minimum(w0.min(0), w1.min(0)) for w0, w1 in zip(*world)])
    hi = np.array([np.maximum(w0.max(0), w1.max(0)) for w0, w1 in zip(*world)])
    centre = np.array([w.mean(0) for w in world[0]])
    radius = np.array([np.linalg.norm(w - c, axis=1).max() for w, c in zip(world[0], centre)])
    boxes_meet = ((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None])).all(axis=2)
    reach = radius[:, None] + radius[None] + motion[:, None] + motion[None]
    spheres_meet = np.linalg.norm(centre[:, None] - centre[None], axis=2) <= reach
    ratios, touching = [], 0
    for a, b in zip(*np.nonzero(np.triu(boxes_meet & spheres_meet, 1))):
        if a >= n_moving and b >= n_moving:
            continue  # two static meshes are never searched
        distance = fcl.distance(fcl_object(models[names[a]], poses[k, a]), fcl_object(models[names[b]], poses[k, b]),
                                fcl.DistanceRequest(), fcl.DistanceResult())
        if distance <= 0:
            touching += 1
        else:
            ratios.append((distance / (motion[a] + motion[b]), "with a static mesh" if b >= n_moving else "moving"))
    return ratios, touching


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", type=Path, help="folder holding meshes/ and traj.h5")
    parser.add_argument("--every", type=int, default=15, help="measure every N-th step")
    args = parser.parse_args()
    meshes, names, poses, n_moving = load(args.scene)
    models = {}
    for name, mesh in meshes.items():
        models[name] = fcl.BVHModel()
        models[name].beginModel(len(mesh.vertices), len(mesh.faces))
        models[name].addSubModel(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32))
        models[name].endModel()
    ratios, touching = [], 0
    for k in range(0, poses.shape[0] - 1, args.every):
        found, touch = step_ratios(meshes, models, names, poses, n_moving, k)
        ratios += found
        touching += touch
    ratio = np.array([r for r, _ in ratios])
    kinds = collections.Counter(kind for _, kind in ratios)
    print(f"{len(range(0, poses.shape[0] - 1, args.every))} steps: {ratio.size} searched pairs apart at the "
          f"step's start ({dict(kinds)}), {touching} touching")
    for q in (0.1, 0.25, 0.5, 0.75, 0.9):
        print(f"  {q:4.0%} of them: distance <= {np.quantile(ratio, q):6.2f} x the pair's motion over the step")
    for steps in (1, 2, 4, 8):
        print(f"  a distance certificate would spare >= {steps} step(s) for {np.mean(ratio > steps):.0%} of them")


if __name__ == "__main__":
    main()
