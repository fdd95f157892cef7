"""Helpers of the scale benchmarks (issue 12: bench_frames.py, bench_bodies.py,
bench_meshsize.py), on top of benchlib.py:

- ``write_scene``: a meshes folder and a ``poses/matrix`` trajectory from generated meshes;
- ``ScanEnv`` / ``interleaved_scans``: ``collide scan --format json`` processes, every
  configuration ``repeat`` times interleaved, with a private mesh cache folder (the
  user's numba kernel cache is kept, so nothing recompiles);
- ``contacts_identical``: byte comparison of two contacts files' ``contacts/`` columns;
- ``print_work``: the ``work`` counts of discrete and continuous scans, totals and per
  frame / step, and the swept part of a continuous scan (continuous minus discrete: a
  continuous scan runs the discrete frame scan first);
- ``fcl_manager_loop``: python-fcl's DynamicAABBTreeCollisionManager, transforms updated
  and ``collide`` called per frame (a Python callback runs ``fcl.collide`` on each
  broad-phase candidate pair);
- ``acceptance``: one ``ACCEPTANCE:`` line.
"""
import os
import sys
import time
from pathlib import Path

import h5py
import numpy as np
from benchlib import fcl_model, machine_load, median, ratio, run_scan

WORK = ("object_pairs", "node_pairs", "leaf_pairs", "triangle_pairs", "ccd_pairs", "ccd_queries", "box_checks",
        "substeps", "splits")
MODES = ("discrete", "continuous")


# --- scenes ----------------------------------------------------------------------------------

def rotations(axes, angles):
    """Rotation matrices (..., 3, 3) about unit ``axes`` (..., 3) by ``angles`` (...,) (Rodrigues)."""
    axes = np.asarray(axes, float)
    axes = axes / np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = np.asarray(angles, float)
    x, y, z = np.moveaxis(axes, -1, 0)
    c, s = np.cos(angles), np.sin(angles)
    C = 1 - c
    return np.stack([np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], -1),
                     np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], -1),
                     np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], -1)], -2)


def orthonormalize(rotation):
    """The nearest rotation matrices (..., 3, 3) (SVD), to keep composed rotations exact."""
    u, _, vt = np.linalg.svd(rotation)
    return u @ vt


def poses_from(rotation, translation):
    """(..., 4, 4) rigid transforms from rotations (..., 3, 3) and translations (..., 3)."""
    out = np.zeros(rotation.shape[:-2] + (4, 4))
    out[..., :3, :3] = rotation
    out[..., :3, 3] = translation
    out[..., 3, 3] = 1.0
    return out


def write_scene(folder, meshes, names, poses, mesh_of=None, dt=0.01):
    """Write ``meshes`` ({file stem: trimesh.Trimesh}) as binary PLY files into
    folder/meshes and a trajectory folder/traj.h5 with ``names`` (N,) moving on
    ``poses`` (T, N, 4, 4) (``mesh_of``: the mesh stem of each object, to share meshes;
    meshes that no object uses are static). Returns (meshes folder, trajectory)."""
    folder = Path(folder)
    mesh_dir = folder / "meshes"
    mesh_dir.mkdir(parents=True, exist_ok=True)
    for stem, mesh in meshes.items():
        mesh.export(mesh_dir / f"{stem}.ply")
    trajectory = folder / "traj.h5"
    with h5py.File(trajectory, "w") as f:
        f["time"] = np.arange(poses.shape[0]) * dt
        f["time"].attrs["unit"] = "s"
        f.create_dataset("objects/name", data=list(names), dtype=h5py.string_dtype())
        if mesh_of is not None:
            f.create_dataset("objects/mesh", data=list(mesh_of), dtype=h5py.string_dtype())
        f["poses/matrix"] = poses
    return mesh_dir, trajectory


# --- collide runs ----------------------------------------------------------------------------

class ScanEnv:
    """Where the scans of one benchmark run: a private mesh cache folder under ``folder``
    (so large BVHs neither fill nor evict the user's cache) and the user's numba kernel
    cache (so nothing is compiled again)."""

    def __init__(self, folder):
        from collide.jit import cache_root
        self.folder = Path(folder)
        self.env = {"COLLIDE_CACHE_DIR": str(self.folder / "mesh-cache"),
                    "COLLIDE_KERNEL_CACHE_DIR": str(cache_root())}

    def scan(self, meshes, trajectory, output, *options):
        return run_scan(meshes, trajectory, output, *options, env=self.env)


