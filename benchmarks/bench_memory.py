"""Issue 12, long trajectories in bounded memory: peak memory and time of a scan against
the number of frames.

    python benchmarks/bench_memory.py [--frames 10000,100000,1000000] [--modes discrete]
                                      [--out FOLDER]

Scene: the 4 bodies of bench_frames.py (two static obstacles, two moving parts), for
each number of frames. Each scan runs as its own process (``collide scan``, one worker)
and its peak resident memory is the kernel's count for that process (VmHWM, reset as the
process starts: Linux only).

Two ways of holding poses, in the same run:

- ``blocks``: collide as shipped: at most config.POSE_BLOCK_BYTES (64 MB) of poses at a
  time, read from the file block by block (once to check them, once to scan);
- ``one block``: the same scan with the block size raised above the trajectory's size,
  so that every pose is read at once and held throughout (how collide worked before).

Target (issue 12): peak memory independent of the number of frames beyond the output
(frame times), and 100 000 frames continuous (one worker) under a minute.
"""
import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_frames import DT, MOVING, make_meshes, motion
from benchlib import print_table
from scalelib import env_note, write_scene

#: runs collide's command line with config.POSE_BLOCK_BYTES set to argv[1], and prints the
#: process's peak resident memory (VmHWM) on stderr as it exits. The peak is reset first:
#: a child started from this (large) process would otherwise count this one's memory too
RUNNER = ("import atexit, sys; open('/proc/self/clear_refs', 'w').write('5'); "
          "atexit.register(lambda: print(next(l for l in open('/proc/self/status') if l.startswith('VmHWM')), "
          "file=sys.stderr)); "
          "from collide import config; config.POSE_BLOCK_BYTES = int(sys.argv[1]); "
          "from collide_cli.main import main; sys.argv = ['collide'] + sys.argv[2:]; main()")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", default="10000,100000,1000000")
    parser.add_argument("--modes", default="discrete,continuous")
    parser.add_argument("--continuous-max-frames", type=int, default=100_000,
                        help="continuous scans only up to this many frames (they take about 1 s per 10 000)")
    parser.add_argument("--out", help="folder for the scenes (default: a temporary folder, removed)")
    args = parser.parse_args(argv)
    print(f"machine: {env_note()}")
    header = ("frames", "mode", "poses", "pose MiB", "wall s", "scan s", "peak MiB", "contacts")
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-memory-") as tmp:
        root = Path(args.out or tmp)
        for n in (int(f) for f in args.frames.split(",")):
            folder = root / f"f{n}"
            meshes_dir, traj = write_scene(folder, make_meshes(), MOVING, motion(n), dt=DT)
            pose_mib = n * 4 * 12 * 8 / 2**20
            for mode in args.modes.split(","):
                if mode == "continuous" and n > args.continuous_max_frames:
                    continue
                found = set()
                for label, block in (("blocks", 64 * 2**20), ("one block", 2**62)):
                    wall, peak_mib, summary = measure(meshes_dir, traj, mode, block, folder / "c.h5")
                    found.add(summary["contacts"])
                    rows.append((str(n), mode, label, f"{pose_mib:.0f}", f"{wall:.1f}",
                                 f"{summary['seconds']['scan']:.1f}", f"{peak_mib:.0f}", str(summary["contacts"])))
                    print(f"  {n} frames, {mode}, {label}: {wall:.1f} s, peak {peak_mib:.0f} MiB",
                          file=sys.stderr, flush=True)
                if len(found) != 1:
                    raise SystemExit(f"{n} frames, {mode}: the contacts differ between block sizes: {found}")
    print_table(header, rows)
    print(f"machine after: {env_note()}")
    return 0


def measure(meshes, traj, mode, block_bytes, out):
    """(wall s, peak resident MiB, JSON summary) of one scan in a process of its own."""
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", RUNNER, str(block_bytes), "scan", str(meshes), str(traj),
                             "-o", str(out), "--mode", mode, "--workers", "1", "--format", "json", "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stdout, stderr = proc.communicate()
    wall = time.perf_counter() - start
    if proc.returncode not in (0, 1):
        raise SystemExit(f"scan failed: {stderr[-500:]}")
    peak_kib = int(stderr.strip().splitlines()[-1].split()[1])  # "VmHWM:  432220 kB"
    return wall, peak_kib / 1024, json.loads(stdout)


if __name__ == "__main__":
    sys.exit(main())
