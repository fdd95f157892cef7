"""FCL's env/rob mesh-mesh test, timed side by side: collide vs python-fcl vs coal.

rob.obj (216 triangles) under random rigid poses (FCL's own distribution: translation
uniform in [-3000,3000]^2 x [0,3000], three uniform Euler angles) against a static
env.obj (2180 triangles). Every tool is asked for *all* intersecting triangle pairs at
every pose (the FCL test's question), and separately for a yes/no answer.

    python benchmarks/bench_envrob.py [--poses 5000] [--workers 2]

Peers are optional (pip install -e .[bench]); a missing peer is reported, not hidden.
Times are wall clock, warm (BVH built and kernels compiled before timing), single thread
unless stated. Agreement is measured against collide's exact pair sets.
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "tests"))

from fcl_poses import fcl_model, fcl_poses  # noqa: E402

from collide.discrete import scan_frames  # noqa: E402
from collide.filters import build_filters  # noqa: E402
from collide.load import load_mesh  # noqa: E402
from collide.packed import pack_scene  # noqa: E402
from collide.pipeline import TrianglePairs, _run_discrete  # noqa: E402

DATA = HERE.parent / "tests" / "data"


def run_collide(env, rob, rot, trans, split, workers):
    n = rot.shape[0]
    poses = np.zeros((n, 2, 3, 4))
    poses[:, 0, :, :3] = rot
    poses[:, 0, :, 3] = trans
    poses[:, 1, :, :3] = np.eye(3)
    static = np.array([False, True])
    filters = build_filters(["rob", "env"])
    pairs = filters.kernel_filter()
    start = time.perf_counter()
    ps, build_s = pack_scene([rob, env], np.array([0, 1]), split)
    scan_frames(ps, poses, static, pairs, 0, 2, True, False)  # compile / warm up
    scan_frames(ps, poses, static, pairs, 0, 2, False, True)
    out = {"build_s": build_s}
    t0 = time.perf_counter()
    _, found, _ = scan_frames(ps, poses, static, pairs, 0, n, True, False)
    out["all pairs"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    hits, _, _ = scan_frames(ps, poses, static, pairs, 0, n, False, True)
    out["yes/no"] = time.perf_counter() - t0
    out["colliding"] = set(hits[:, 0].tolist())
    t0 = time.perf_counter()
    _run_discrete(ps, poses, n, 0, static, filters, TrianglePairs(), workers, None)
    out[f"all pairs, {workers} threads"] = time.perf_counter() - t0
    sets = [set() for _ in range(n)]
    for f, _, _, a, b in found.tolist():
        sets[f].add((b, a))  # (env triangle, rob triangle)
    out["setup_s"] = time.perf_counter() - start
    return out, sets


def run_fcl(env, rob, rot, trans):
    import fcl

    env_obj = fcl.CollisionObject(fcl_model(fcl, env), fcl.Transform())
    rob_obj = fcl.CollisionObject(fcl_model(fcl, rob), fcl.Transform())
    out = {}
    sets = []
    for mode, max_contacts in (("all pairs", 1_000_000), ("yes/no", 1)):
        t0 = time.perf_counter()
        for k in range(rot.shape[0]):
            rob_obj.setTransform(fcl.Transform(rot[k], trans[k]))
            request = fcl.CollisionRequest(num_max_contacts=max_contacts, enable_contact=True)
            result = fcl.CollisionResult()
            fcl.collide(env_obj, rob_obj, request, result)
            if max_contacts > 1:
                sets.append({(c.b1, c.b2) for c in result.contacts})
        out[mode] = time.perf_counter() - t0
    return out, sets


def run_coal(env, rob, rot, trans):
    import coal

    def model(mesh):
        m = coal.BVHModelOBBRSS()
        m.beginModel(len(mesh.faces), len(mesh.vertices))
        m.addVertices(np.ascontiguousarray(mesh.vertices))
        m.addTriangles(np.ascontiguousarray(mesh.faces, dtype=np.int64))
        m.endModel()
        return m

    env_model, rob_model = model(env), model(rob)
    identity = coal.Transform3s()
    out = {}
    sets = []
    for mode, max_contacts in (("all pairs", 1_000_000), ("yes/no", 1)):
        request = coal.CollisionRequest(coal.CollisionRequestFlag.CONTACT, max_contacts)
        t0 = time.perf_counter()
        for k in range(rot.shape[0]):
            pose = coal.Transform3s(rot[k], trans[k])
            result = coal.CollisionResult()
            coal.collide(env_model, identity, rob_model, pose, request, result)
            if max_contacts > 1:
                sets.append({(c.b1, c.b2) for c in result.getContacts()})
        out[mode] = time.perf_counter() - t0
    return out, sets


def compare(reference, sets):
    """(poses with a different pair set, pairs reported but not touching, touching pairs missed)."""
    bad = extra = missed = 0
    for ref, got in zip(reference, sets):
        if ref != got:
            bad += 1
            extra += len(got - ref)
            missed += len(ref - got)
    return bad, extra, missed


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=5000)
    parser.add_argument("--split", default="sah")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    env, rob = load_mesh(DATA / "env.obj"), load_mesh(DATA / "rob.obj")
    rot, trans = fcl_poses(args.poses, seed=0)
    n = args.poses
    times, reference = run_collide(env, rob, rot, trans, args.split, args.workers)
    n_pairs = sum(len(s) for s in reference)
    n_colliding = sum(1 for s in reference if s)
    print(f"env/rob: {n} poses, {n_colliding} colliding, {n_pairs} intersecting triangle pairs "
          f"(collide, split={args.split}, BVH build {1000 * times['build_s']:.1f} ms)")
    assert times["colliding"] == {f for f, s in enumerate(reference) if s}  # yes/no agrees with all pairs
    rows = [("collide", "all pairs", times["all pairs"], (0, 0, 0)),
            ("collide", f"all pairs, {args.workers} threads", times[f"all pairs, {args.workers} threads"],
             (0, 0, 0)),
            ("collide", "yes/no", times["yes/no"], None)]
    for name, runner in (("python-fcl", run_fcl), ("coal", run_coal)):
        try:
            peer_times, sets = runner(env, rob, rot, trans)
        except ImportError as exc:
            print(f"{name}: not installed ({exc}); pip install -e .[bench]")
            continue
        agreement = compare(reference, sets)
        rows.append((name, "all pairs", peer_times["all pairs"], agreement))
        rows.append((name, "yes/no", peer_times["yes/no"], None))
    base = {r[1]: r[2] for r in rows if r[0] == "coal"}
    print(f"{'tool':<11} {'question':<22} {'us/pose':>9} {'coal/this':>9}  differing poses / "
          f"non-touching pairs reported / touching pairs missed")
    for name, mode, seconds, agreement in rows:
        per_pose = 1e6 * seconds / n
        ref = base.get("all pairs" if mode.startswith("all pairs") else mode)
        ratio = f"{ref / seconds:9.2f}" if ref else "        -"
        agree = "" if agreement is None else " / ".join(map(str, agreement))
        print(f"{name:<11} {mode:<22} {per_pose:9.1f} {ratio}  {agree}")


if __name__ == "__main__":
    main()
