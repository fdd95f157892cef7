"""Issue 12, item 4: BVH build time and query cost of the split rules (sah, median, lbvh).

    python benchmarks/bench_bvh_build.py [--triangles 100000,1000000] [--kinds terrain,sphere]
                                         [--splits sah,median,lbvh] [--threads 1,2] [--repeat 3]
                                         [--query-triangles 100000] [--frames 20] [--no-query]

Meshes (deterministic): ``terrain``, bench_meshsize.py's height field (a regular grid of
about T triangles, seed --seed); ``sphere``, trimesh's icosphere with the subdivision
count nearest T (81920 for 100k, 1310720 for 1M). Each is written as a binary PLY file.

1. Build, in this process, for every mesh, split rule and numba thread count
   (``numba.set_num_threads``; sah and median are sequential, lbvh is parallel from
   ``config.LBVH_PARALLEL_MIN`` primitives on): median of --repeat of ``load_mesh`` (parse
   the PLY file, check it), of ``build_mesh_bvh`` (triangle boxes and the tree, no mesh
   cache), and of the two together, after an untimed build of every rule on a small mesh
   (kernels compiled or loaded). ``bvh_stats``: SAH cost (what ``collide inspect``
   shows), nodes, depth. Ratios to sah at the same thread count.
2. Query (tandem descent): ``collide.scan(mode="discrete", cache=False)`` in this process,
   two copies of the --query-triangles mesh of each kind overlapping (``b`` moves and turns
   a little against ``a`` over --frames frames; their surfaces cross along long curves), for
   every split rule and ``--workers`` in --threads: the scan stage (``seconds.scan``, BVHs
   already built), median of --repeat, and the work counts (node pairs, leaf pairs). Once
   as scans run (the first intersecting triangle pair of each object pair and frame is
   enough), once with ``triangle_pairs=True`` (every intersecting pair: the whole descent).
   Contacts (and triangle pairs) must equal sah's (sah is always run once, as reference).

Target (issue 12): load + BVH build of a 1M-triangle mesh <= 5 s (ACCEPTANCE lines, one
thread, per rule and kind).
"""
import argparse
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np
import trimesh
from bench_meshsize import Terrain, height_field
from benchlib import machine_load, median, parse_workers, print_table, ratio, thread_headroom
from scalelib import acceptance, poses_from, rotations, write_scene

import collide
from collide.bvh import build_mesh_bvh, bvh_stats
from collide.load import load_mesh

TERRAIN_SIZE = 10.0


# --- meshes and scenes ------------------------------------------------------------------------

def make_mesh(kind, triangles, seed):
    if kind == "terrain":
        return height_field(Terrain(np.random.default_rng(seed), TERRAIN_SIZE), TERRAIN_SIZE, triangles)
    if kind == "sphere":   # 20 * 4**k faces
        k = int(np.clip(np.round(np.log(triangles / 20) / np.log(4)), 0, 9))
        return trimesh.creation.icosphere(subdivisions=k)
    raise ValueError(f"unknown mesh kind {kind!r}")


def overlap_poses(kind, frames):
    """Poses (T, 2, 4, 4): ``a`` at the identity, ``b`` (a copy of the same mesh) moving
    and turning a little against it, always overlapping it."""
    s = np.linspace(0.0, 1.0, frames)
    if kind == "terrain":   # the same height field, shifted and turned: the surfaces cross
        rotation = rotations(np.broadcast_to([0.0, 0.0, 1.0], (frames, 3)), np.radians(3.0) * s)
        translation = np.stack([0.2 + 0.3 * s, 0.1 + 0.0 * s, 0.0 * s], -1)
    else:                   # two unit spheres, centres 1.2 .. 0.6 apart
        rotation = rotations(np.broadcast_to([1.0, 2.0, 3.0], (frames, 3)), np.radians(20.0) * s)
        translation = (1.2 - 0.6 * s)[:, None] * (np.array([1.0, 0.5, 0.3]) / np.linalg.norm([1.0, 0.5, 0.3]))
    poses = np.repeat(np.eye(4)[None, None], frames, axis=0).repeat(2, axis=1)
    poses[:, 1] = poses_from(rotation, translation)
    return poses


