"""Primitive CCD on the benchmark queries of Wang et al. 2021: collide vs ipctk, in one run.

    python benchmarks/bench_ccd.py [QUERIES_FOLDER]     (default ../shared/data/ccd-queries)

For every scene and query kind: false negatives (must be 0), false positives, and
microseconds per query (warm; the first JIT compile is timed separately). collide runs its
batched numba kernel on one thread (NUMBA_NUM_THREADS=1 is set below) so the comparison is
per core; ipctk's Tight-Inclusion and additive CCD (``pip install -e .[bench]``) run one
query per Python call, so their times include about a microsecond of call overhead.
"""
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "tests"))

from ccd_queries import KINDS, read_scene, scenes  # noqa: E402
from collide.ccd import edge_edge_toi, vertex_face_toi  # noqa: E402

COLLIDE = {"vertex-face": vertex_face_toi, "edge-edge": edge_edge_toi}


def run_collide(kind, x_t0, x_t1):
    start = time.perf_counter()
    toi = COLLIDE[kind](x_t0, x_t1, time_tol=1e-6)
    return np.isfinite(toi), time.perf_counter() - start


def run_ipctk(solver, kind, x_t0, x_t1):
    method = solver.point_triangle_ccd if kind == "vertex-face" else solver.edge_edge_ccd
    hits = np.zeros(x_t0.shape[0], dtype=bool)
    start = time.perf_counter()
    for i in range(x_t0.shape[0]):
        a, b = x_t0[i], x_t1[i]
        hits[i] = method(a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3])[0]
    return hits, time.perf_counter() - start


def main():
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parent.parent / "shared" / "data" / "ccd-queries"
    if not root.is_dir():
        sys.exit(f"no queries at {root}")
    start = time.perf_counter()
    for kind in KINDS:  # compile both kernels once
        COLLIDE[kind](np.zeros((1, 4, 3)), np.ones((1, 4, 3)))
    print(f"collide first JIT (both kinds, incl. cache load): {time.perf_counter() - start:.2f} s")
    methods = [("collide", None)]
    try:
        import ipctk
        methods += [("ipctk TI", ipctk.TightInclusionCCD()), ("ipctk additive", ipctk.AdditiveCCD())]
    except ImportError:
        print("ipctk not installed: pip install -e .[bench]")
    totals = {name: [0, 0, 0, 0.0] for name, _ in methods}  # queries, FN, FP, seconds
    print(f"{'scene':<26} {'kind':<12} {'n':>5} {'pos':>4}  " +
          "  ".join(f"{name + ' FN/FP/us':>26}" for name, _ in methods))
    for scene in scenes(root):
        for kind in KINDS:
            x_t0, x_t1, truth = read_scene(scene, kind)
            cells = []
            for name, solver in methods:
                hits, seconds = (run_collide(kind, x_t0, x_t1) if solver is None
                                 else run_ipctk(solver, kind, x_t0, x_t1))
                fn, fp = int((truth & ~hits).sum()), int((~truth & hits).sum())
                t = totals[name]
                t[0] += truth.size
                t[1] += fn
                t[2] += fp
                t[3] += seconds
                cells.append(f"{fn:>6} / {fp:>4} / {1e6 * seconds / truth.size:>8.1f}")
            print(f"{scene.name:<26} {kind:<12} {truth.size:>5} {truth.sum():>4}  " + "  ".join(
                f"{c:>26}" for c in cells))
    print()
    print(f"{'method':<16} {'queries':>8} {'FN':>4} {'FP':>6} {'us/query':>9} {'vs collide':>11}")
    base = totals["collide"][3]
    for name, (n, fn, fp, seconds) in totals.items():
        print(f"{name:<16} {n:>8} {fn:>4} {fp:>6} {1e6 * seconds / n:>9.1f} {seconds / base:>10.2f}x")


if __name__ == "__main__":
    main()