def output_path(folder, mode, workers, tag=""):
    return Path(folder) / f"contacts_{mode}_w{workers}{tag}.h5"


def interleaved_scans(scan_env, meshes, trajectory, configs, repeat, extra=(), between=None, log=sys.stderr):
    """Run every (mode, workers) of ``configs`` ``repeat`` times, interleaved, after a
    short untimed warm-up (``--frames 0:2`` in each mode: mesh cache filled, kernels
    loaded). ``between(r)`` is called after each round (e.g. a python-fcl loop, so that
    peers are timed in the same conditions). After each round the contacts of the
    workers runs of each mode are compared byte for byte.
    Returns ({config: [Run, ...]}, {mode: all rounds identical across workers})."""
    for mode in sorted({m for m, _ in configs}):
        scan_env.scan(meshes, trajectory, scan_env.folder / "warmup.h5", "--mode", mode, "--frames", "0:2",
                      "--workers", "1", *extra)
    runs = {c: [] for c in configs}
    identical = {m: True for m, _ in configs}
    for r in range(repeat):
        for mode, workers in configs:
            started = time.perf_counter()
            run = scan_env.scan(meshes, trajectory, output_path(scan_env.folder, mode, workers), "--mode", mode,
                                "--workers", workers, *extra)
            runs[(mode, workers)].append(run)
            print(f"  round {r + 1}/{repeat}: {mode} --workers {workers}: scan {run.summary['seconds']['scan']:.2f} s, "
                  f"wall {time.perf_counter() - started:.2f} s ({machine_load()})", file=log, flush=True)
        for mode in identical:
            paths = [output_path(scan_env.folder, mode, w) for m, w in configs if m == mode]
            identical[mode] &= all(contacts_identical(paths[0], p) for p in paths[1:])
        if between is not None:
            between(r)
    return runs, identical


def contacts_identical(a, b):
    """The contacts/ columns of two contacts files are the same bytes (names, dtypes, values)."""
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        ga, gb = fa["contacts"], fb["contacts"]
        if sorted(ga) != sorted(gb):
            return False
        return all(ga[k].dtype == gb[k].dtype and ga[k][()].tobytes() == gb[k][()].tobytes() for k in ga)


def scan_seconds(runs):
    return [r.summary["seconds"]["scan"] for r in runs]


def walls(runs):
    return [r.wall for r in runs]


def per_repeat_ratio(numerators, denominators):
    """Median over repeats of numerators[i] / denominators[i]."""
    return median([ratio(a, b) for a, b in zip(numerators, denominators)])


def scan_table(runs, n_frames):
    """Rows (mode, workers, scan s, wall s, load s, build s, jit s, rest s (whole process minus
    those stages: interpreter start, imports, checks, output), scan us per frame, contacts,
    pairs in contact, frames in contact): medians."""
    rows = []
    for (mode, workers), rs in runs.items():
        s = rs[-1].summary
        rows.append([mode, str(workers), median(scan_seconds(rs)), median(walls(rs)),
                     median([r.summary["seconds"]["load"] for r in rs]),
                     median([r.summary["seconds"]["build"] for r in rs]),
                     median([r.summary["seconds"]["jit"] for r in rs]),
                     median([r.wall - sum(r.summary["seconds"].values()) for r in rs]),
                     f"{1e6 * median(scan_seconds(rs)) / n_frames:.1f}",
                     str(s["contacts"]), str(s["pairs_in_contact"]), str(s["frames_in_contact"])])
    return ["mode", "workers", "scan s", "wall s", "load s", "build s", "jit s", "rest s", "scan us/frame", "contacts",
            "pairs hit", "frames hit"], rows


