"""A 7-joint arm in a cell: pair filters, discrete vs continuous, python-fcl, mesh cache.

    python benchmarks/bench_robot.py [--out FOLDER] [--repeat 3] [--workers 1,2]
                                     [--frames 1000] [--max-edge 0.04]

Scene (benchmarks/robot_cell.py, deterministic): an 8-link arm (about 1 m reach, links
overlapping at their joints like real housings) on a table standing on a floor, three
posts on the table, about 14k triangles; 1000 frames at 100 Hz of smooth joint motion
in which the gripper (link7) runs into post_a during a known window (frames 485-516 at
the defaults) and the wrist roll swings up to 8 degrees per frame. ``collide urdf``
turns it into a meshes folder and a trajectory (with its adjacent-link ignore list, and
once more with --no-ignore-adjacent); the static meshes are copied next to the links.

Measured (each configuration ``--repeat`` times, interleaved; medians; separate
``collide scan`` processes with a warm numba cache):

1. scans in discrete and continuous (screw) mode, (a) filtered: the adjacent-link list
   plus ``--ignore`` of the static pairs that stand on each other (table:floor,
   post_*:table, base:table), (b) unfiltered; scan stage (``seconds.scan`` of the JSON
   summary) and whole process; contacts found; exit code with ``--fail-on-contact``;
   unfiltered / filtered ratios (issue 9 acceptance: >= 5 for continuous);
2. a python-fcl frame loop over the filtered scan's object pairs (``fcl.collide``,
   num_max_contacts=1, models built once, poses from the trajectory file) against the
   filtered discrete scan stage on one thread (acceptance: collide / fcl <= 1), and the
   (frame, pair) sets of both compared;
3. the mesh cache: the filtered continuous scan twice with a fresh COLLIDE_CACHE_DIR (cold,
   then warm) and once with --no-cache (acceptance: the warm run parses no mesh and
   builds no BVH).

Ratios are taken within each repeat (the machine is shared and noisy), then the median.
"""
import argparse
import fnmatch
import itertools
import shutil
import sys
import tempfile
from pathlib import Path
from typing import NamedTuple

import h5py
from benchlib import (
    contact_pairs,
    fcl_frame_loop,
    fcl_objects,
    frame_pairs,
    machine_load,
    median,
    parse_workers,
    print_table,
    ratio,
    read_poses,
    run_cli,
    run_scan,
    thread_headroom,
)
from robot_cell import STATIC_PAIRS_THAT_TOUCH, write_cell

from collide.load import load_mesh

MODES = ("discrete", "continuous")
VARIANTS = ("filtered", "unfiltered")


class Scene(NamedTuple):
    """The inputs of the scans."""
    folder: Path
    meshes: Path           #: links (collide urdf) + static obstacles
    trajectory: Path       #: with filters/ignore (adjacent links)
    trajectory_all: Path   #: without (collide urdf --no-ignore-adjacent)
    ignore: list           #: --ignore patterns of the filtered scans (static pairs)
    cell: object           #: robot_cell.Cell


def build_scene(folder, frames, max_edge):
    """Generate the cell and run ``collide urdf`` on it (twice: with and without the
    adjacent-link ignore list); returns a Scene."""
    folder = Path(folder)
    cell = write_cell(folder, frames=frames, max_edge=max_edge)
    meshes = folder / "cell"
    for path in (meshes, folder / "cell_all"):
        shutil.rmtree(path, ignore_errors=True)
    run_cli("urdf", cell.urdf, cell.joints_csv, "-o", folder / "traj.h5", "--meshes-out", meshes, "-q")
    run_cli("urdf", cell.urdf, cell.joints_csv, "-o", folder / "traj_all.h5", "--meshes-out", folder / "cell_all",
            "--no-ignore-adjacent", "-q")
    shutil.rmtree(folder / "cell_all")   # the same link meshes as cell/
    for path in sorted(cell.obstacles.glob("*.ply")):
        shutil.copy(path, meshes / path.name)
    ignore = [f"{a}:{b}" for a, b in STATIC_PAIRS_THAT_TOUCH]
    return Scene(folder, meshes, folder / "traj.h5", folder / "traj_all.h5", ignore, cell)