# --- 1. build ---------------------------------------------------------------------------------

def warm_up(splits):
    """One untimed build per rule, on a mesh large enough for lbvh's parallel path."""
    mesh = make_mesh("terrain", 70_000, 0)
    vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
    for split in splits:
        build_mesh_bvh(vertices, faces, split)


def timed(function, *args):
    start = time.perf_counter()
    value = function(*args)
    return value, time.perf_counter() - start


def bench_builds(path, splits, threads_list, repeat, log):
    """{(split, threads): {"load": [s], "build": [s], "stats": bvh_stats}} of one mesh file."""
    out = {}
    for threads in threads_list:
        numba.set_num_threads(threads)
        for r in range(repeat):
            for split in splits:   # interleaved, so that a busy moment hits every rule alike
                mesh, load_s = timed(load_mesh, path)
                bvh, build_s = timed(build_mesh_bvh, mesh.vertices, mesh.faces, split)
                row = out.setdefault((split, threads), {"load": [], "build": [], "total": []})
                row["load"].append(load_s)
                row["build"].append(build_s)
                row["total"].append(load_s + build_s)
                if "stats" not in row:
                    row["stats"] = bvh_stats(bvh)
                print(f"  {path.stem}: {split}, {threads} thread(s), round {r + 1}/{repeat}: load {load_s:.3f} s, "
                      f"build {build_s:.3f} s ({machine_load()})", file=log, flush=True)
                del mesh, bvh
    return out


def build_rows(name, triangles, results, splits, threads_list):
    rows = []
    for threads in threads_list:
        sah = results.get(("sah", threads))
        for split in splits:
            r = results[(split, threads)]
            st = r["stats"]
            rows.append([name, str(triangles), split, str(threads), median(r["load"]), median(r["build"]),
                         median(r["total"]),
                         f"{ratio(median(r['build']), median(sah['build'])):.3f}" if sah else "-",
                         st["sah_cost"], f"{ratio(st['sah_cost'], sah['stats']['sah_cost']):.3f}" if sah else "-",
                         str(st["nodes"]), str(st["depth"]), f"{st['leaf_size_mean']:.2f}"])
    return rows


# --- 2. query ---------------------------------------------------------------------------------

def bench_queries(folder, kind, mesh, frames, splits, workers_list, repeat, log):
    """{(split, workers, pairs): {"scan": [s], "work": {...}, "same": bool}}."""
    meshes_dir, traj = write_scene(folder / f"query-{kind}", {"m": mesh}, ["a", "b"], overlap_poses(kind, frames),
                                   mesh_of=["m", "m"])
    out = {}
    reference = {}   # untimed: the reference answers (sah's), kernels loaded
    for pairs in (False, True):
        reference[pairs] = collide.scan(meshes_dir, traj, mode="discrete", split="sah", triangle_pairs=pairs,
                                        cache=False, workers=1)
    for r in range(repeat):
        for pairs in (False, True):
            for workers in workers_list:
                for split in splits:
                    result = collide.scan(meshes_dir, traj, mode="discrete", split=split, triangle_pairs=pairs,
                                          cache=False, workers=workers)
                    row = out.setdefault((split, workers, pairs), {"scan": [], "same": True})
                    row["scan"].append(result.stats["scan_s"])
                    row["work"] = result.stats["work"]
                    row["contacts"] = result.stats["contacts"]
                    row["triangle_pairs"] = result.stats["triangle_pairs"]
                    row["same"] &= same_result(result, reference[pairs], pairs)
                    print(f"  query {kind}: {split}, workers {workers}, triangle_pairs {pairs}, "
                          f"round {r + 1}/{repeat}: "
                          f"scan {result.stats['scan_s']:.3f} s ({machine_load()})", file=log, flush=True)
    return out


def same_result(a, b, pairs):
    columns = [(a.contacts, b.contacts)] + ([(a.triangle_pairs, b.triangle_pairs)] if pairs else [])
    return all(sorted(x) == sorted(y) and all(np.array_equal(x[k], y[k], equal_nan=True) for k in x)
               for x, y in columns)


