"""Cost of the screw motion against linear-vertex motion on the same scene (same run).

    python benchmarks/bench_interpolation.py [MESHES TRAJECTORY] [--repeat 5] [--workers 1]

Runs ``collide.scan`` in continuous mode with both interpolations, alternating, and
reports the median scan-stage time of each and their ratio (the machine is shared and
noisy: compare ratios measured in the same run). Default scene: the bundled fixture.
"""
import argparse
import statistics
import sys
from pathlib import Path

import collide

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "fixture"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", nargs="?", default=str(EXAMPLE / "meshes"))
    parser.add_argument("trajectory", nargs="?", default=str(EXAMPLE / "traj.h5"))
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args(argv)
    modes = ("linear-vertex", "screw")
    times = {m: [] for m in modes}
    contacts = {}
    for m in modes:  # warm-up: compile or load the kernels
        collide.scan(args.meshes, args.trajectory, interpolation=m, workers=args.workers)
    for _ in range(args.repeat):
        for m in modes:
            result = collide.scan(args.meshes, args.trajectory, interpolation=m, workers=args.workers)
            times[m].append(result.stats["scan_s"])
            contacts[m] = result.contacts["t_begin"].size
    median = {m: statistics.median(times[m]) for m in modes}
    for m in modes:
        print(f"{m:14s} scan stage median {median[m]:.3f} s over {args.repeat} runs "
              f"({contacts[m]} contact intervals)")
    print(f"ratio screw / linear-vertex: {median['screw'] / median['linear-vertex']:.2f}")


if __name__ == "__main__":
    sys.exit(main())