def scan_options(scene, mode, variant, workers):
    """(trajectory, options) of one scan configuration."""
    options = ["--mode", mode, "--workers", workers, "--fail-on-contact"]
    if variant == "filtered":
        return scene.trajectory, options + [x for pattern in scene.ignore for x in ("--ignore", pattern)]
    return scene.trajectory_all, options


def output_path(scene, mode, variant):
    return scene.folder / f"contacts_{mode}_{variant}.h5"


def scan_configurations(scene, workers_list, repeat):
    """Every (mode, variant, workers) scan, ``repeat`` times, interleaved (after one
    untimed warm-up run each). Returns {(mode, variant, workers): [Run, ...]}."""
    configs = list(itertools.product(MODES, VARIANTS, workers_list))
    runs = {c: [] for c in configs}
    for r in range(repeat + 1):
        for mode, variant, workers in configs:
            trajectory, options = scan_options(scene, mode, variant, workers)
            run = run_scan(scene.meshes, trajectory, output_path(scene, mode, variant), *options)
            if r > 0:
                runs[(mode, variant, workers)].append(run)
        print(f"  scans: round {r}/{repeat} done ({machine_load()})", file=sys.stderr)
    return runs


def filtered_pairs(scene, names):
    """Name pairs the filtered scan checks: all pairs but those its ignore patterns match
    (the trajectory's filters/ignore and the --ignore patterns)."""
    with h5py.File(scene.trajectory, "r") as f:
        patterns = [tuple(p) for p in f["filters/ignore"].asstr()[()]]
    patterns += [tuple(p.split(":")) for p in scene.ignore]

    def ignored(a, b):
        return any((fnmatch.fnmatchcase(a, p) and fnmatch.fnmatchcase(b, q))
                   or (fnmatch.fnmatchcase(b, p) and fnmatch.fnmatchcase(a, q)) for p, q in patterns)
    return [(a, b) for a, b in itertools.combinations(names, 2) if not ignored(a, b)]


def canonical(hits):
    """{(frame, a, b)} with each name pair sorted (tools order pairs differently)."""
    return {(f, *sorted((a, b))) for f, a, b in hits}


def fcl_comparison(scene, repeat):
    """python-fcl loop over the filtered pairs, ``repeat`` times; returns a dict of
    timings and the agreement with the filtered discrete scan's (frame, pair) set."""
    names, poses = read_poses(scene.trajectory)
    meshes = {path.stem: load_mesh(path) for path in sorted(scene.meshes.glob("*.ply"))}
    objects, build_s = fcl_objects(meshes)
    pairs = filtered_pairs(scene, list(meshes))
    times = []
    for _ in range(repeat):
        seconds, hits, _ = fcl_frame_loop(objects, names, poses, pairs)
        times.append(seconds)
    ours = canonical(frame_pairs(output_path(scene, "discrete", "filtered")))
    theirs = canonical(hits)
    return {"seconds": times, "build_s": build_s, "pairs": len(pairs),
            "fcl_hits": theirs, "collide_hits": ours}


def cache_runs(scene, repeat, workers):
    """The filtered continuous scan: cold (fresh cache folder), warm (same folder), and
    --no-cache, ``repeat`` times. Returns {"cold"|"warm"|"no-cache": [Run, ...]}."""
    trajectory, options = scan_options(scene, "continuous", "filtered", workers)
    out = output_path(scene, "continuous", "cache")
    runs = {"cold": [], "warm": [], "no-cache": []}
    for _ in range(repeat):
        with tempfile.TemporaryDirectory(prefix="collide-cache-") as cache:
            env = {"COLLIDE_CACHE_DIR": cache}
            runs["cold"].append(run_scan(scene.meshes, trajectory, out, *options, env=env))
            runs["warm"].append(run_scan(scene.meshes, trajectory, out, *options, env=env))
            runs["no-cache"].append(run_scan(scene.meshes, trajectory, out, *options, "--no-cache", env=env))
    return runs


def per_repeat_ratio(numerators, denominators):
    """Median over repeats of numerator[i] / denominator[i]."""
    return median([ratio(a, b) for a, b in zip(numerators, denominators)])