def print_work(runs, n_frames, print_table):
    """The work counts of one discrete and one continuous run (workers 1): totals, per frame
    (discrete) and per step of the swept part (continuous minus discrete)."""
    work = {mode: runs[(mode, 1)][-1].summary["work"] for mode in MODES if (mode, 1) in runs}
    rows = []
    if "discrete" in work:
        rows.append(["discrete, total"] + [str(work["discrete"][k]) for k in WORK])
        rows.append(["discrete, per frame"] + [f"{work['discrete'][k] / n_frames:.4g}" for k in WORK])
    if "continuous" in work:
        rows.append(["continuous, total"] + [str(work["continuous"][k]) for k in WORK])
        if "discrete" in work:
            swept = {k: work["continuous"][k] - work["discrete"][k] for k in WORK}
            steps = max(n_frames - 1, 1)
            rows.append(["swept part, total"] + [str(swept[k]) for k in WORK])
            rows.append(["swept part, per step"] + [f"{swept[k] / steps:.4g}" for k in WORK])
    print_table(["work (workers 1)"] + list(WORK), rows)
    if "continuous" in work and "discrete" in work:
        swept = {k: work["continuous"][k] - work["discrete"][k] for k in WORK}
        per_query = ratio(swept["box_checks"], swept["ccd_queries"]) if swept["ccd_queries"] else 0.0
        per_pair = ratio(swept["ccd_queries"], swept["ccd_pairs"]) if swept["ccd_pairs"] else 0.0
        print(f"   swept part: {per_pair:.2f} CCD queries per CCD triangle pair, {per_query:.2f} box checks per "
              f"query; swept / discrete node pairs {ratio(swept['node_pairs'], work['discrete']['node_pairs']):.2f}x, "
              f"triangle pairs {ratio(swept['triangle_pairs'], max(work['discrete']['triangle_pairs'], 1)):.2f}x")


# --- python-fcl ------------------------------------------------------------------------------

def fcl_pair_loop(objects, names, poses, pairs, repeat_hits=True):
    """benchlib.fcl_frame_loop (``fcl.collide`` per listed pair per frame, yes/no)."""
    from benchlib import fcl_frame_loop
    seconds, hits, _ = fcl_frame_loop(objects, names, poses, pairs)
    return seconds, {(f, *sorted((a, b))) for f, a, b in hits}


class FclManager:
    """python-fcl DynamicAABBTreeCollisionManager over every object (one BVHModel per
    object, so that the callback can tell objects apart by their geometry; models
    built once, untimed). ``run(names, poses)`` sets the moving objects' transforms,
    ``update()``s the manager and ``collide``s it at every frame; the callback calls
    ``fcl.collide`` (num_max_contacts=1: yes/no) on each candidate pair and never stops
    early. Objects not in ``names`` stay at the identity (static)."""

    def __init__(self, meshes, mesh_of_object):
        """meshes {stem: collide Mesh}; mesh_of_object {object name: mesh stem} (every object)."""
        import fcl
        self.fcl = fcl
        start = time.perf_counter()
        self.geometry = {name: fcl_model(fcl, meshes[stem]) for name, stem in mesh_of_object.items()}
        self.objects = {name: fcl.CollisionObject(g, fcl.Transform()) for name, g in self.geometry.items()}
        self.build_s = time.perf_counter() - start
        self.name_of = {id(g): name for name, g in self.geometry.items()}

    def run(self, names, poses):
        """(seconds, hits {(frame, a, b)} with a < b by name)."""
        fcl = self.fcl
        objects = self.objects
        moving = [objects[n] for n in names]
        rotation = np.ascontiguousarray(poses[:, :, :3, :3])
        translation = np.ascontiguousarray(poses[:, :, :3, 3])
        for obj in objects.values():
            obj.setTransform(fcl.Transform())
        manager = fcl.DynamicAABBTreeCollisionManager()
        manager.registerObjects(list(objects.values()))
        manager.setup()
        request = fcl.CollisionRequest(num_max_contacts=1, enable_contact=False)
        found = []
        name_of = self.name_of

        def callback(o1, o2, _):
            result = fcl.CollisionResult()
            if fcl.collide(o1, o2, request, result):
                contact = result.contacts[0]   # o1, o2 are the models (fcl records one even without contact details)
                found.append((name_of[id(contact.o1)], name_of[id(contact.o2)]))
            return False

        hits = set()
        start = time.perf_counter()
        for frame in range(poses.shape[0]):
            for i, obj in enumerate(moving):
                obj.setTransform(fcl.Transform(rotation[frame, i], translation[frame, i]))
            manager.update()
            manager.collide(None, callback)
            if found:
                hits.update((frame, *sorted(p)) for p in found)
                found.clear()
        return time.perf_counter() - start, hits


