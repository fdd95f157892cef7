"""A/B of the scan stage between two source trees of collide, in alternating fresh processes.

    python benchmarks/ab_scan.py MESHES TRAJ --base ../collide-before [--new .] [--mode continuous]
                                 [--rounds 7] [--workers 1] [--interpolation screw]

How the changes logged in benchmarks/README.md were measured: each round runs one scan
with each tree (``PYTHONPATH`` set to it, so its own source and its own compiled kernels
are used), in a fresh process, the order alternating from round to round, so that both
see the same machine state on a shared machine. Reports each tree's median scan stage
(``collide.scan(...).stats["scan_s"]``: the scan, not loading or start-up), the median of
the per-round ratios new / base, and whether the two trees' contacts are identical, column
by column and bit for bit (a SHA-256 over every column's name, dtype and bytes).

A tree is a checkout of this repository (make one of an older commit with ``git worktree
add ../collide-before COMMIT``). Each tree compiles its kernels on its first scan (about
80 s on two cores; an untimed first round does it), into the kernel cache shared by both:
a tree's kernels are keyed by the content of its ``collide/`` sources. Scenes: keep one
from a scale benchmark with ``--out FOLDER`` (``FOLDER/meshes``, ``FOLDER/traj.h5``).

Read small ratios with care: the same code in both trees (an A/A run, 9 rounds) read 1.03
on a 1.5 ms scan and 1.08 on a 20 ms one on this project's shared two-core machine.
Exits 1 when the contacts differ.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

#: what each fresh process runs: one scan through the Python API, then its timing, the
#: contacts' digest and where collide was imported from, as one JSON line
_CHILD = """
import hashlib, json, logging, sys
logging.disable(logging.CRITICAL)
import collide
meshes, traj, mode, interpolation, workers = sys.argv[1:6]
result = collide.scan(meshes, traj, mode=mode, interpolation=interpolation, workers=int(workers))
digest = hashlib.sha256()
for name in sorted(result.contacts):
    column = result.contacts[name]
    digest.update(name.encode() + str(column.dtype).encode() + column.tobytes())
print(json.dumps({"scan_s": result.stats["scan_s"], "contacts": digest.hexdigest(),
                  "rows": int(len(result.contacts["t_begin"])), "collide": collide.__file__}))
"""


def scan_once(tree, args, mode):
    """One scan in a fresh process with ``tree`` first on the import path: its JSON record."""
    env = dict(os.environ, PYTHONPATH=str(Path(tree).resolve()), OPENBLAS_NUM_THREADS="1")
    # run from a neutral folder: ``python -c`` puts the current folder first on the import path
    done = subprocess.run([sys.executable, "-c", _CHILD, str(args.meshes.resolve()), str(args.traj.resolve()), mode,
                           args.interpolation, str(args.workers)], env=env, capture_output=True, text=True,
                          cwd=tempfile.gettempdir())
    if done.returncode != 0:
        sys.exit(f"the scan with {tree} failed (exit {done.returncode}):\n{done.stderr.strip()}")
    record = json.loads(done.stdout.strip().splitlines()[-1])
    if Path(record["collide"]).resolve().parent.parent != Path(tree).resolve():
        sys.exit(f"{tree}: collide was imported from {record['collide']}, not from this tree "
                 "(is collide installed in a way that overrides PYTHONPATH?)")
    return record


def compare(args, mode):
    """Alternating rounds of one mode; prints the medians, the ratio and the contacts' verdict."""
    trees = {"base": args.base, "new": args.new}
    print(f"{mode}: an untimed scan with each tree first (about 80 s each if its kernels are not compiled yet)",
          flush=True)
    for tree in trees.values():
        scan_once(tree, args, mode)
    records = {name: [] for name in trees}
    for round_ in range(args.rounds):
        for name in ("base", "new") if round_ % 2 == 0 else ("new", "base"):
            records[name].append(scan_once(trees[name], args, mode))
    seconds = {name: [r["scan_s"] for r in rows] for name, rows in records.items()}
    ratios = [n / b for n, b in zip(seconds["new"], seconds["base"])]
    print(f"{mode}, {args.rounds} rounds, --workers {args.workers}:")
    for name in trees:
        print(f"  {name:4s} {trees[name]}: scan stage median {statistics.median(seconds[name]) * 1e3:.3f} ms, "
              f"min {min(seconds[name]) * 1e3:.3f} ms")
    print(f"  new / base: {statistics.median(ratios):.3f} (median of the per-round ratios)")
    digests = {name: {r["contacts"] for r in rows} for name, rows in records.items()}
    for name, found in digests.items():
        if len(found) > 1:
            print(f"  {name}: contacts differ between rounds of the same tree")
    same = digests["base"] == digests["new"] and len(digests["base"]) == 1
    rows = {name: records[name][0]["rows"] for name in trees}
    print(f"  contacts: {'identical' if same else 'DIFFERENT'} (rows: base {rows['base']}, new {rows['new']})")
    return same


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", type=Path)
    parser.add_argument("traj", type=Path)
    parser.add_argument("--base", type=Path, required=True, help="the tree measured against (a checkout)")
    parser.add_argument("--new", type=Path, default=Path(__file__).resolve().parent.parent,
                        help="the tree measured (default: this checkout)")
    parser.add_argument("--mode", choices=["continuous", "discrete", "both"], default="continuous")
    parser.add_argument("--interpolation", choices=["screw", "linear-vertex"], default="screw")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args(argv)
    if args.rounds < 1 or args.workers < 1:
        parser.error("--rounds and --workers take a whole number of at least 1")
    for name in ("base", "new"):
        tree = getattr(args, name)
        if not (tree / "collide" / "__init__.py").is_file():
            parser.error(f"--{name} {tree}: not a checkout of collide (no collide/__init__.py there)")
    modes = ["discrete", "continuous"] if args.mode == "both" else [args.mode]
    identical = [compare(args, mode) for mode in modes]
    return 0 if all(identical) else 1


if __name__ == "__main__":
    sys.exit(main())