def report_scans(scene, runs, workers_list):
    """Table 1: scan stage and whole process per configuration, contacts, exit codes."""
    print("\n1. scans (medians; scan = seconds.scan of the JSON summary; wall = whole process)")
    rows = []
    for (mode, variant, workers), rs in runs.items():
        s = rs[-1].summary
        rows.append([mode, variant, str(workers), median([r.summary["seconds"]["scan"] for r in rs]),
                     median([r.wall for r in rs]), str(s["contacts"]), str(s["pairs_in_contact"]),
                     str(sorted({r.returncode for r in rs})), str(s["work"]["node_pairs"]),
                     str(s["work"]["triangle_pairs"]), str(s["work"]["ccd_queries"])])
    print_table(["mode", "pairs", "workers", "scan s", "wall s", "contacts", "pairs hit", "exit",
                 "node pairs", "tri pairs", "ccd queries"], rows)
    for variant in VARIANTS:
        found = contact_pairs(output_path(scene, "continuous", variant))
        print(f"   {variant} contacts (continuous; pair: intervals): "
              + ", ".join(f"{a}:{b}: {n}" for (a, b), n in sorted(found.items())))
    hits = sorted(f for f, a, b in frame_pairs(output_path(scene, "discrete", "filtered")) if "post_a" in (a, b))
    expected = scene.cell.expected_hit
    print(f"   link7:post_a frames in contact (discrete): {hits[0] if hits else None}..{hits[-1] if hits else None} "
          f"({len(hits)} frames); expected by the generator: {expected.min()}..{expected.max()} "
          f"({expected.size} frames, vertex-in-solid test)")
    ratios = {}
    print("   unfiltered / filtered (median of per-repeat ratios):")
    for mode, workers in itertools.product(MODES, workers_list):
        scan = per_repeat_ratio([r.summary["seconds"]["scan"] for r in runs[(mode, "unfiltered", workers)]],
                                [r.summary["seconds"]["scan"] for r in runs[(mode, "filtered", workers)]])
        wall = per_repeat_ratio([r.wall for r in runs[(mode, "unfiltered", workers)]],
                                [r.wall for r in runs[(mode, "filtered", workers)]])
        ratios[(mode, workers)] = scan
        print(f"     {mode:10s} workers {workers}: scan stage {scan:7.1f}x, whole process {wall:5.2f}x")
    return ratios


def report_fcl(fcl, runs):
    """Table 2: collide discrete (filtered, one thread) against the python-fcl loop."""
    collide_1 = [r.summary["seconds"]["scan"] for r in runs[("discrete", "filtered", 1)]]
    walls_1 = [r.wall for r in runs[("discrete", "filtered", 1)]]
    print(f"\n2. discrete, filtered pairs ({fcl['pairs']} object pairs), yes/no per pair per frame")
    rows = [["python-fcl loop (fcl.collide, num_max_contacts=1)", median(fcl["seconds"]), "1.00"],
            ["collide scan stage, --workers 1", median(collide_1),
             f"{per_repeat_ratio(collide_1, fcl['seconds']):.3f}"],
            ["collide whole process, --workers 1", median(walls_1), f"{per_repeat_ratio(walls_1, fcl['seconds']):.2f}"]]
    for (mode, variant, workers), rs in runs.items():
        if mode == "discrete" and variant == "filtered" and workers != 1:
            s = [r.summary["seconds"]["scan"] for r in rs]
            rows.insert(2, [f"collide scan stage, --workers {workers}", median(s),
                            f"{per_repeat_ratio(s, fcl['seconds']):.3f}"])
    print_table(["", "seconds", "/ fcl"], rows)
    print(f"   (python-fcl model build, once, not timed above: {fcl['build_s']:.3f} s)")
    ours, theirs = fcl["collide_hits"], fcl["fcl_hits"]
    differences = f"; first differences {sorted(ours ^ theirs)[:5]}" if ours != theirs else ""
    print(f"   (frame, pair) sets: collide {len(ours)}, python-fcl {len(theirs)}, only collide {len(ours - theirs)}, "
          f"only fcl {len(theirs - ours)}{differences}")
    return per_repeat_ratio(collide_1, fcl["seconds"]), ours == theirs