def compare_hits(ours, theirs):
    """One line: sizes of two {(frame, a, b)} sets and their differences."""
    text = (f"(frame, pair) sets: collide {len(ours)}, python-fcl {len(theirs)}, only collide {len(ours - theirs)}, "
            f"only fcl {len(theirs - ours)}")
    if ours != theirs:
        text += f"; first differences {sorted(ours ^ theirs)[:4]}"
    return text


def frame_hits(contacts):
    """{(frame, a, b)} (names sorted) of a discrete contacts file."""
    from benchlib import frame_pairs
    return {(f, *sorted((a, b))) for f, a, b in frame_pairs(contacts)}


# --- reporting -------------------------------------------------------------------------------

def acceptance(text, value, target, ok, unit="x"):
    """Print one ACCEPTANCE line: ``text`` = value (target): met / NOT met."""
    print(f"ACCEPTANCE: {text} = {value:.3g}{unit} (target {target}): {'met' if ok else 'NOT met'}")


def env_note():
    return f"{machine_load()}; pid {os.getpid()}"


# --- the common report -----------------------------------------------------------------------

def report_scans_and_fcl(repeat, n_frames, runs, fcl_times, fcl_hits, build_s, folder, modes):
    """Sections 1 (collide scans, work counts) and 2 (python-fcl peers, agreement).
    Returns (peer name, peer seconds per repeat): the faster python-fcl loop."""
    from benchlib import print_table
    print(f"\n1. collide scans (median of {repeat}; scan = seconds.scan of the JSON summary, wall = whole process)")
    headers, rows = scan_table(runs, n_frames)
    print_table(headers, rows)
    print()
    print_work(runs, n_frames, print_table)

    peers = {k: v for k, v in fcl_times.items() if v}
    peer_name = min(peers, key=lambda k: median(peers[k]))
    peer = peers[peer_name]
    print(f"\n2. against python-fcl (yes/no per pair per frame, OBBRSS models built once in {build_s:.3f} s, untimed; "
          f"ratios: median of per-round ratios)")
    rows = [[f"python-fcl {k}" + (" (peer)" if k == peer_name else ""), median(v),
             f"{per_repeat_ratio(v, peer):.3f}"] for k, v in peers.items()]
    for kind, values in (("scan stage", scan_seconds), ("whole process", walls)):
        for mode, workers in runs:
            v = values(runs[(mode, workers)])
            rows.append([f"collide {mode} {kind}, --workers {workers}", median(v), f"{per_repeat_ratio(v, peer):.3f}"])
    print_table(["", "seconds", "/ fcl peer"], rows)
    if "discrete" in modes:
        ours = frame_hits(output_path(folder, "discrete", 1))
        for k, hits in fcl_hits.items():
            print(f"   collide discrete vs python-fcl {k}: {compare_hits(ours, hits)}")
    return peer_name, peer


def accept_continuous(runs, modes, peer_name, peer):
    """ACCEPTANCE lines: continuous <= 2x discrete, continuous <= 1x the python-fcl peer."""
    if "continuous" in modes and "discrete" in modes:
        cd = per_repeat_ratio(scan_seconds(runs[("continuous", 1)]), scan_seconds(runs[("discrete", 1)]))
        acceptance("continuous / discrete scan stage (workers 1)", cd, "<= 2x", cd <= 2)
    if "continuous" in modes:
        cf = per_repeat_ratio(scan_seconds(runs[("continuous", 1)]), peer)
        acceptance(f"continuous scan stage (workers 1) / python-fcl discrete {peer_name}", cf, "<= 1x", cf <= 1)