def query_rows(kind, triangles, results, splits, workers_list):
    rows = []
    for pairs in (False, True):
        for workers in workers_list:
            sah = results.get(("sah", workers, pairs))
            for split in splits:
                r = results[(split, workers, pairs)]
                w = r["work"]
                rows.append([kind, str(triangles), "all pairs" if pairs else "first pair", split, str(workers),
                             median(r["scan"]),
                             f"{ratio(median(r['scan']), median(sah['scan'])):.3f}" if sah else "-",
                             str(w["node_pairs"]),
                             f"{ratio(w['node_pairs'], sah['work']['node_pairs']):.3f}" if sah else "-",
                             str(w["leaf_pairs"]), str(w["triangle_pairs"]), str(r["contacts"]),
                             "yes" if r["same"] else "NO"])
    return rows


# --- main -------------------------------------------------------------------------------------

def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", default="100000,1000000", help="comma-separated mesh sizes (build)")
    parser.add_argument("--kinds", default="terrain,sphere")
    parser.add_argument("--splits", default="sah,median,lbvh")
    parser.add_argument("--threads", default="1,2", help="numba threads (build) and --workers (query)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--query-triangles", type=int, default=100_000)
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--no-query", action="store_true")
    parser.add_argument("--seed", type=int, default=12)
    parser.add_argument("--out", help="folder for the meshes and scenes (default: a temporary folder, removed)")
    args = parser.parse_args(argv)
    sizes = parse_workers(args.triangles)
    kinds = [k for k in args.kinds.split(",") if k]
    splits = [s for s in args.splits.split(",") if s]
    threads_list = [t for t in parse_workers(args.threads) if t <= numba.config.NUMBA_NUM_THREADS]
    log = sys.stderr
    with tempfile.TemporaryDirectory(prefix="bench-bvh-build-") as tmp:
        folder = Path(args.out or tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print(f"machine: {machine_load()}; numba {numba.__version__}, threading layer "
              f"{numba.config.THREADING_LAYER}, up to {numba.config.NUMBA_NUM_THREADS} threads; two-thread headroom "
              f"now {thread_headroom():.2f}x")
        warm_up(splits)
        print(f"threading layer in use: {numba.threading_layer()}")

        build_table = []
        accept = []
        for kind in kinds:
            for triangles in sizes:
                mesh = make_mesh(kind, triangles, args.seed)
                path = folder / f"{kind}{triangles // 1000}k.ply"
                mesh.export(path)
                n = len(mesh.faces)
                print(f"{path.name}: {n} triangles, {path.stat().st_size / 1e6:.0f} MB", file=log, flush=True)
                results = bench_builds(path, splits, threads_list, args.repeat, log)
                build_table += build_rows(kind, n, results, splits, threads_list)
                if triangles >= 1_000_000:
                    accept += [(f"load + BVH build of {kind} ({n} triangles), {split}, 1 thread",
                                median(results[(split, 1)]["total"])) for split in splits if (split, 1) in results]
        print(f"\n1. BVH build (median of {args.repeat}; build = triangle boxes + tree, no mesh cache; "
              "ratios to sah at the same thread count)")
        print_table(["mesh", "triangles", "split", "threads", "load s", "build s", "load+build s", "build / sah",
                     "SAH cost", "cost / sah", "nodes", "depth", "leaf mean"], build_table)

        if not args.no_query:
            query_table = []
            for kind in kinds:
                mesh = make_mesh(kind, args.query_triangles, args.seed)
                results = bench_queries(folder, kind, mesh, args.frames, splits, threads_list, args.repeat, log)
                query_table += query_rows(kind, len(mesh.faces), results, splits, threads_list)
            print(f"\n2. query: discrete scan of two overlapping copies, {args.frames} frames "
                  f"(median of {args.repeat}; "
                  "scan = seconds.scan, BVHs built before; first pair: as scans run, all pairs: triangle_pairs=True)")
            print_table(["mesh", "triangles", "descent", "split", "workers", "scan s", "scan / sah", "node pairs",
                         "node pairs / sah", "leaf pairs", "tri pairs", "contacts", "same as sah"], query_table)

        print()
        for text, seconds in accept:
            acceptance(text, seconds, "<= 5 s", seconds <= 5.0, unit=" s")
        print(f"machine at the end: {machine_load()}")


if __name__ == "__main__":
    main()