def report_cache(runs):
    """Table 3: cold vs warm mesh cache, and --no-cache."""
    print("\n3. mesh cache (filtered continuous scan; fresh COLLIDE_CACHE_DIR per repeat; numba cache warm)")
    rows = []
    for name, rs in runs.items():
        c = rs[-1].summary["cache"]
        rows.append([name, median([r.wall for r in rs])]
                    + [median([r.summary["seconds"][stage] for r in rs]) for stage in ("load", "build", "jit", "scan")]
                    + [f"{c['mesh_hits']}/{c['mesh_hits'] + c['mesh_misses']}",
                       f"{c['bvh_hits']}/{c['bvh_hits'] + c['bvh_misses']}"])
    print_table(["run", "wall s", "load s", "build s", "jit s", "scan s", "mesh hits", "BVH hits"], rows)
    warm = runs["warm"][-1].summary["cache"]
    skipped = all(r.summary["cache"]["mesh_misses"] == 0 and r.summary["cache"]["bvh_misses"] == 0
                  for r in runs["warm"])
    return skipped, warm, median([r.wall for r in runs["cold"]]), median([r.wall for r in runs["warm"]])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="folder for the scene and results (default: a temporary folder, removed)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--workers", default="1,2", help="comma-separated thread counts (1 is always run)")
    parser.add_argument("--frames", type=int, default=1000)
    parser.add_argument("--max-edge", type=float, default=0.04, help="tessellation of the links (m)")
    args = parser.parse_args(argv)
    workers_list = sorted(set(parse_workers(args.workers)) | {1})
    with tempfile.TemporaryDirectory(prefix="bench-robot-") as tmp:
        folder = Path(args.out or tmp)
        print(f"machine: {machine_load()}; two-thread headroom now {thread_headroom():.2f}x "
              "(a trivially parallel loop on 2 threads vs 1)")
        scene = build_scene(folder, args.frames, args.max_edge)
        cell = scene.cell
        print(f"scene in {folder}: {sum(cell.triangles.values())} triangles "
              f"({', '.join(f'{k} {v}' for k, v in cell.triangles.items())}); {args.frames} frames at 100 Hz; "
              f"largest joint step {cell.max_step_deg:.1f} deg/frame")
        print("filtered scans: the trajectory's adjacent-link ignore list + "
              + " ".join(f"--ignore '{p}'" for p in scene.ignore))
        runs = scan_configurations(scene, workers_list, args.repeat)
        fcl = fcl_comparison(scene, args.repeat)
        cache = cache_runs(scene, args.repeat, workers_list[0])
        ratios = report_scans(scene, runs, workers_list)
        fcl_ratio, same_sets = report_fcl(fcl, runs)
        skipped, warm, cold_wall, warm_wall = report_cache(cache)
        print(f"\nmachine after: {machine_load()}")
        met = "met" if ratios[("continuous", 1)] >= 5 else "NOT met"
        print(f"ACCEPTANCE: continuous scan stage unfiltered / filtered = {ratios[('continuous', 1)]:.1f}x "
              f"(workers 1; target >= 5x): {met}")
        print(f"ACCEPTANCE: discrete scan stage unfiltered / filtered = {ratios[('discrete', 1)]:.1f}x "
              f"(workers 1; reported, no target)")
        print(f"ACCEPTANCE: collide discrete scan stage / python-fcl loop = {fcl_ratio:.3f} (workers 1; target <= 1): "
              f"{'met' if fcl_ratio <= 1 else 'NOT met'}; same (frame, pair) sets: {'yes' if same_sets else 'NO'}")
        print(f"ACCEPTANCE: warm run skips mesh parsing and BVH builds: {'met' if skipped else 'NOT met'} "
              f"({warm['mesh_hits']} mesh and {warm['bvh_hits']} BVH hits, {warm['mesh_misses']} + "
              f"{warm['bvh_misses']} misses); whole process cold {cold_wall:.2f} s -> warm {warm_wall:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