def accept_discrete_fcl(runs, modes, peer_name, peer, fcl_hits, folder, target_applies, scene=""):
    """ACCEPTANCE lines: discrete <= 1x python-fcl; the (frame, pair) sets agree."""
    if "discrete" not in modes:
        return
    df = per_repeat_ratio(scan_seconds(runs[("discrete", 1)]), peer)
    target = "<= 1x" if target_applies else f"<= 1x at {scene}; reported"
    acceptance(f"discrete scan stage (workers 1) / python-fcl {peer_name}", df, target, df <= 1)
    ours = frame_hits(output_path(folder, "discrete", 1))
    same = all(ours == h for h in fcl_hits.values())
    print(f"ACCEPTANCE: collide discrete and python-fcl ({', '.join(fcl_hits)}) (frame, pair) contact sets agree: "
          f"{'met' if same else 'NOT met'}")


def accept_workers(runs, identical, modes, workers_list, target_applies, scene):
    """ACCEPTANCE lines: whole-process speed-up of more workers, contacts identical."""
    for mode in modes:
        for workers in workers_list:
            if workers == 1:
                continue
            sp = per_repeat_ratio(walls(runs[(mode, 1)]), walls(runs[(mode, workers)]))
            ss = per_repeat_ratio(scan_seconds(runs[(mode, 1)]), scan_seconds(runs[(mode, workers)]))
            target = ">= 1.8x" if target_applies else f">= 1.8x on {scene}; reported"
            print(f"ACCEPTANCE: {mode} whole process --workers 1 / --workers {workers} = {sp:.3g}x (target {target}; "
                  f"scan stage {ss:.2f}x): {'met' if sp >= 1.8 else 'NOT met'}")
        if len(workers_list) > 1:
            print(f"ACCEPTANCE: {mode} contacts identical across --workers {','.join(map(str, workers_list))} "
                  f"(every round, byte for byte): {'met' if identical[mode] else 'NOT met'}")


# --- in-process breakdown of the scan stage ---------------------------------------------------

#: the steps of collide.pipeline.scan's scan stage, timed by wrapping them (this process only)
SCAN_STEPS = ("_run_discrete", "_run_swept", "_run_steps", "intervals_from_hits", "intervals_from_steps",
              "smallest_pairs_at_frames", "_fill_contact_points")


def scan_steps(meshes, trajectory, mode, workers=1):
    """Run ``collide.scan`` in this process with the steps of its scan stage wrapped in
    timers (collide.pipeline's module attributes, restored afterwards; nothing else
    changes). Returns (scan stage seconds, {step: seconds})."""
    import collide
    from collide import pipeline
    times = {}
    originals = {name: getattr(pipeline, name) for name in SCAN_STEPS}

    def timed(name, function):
        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                times[name] = times.get(name, 0.0) + time.perf_counter() - start
        return wrapper

    collide.scan(meshes, trajectory, mode=mode, workers=workers, frames="0:2")   # kernels loaded
    try:
        for name, function in originals.items():
            setattr(pipeline, name, timed(name, function))
        result = collide.scan(meshes, trajectory, mode=mode, workers=workers)
    finally:
        for name, function in originals.items():
            setattr(pipeline, name, function)
    return result.stats["scan_s"], times


_LEVELS = None


