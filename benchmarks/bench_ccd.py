"""Primitive CCD on the benchmark queries of Wang et al. 2021: collide vs ipctk, in one run.

    python benchmarks/bench_ccd.py [QUERIES] [--threads N] [--repeat R] [--time-tol T]
                                   [--warm-cache] [--skip-ipctk-wrapper]

QUERIES defaults to ../shared/data/ccd-queries (relative to the repository root). For
every scene and query kind, and for each method: false negatives (must be 0), false
positives, and microseconds per query (warm: best of R runs), plus the ratio of
collide's time to the method's (< 1: collide is faster).

Methods:
- collide: the batched numba kernels (collide.ccd), on N threads (default 1, so the
  comparison is per core). The first call's time (numba JIT compile, in a fresh cache
  directory unless --warm-cache) is reported separately.
- ipctk TI: ipctk.tight_inclusion.{point_triangle,edge_edge}_ccd, the Tight-Inclusion
  root finder itself (tolerance = time_tol, default iteration cap).
- ipctk TI-CCD: ipctk.TightInclusionCCD, ipctk's narrow-phase wrapper around it
  (conservative rescaling, retries near t = 0); slow on the degenerate scenes.
- ipctk additive: ipctk.AdditiveCCD (Li et al. 2021), not certified.
ipctk runs one query per Python call, so its times include ~1 us of call overhead.
ipctk is an optional extra for this benchmark only (``pip install ipctk``); collide
never imports it.
"""
import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "tests"))

from ccd_queries import KINDS, read_scene, scenes  # noqa: E402  (numpy only; no numba yet)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("queries", nargs="?", type=Path, default=REPO.parent / "shared" / "data" / "ccd-queries")
    parser.add_argument("--threads", type=int, default=1, help="numba threads for collide (default 1)")
    parser.add_argument("--repeat", type=int, default=5, help="timing runs per scene (best is kept)")
    parser.add_argument("--time-tol", type=float, default=1e-6)
    parser.add_argument("--warm-cache", action="store_true",
                        help="use numba's normal on-disk cache (first call = cache load, not a compile)")
    parser.add_argument("--skip-ipctk-wrapper", action="store_true", help="leave out the slow TightInclusionCCD")
    return parser.parse_args(argv)


def collide_methods(args):
    """Import collide only now: numba reads NUMBA_NUM_THREADS / NUMBA_CACHE_DIR on import.
    -> ({kind: batched function}, method(kind, x_t0, x_t1) -> hits)."""
    os.environ["NUMBA_NUM_THREADS"] = str(args.threads)
    if not args.warm_cache:
        os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="collide-bench-numba-")
    from collide.ccd import edge_edge_toi, vertex_face_toi

    functions = {"vertex-face": vertex_face_toi, "edge-edge": edge_edge_toi}

    def run(kind, x_t0, x_t1):
        return np.isfinite(functions[kind](x_t0, x_t1, time_tol=args.time_tol))
    return functions, run


def ipctk_methods(args):
    """[(name, function(kind, x_t0, x_t1) -> hits)] for the ipctk methods available."""
    try:
        import ipctk
    except ImportError:
        print("ipctk not installed (pip install ipctk): collide only\n")
        return []
    ipctk.set_logger_level(ipctk.LoggerLevel.off)  # it warns on queries touching at t = 0
    ti = ipctk.tight_inclusion

    def raw(kind, x_t0, x_t1):
        f = ti.point_triangle_ccd if kind == "vertex-face" else ti.edge_edge_ccd
        return np.array([f(*a, *b, tolerance=args.time_tol)[0] for a, b in zip(x_t0, x_t1)])

    def narrow_phase(solver):
        def run(kind, x_t0, x_t1):
            f = solver.point_triangle_ccd if kind == "vertex-face" else solver.edge_edge_ccd
            return np.array([f(*a, *b)[0] for a, b in zip(x_t0, x_t1)])
        return run

    methods = [("ipctk TI", raw)]
    if not args.skip_ipctk_wrapper:
        methods.append(("ipctk TI-CCD", narrow_phase(ipctk.TightInclusionCCD(tolerance=args.time_tol))))
    methods.append(("ipctk additive", narrow_phase(ipctk.AdditiveCCD())))
    return methods


def timed(method, kind, x_t0, x_t1, repeat):
    """(hits, best seconds over repeat runs)."""
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        hits = method(kind, x_t0, x_t1)
        best = min(best, time.perf_counter() - start)
    return hits, best


def main(argv=None):
    args = parse_args(argv)
    root = args.queries
    if not root.is_dir():
        sys.exit(f"bench_ccd: no queries at {root}")
    functions, run_collide = collide_methods(args)
    jit = {}
    for kind in KINDS:
        start = time.perf_counter()
        functions[kind](np.zeros((1, 4, 3)), np.ones((1, 4, 3)))
        jit[kind] = time.perf_counter() - start
    methods = [("collide", run_collide)] + ipctk_methods(args)
    cache = "numba on-disk cache" if args.warm_cache else "cold: fresh numba cache, includes compiling"
    print(f"collide first call ({cache}): vertex-face {jit['vertex-face']:.2f} s, "
          f"edge-edge {jit['edge-edge']:.2f} s (then warm)")
    print(f"queries: {root}   time_tol {args.time_tol:g}   collide threads: {args.threads}\n")

    header = f"{'scene':<25} {'kind':<11} {'method':<15} {'n':>5} {'pos':>4} {'FN':>3} {'FP':>4} " \
             f"{'us/query':>10} {'collide/this':>12}"
    print(header)
    print("-" * len(header))
    totals = {name: [0, 0, 0, 0.0] for name, _ in methods}  # queries, FN, FP, seconds
    for scene in scenes(root):
        for kind in KINDS:
            x_t0, x_t1, truth = read_scene(scene, kind)
            n = truth.size
            base = None
            for name, method in methods:
                repeat = args.repeat if name in ("collide", "ipctk TI", "ipctk additive") else 1
                hits, seconds = timed(method, kind, x_t0, x_t1, repeat)
                fn, fp = int((truth & ~hits).sum()), int((~truth & hits).sum())
                base = seconds if base is None else base
                row = totals[name]
                row[0] += n
                row[1] += fn
                row[2] += fp
                row[3] += seconds
                print(f"{scene.name:<25} {kind:<11} {name:<15} {n:>5} {int(truth.sum()):>4} {fn:>3} {fp:>4} "
                      f"{1e6 * seconds / n:>10.1f} {base / seconds:>12.3f}")
        print()
    print(f"{'all scenes':<25} {'':<11} {'method':<15} {'n':>5} {'':>4} {'FN':>3} {'FP':>4} "
          f"{'us/query':>10} {'collide/this':>12}")
    base = totals["collide"][3]
    for name, (n, fn, fp, seconds) in totals.items():
        print(f"{'':<25} {'':<11} {name:<15} {n:>5} {'':>4} {fn:>3} {fp:>4} {1e6 * seconds / n:>10.1f} "
              f"{base / seconds:>12.3f}")


if __name__ == "__main__":
    main()