def _swept_levels_kernel():
    """A numba driver that repeats collide.swept.scan_intervals' loop over steps and object
    pairs (one thread) but stops at a given level: 1 object pairs (boxes, sweep and prune,
    swept spheres), 2 + BVH tandem descent (broad.RULE_SWEPT leaf pairs), 3 + triangle pair
    boxes (narrow.swept_candidates), the CCD queries being all that the full kernel adds.
    Sub-stepped pairs (work count ``substeps``) are treated as whole steps here. Compiled
    on first use (not cached: it inlines collide's kernels)."""
    global _LEVELS
    if _LEVELS is not None:
        return _LEVELS
    from numba import njit

    from collide.broad import RULE_SWEPT, sweep_and_prune
    from collide.discrete import object_margins, object_world_boxes, pair_leaves, pair_scratch
    from collide.filters import pair_selected
    from collide.motion import MOTION_WIDTH, step_motions
    from collide.narrow import new_stamps, swept_candidates
    from collide.rows import COUNT_WIDTH
    from collide.swept import place_pair_leaves, spheres_meet

    @njit(nogil=True)
    def levels(ps, poses, static, pairs, interpolation, dist_tol, level):
        n_objects = poses.shape[1]
        n_world = ps.world_start[n_objects]
        world0 = np.empty((n_world, 3))
        world1 = np.empty((n_world, 3))
        stamp0 = new_stamps(n_world)
        stamp1 = new_stamps(n_world)
        scratch = pair_scratch()
        stack = np.empty((64, 2), np.int64)
        leaves = np.empty((256, 2), np.int64)
        cand = np.empty((64, 2), np.int64)
        counts = np.zeros(COUNT_WIDTH, np.int64)
        margin = np.empty(n_objects)
        motion = np.empty((n_objects, MOTION_WIDTH))
        kept = 0
        for k in range(poses.shape[0] - 1):
            rp0 = poses[k]
            rp1 = poses[k + 1]
            object_margins(ps, rp0, rp1, margin)
            step_motions(interpolation, rp0, rp1, margin, motion)
            lo, hi = object_world_boxes(ps, rp0, rp1, motion, dist_tol, margin)
            candidates = sweep_and_prune(lo, hi)
            meet = spheres_meet(ps, rp0, rp1, motion, margin, dist_tol, candidates)
            for c in range(candidates.shape[0]):
                a = candidates[c, 0]
                b = candidates[c, 1]
                if not pair_selected(pairs, a, b) or not meet[c]:
                    continue
                pair_margin = margin[a] + margin[b] + dist_tol
                kept += 1
                if level < 2:
                    continue
                stack, leaves, n_leaves = pair_leaves(ps, rp0, rp1, motion, a, b, RULE_SWEPT, pair_margin, scratch,
                                                      stack, leaves, counts)
                if level < 3 or n_leaves == 0:
                    continue
                place_pair_leaves(ps, rp0, rp1, k, a, b, static, leaves, n_leaves, stamp0, world0, stamp1, world1)
                cand, n, _ = swept_candidates(leaves, n_leaves, ps.node_first, ps.node_count, ps.prim_ids, ps.faces,
                                            ps.face_start[ps.object_mesh[a]], ps.face_start[ps.object_mesh[b]],
                                            world0, world1, ps.world_start[a], ps.world_start[b], motion[a],
                                            motion[b], dist_tol, -np.inf, np.inf, cand, counts)
        return kept, counts

    _LEVELS = levels
    return levels


def kernel_breakdown(meshes, trajectory, repeat=3, interpolation="screw"):
    """Where one thread's kernel time goes, in this process (medians of ``repeat``):
    {"discrete frame kernel": s (collide.discrete.scan_frames, all frames, yes/no),
     "swept: object pairs": s, "swept: + BVH descent": s, "swept: + triangle boxes": s,
     "swept: full kernel": s (collide.swept.scan_intervals)}, plus the compile time of the
    driver ("compile driver")."""
    from collide import config
    from collide.discrete import scan_frames
    from collide.filters import build_filters
    from collide.load import load_scene
    from collide.motion import INTERPOLATIONS
    from collide.packed import pack_scene
    from collide.pipeline import scene_size
    from collide.swept import scan_intervals

    scene = load_scene(meshes, trajectory)
    ps, _ = pack_scene(scene.meshes, scene.object_mesh)
    poses = scene.poses.read(0, scene.poses.n_frames)
    filters = build_filters(scene.names, (), (), scene.ignore, scene.trajectory_path)
    pairs = filters.kernel_filter(extra_ignore=scene.static)
    dist_tol = config.DIST_TOL_REL * scene_size(ps, scene.poses)
    code = INTERPOLATIONS[interpolation]
    n = poses.shape[0]
    start = time.perf_counter()
    levels = _swept_levels_kernel()
    levels(ps, poses[:2], scene.static, pairs, code, dist_tol, 3)
    compile_s = time.perf_counter() - start
    scan_frames(ps, poses[:2], scene.static, pairs, 0, 2, False, True)
    # every pair searched in full (scan() passes the frame contacts, which spare some searches)
    no_hits = (np.zeros(0, np.int64), np.zeros((0, 2), np.int64))
    scan_intervals(ps, poses[:2], scene.static, pairs, *no_hits, 0, 1, False, code, config.TIME_TOL, dist_tol,
                   config.ONE_SIDED_LEAVES, config.PROBED_FACES, config.PROBE_LEAF_PAIRS)
    jobs = {"discrete frame kernel": lambda: scan_frames(ps, poses, scene.static, pairs, 0, n, False, True),
            "swept: object pairs": lambda: levels(ps, poses, scene.static, pairs, code, dist_tol, 1),
            "swept: + BVH descent": lambda: levels(ps, poses, scene.static, pairs, code, dist_tol, 2),
            "swept: + triangle boxes": lambda: levels(ps, poses, scene.static, pairs, code, dist_tol, 3),
            "swept: full kernel": lambda: scan_intervals(ps, poses, scene.static, pairs, *no_hits, 0, n - 1, False,
                                                         code, config.TIME_TOL, dist_tol,
                                                         config.ONE_SIDED_LEAVES, config.PROBED_FACES,
                                                         config.PROBE_LEAF_PAIRS)}
    times = {k: [] for k in jobs}
    for _ in range(repeat):
        for name, job in jobs.items():
            start = time.perf_counter()
            job()
            times[name].append(time.perf_counter() - start)
    out = {k: median(v) for k, v in times.items()}
    out["compile driver"] = compile_s
    return out


def print_breakdown(meshes, trajectory, mode_list, n_frames, repeat, print_table, frames=None):
    """Section 3: the in-process breakdowns (scan stage steps; kernel levels), on the first
    ``frames`` frames (default all)."""
    what = "all frames"
    if frames is not None and frames < n_frames:
        trajectory, n_frames = first_frames(trajectory, frames), frames
        what = f"the first {n_frames} frames"
    print(f"\n3. where the time goes (in this process, one thread, {what}; scan stage steps: one run each; "
          f"kernels: medians of {repeat})")
    rows = []
    for mode in mode_list:
        stage, steps = scan_steps(meshes, trajectory, mode)
        rest = stage - sum(steps.values())
        rows.append([mode, stage] + [steps.get(s, 0.0) for s in SCAN_STEPS] + [rest])
    print_table(["scan stage", "total s", *[s.strip("_") for s in SCAN_STEPS], "other s"], rows)
    print("   (smallest_pairs_at_frames: searches each contact that begins at a frame for its smallest "
          "triangle pair there, in --workers threads)")
    if "continuous" not in mode_list:
        return
    b = kernel_breakdown(meshes, trajectory, repeat)
    steps = max(n_frames - 1, 1)
    full = b["swept: full kernel"]
    rows = [["discrete frame kernel (scan_frames, all frames)", b["discrete frame kernel"],
             1e6 * b["discrete frame kernel"] / n_frames, ""]]
    previous = 0.0
    for name in ("swept: object pairs", "swept: + BVH descent", "swept: + triangle boxes"):
        share = f"{100 * (b[name] - previous) / full:.0f}%"
        rows.append([name + " (cumulative)", b[name], 1e6 * b[name] / steps, share])
        previous = b[name]
    share = f"{100 * (full - previous) / full:.0f}% (CCD queries)"
    rows.append(["swept: full kernel (scan_intervals)", full, 1e6 * full / steps, share])
    print_table(["kernel", "s", "us per frame/step", "share of the swept kernel"], rows)
    print(f"   swept full kernel / discrete frame kernel: {full / b['discrete frame kernel']:.1f}x "
          f"(driver compiled in {b['compile driver']:.0f} s, untimed)")



def first_frames(trajectory, frames):
    """A copy of a poses/matrix trajectory file with its first ``frames`` frames only
    (next to it, named traj_first<N>.h5); returns its path."""
    trajectory = Path(trajectory)
    out = trajectory.with_name(f"{trajectory.stem}_first{frames}.h5")
    with h5py.File(trajectory, "r") as src, h5py.File(out, "w") as dst:
        dst["time"] = src["time"][:frames]
        for name in ("objects/name", "objects/mesh"):
            if name in src:
                dst.create_dataset(name, data=src[name].asstr()[()].tolist(), dtype=h5py.string_dtype())
        dst["poses/matrix"] = src["poses/matrix"][:frames]
    return out
