"""Cold start: how long the first scan takes on a fresh machine, and the CI cache recipe.

    python benchmarks/bench_cold_start.py [--mode continuous] [--keep DIR]

Makes a fresh virtual environment from a copy of this repository (``pip install .``,
with pip's own download cache, so mostly offline), then, with an empty kernel cache:

1. cold: the quick-start scan of the bundled fixture, whole process (it compiles the
   kernels, in parallel processes when it finds the cache cold);
2. warm: the same scan again (loads the kernels);
3. restored: a second virtual environment, installed from a second copy of the
   repository at another path, with the first one's kernel folder copied to a new
   place (what a CI cache restore does): the scan must compile nothing. Checked by the
   absence of the compile notice and by the kernel folder's file list not changing.

Prints the wall times and exits 1 if the restored run compiled anything.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def copy_repo(target):
    """The repository's tracked and new (not ignored) files, copied to target."""
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard"], cwd=REPO, check=True,
                           capture_output=True, text=True).stdout.split()
    for name in files:
        source = REPO / name
        if source.is_file():
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name)
    return target


def make_venv(folder, source):
    """A fresh virtual environment at folder with collide installed from source; returns its bin/."""
    subprocess.run([sys.executable, "-m", "venv", str(folder)], check=True)
    bin_dir = folder / "bin"
    start = time.perf_counter()
    subprocess.run([str(bin_dir / "python"), "-m", "pip", "install", "--quiet", str(source)], check=True)
    print(f"  pip install into {folder}: {time.perf_counter() - start:.1f} s")
    return bin_dir


def scan(bin_dir, kernel_dir, mode, cwd):
    """One quick-start scan; returns (seconds, stderr)."""
    env = dict(os.environ, COLLIDE_KERNEL_CACHE_DIR=str(kernel_dir), COLLIDE_CACHE_DIR=str(kernel_dir.parent / "m"))
    env.pop("NUMBA_CACHE_DIR", None)
    start = time.perf_counter()
    proc = subprocess.run([str(bin_dir / "collide"), "scan", "examples/fixture/meshes", "examples/fixture/traj.h5",
                           "-o", "contacts.h5", "--mode", mode], cwd=cwd, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"scan failed: {proc.stderr}")
    return time.perf_counter() - start, proc.stderr


def files_of(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mode", choices=["continuous", "discrete"], default="continuous")
    parser.add_argument("--keep", type=Path, help="work in this folder and keep it")
    args = parser.parse_args(argv)
    work = args.keep or Path(tempfile.mkdtemp(prefix="collide-cold-"))
    work.mkdir(parents=True, exist_ok=True)
    first = copy_repo(work / "checkout-a")
    second = copy_repo(work / "another" / "checkout-b")
    bin_a = make_venv(work / "venv-a", first)
    bin_b = make_venv(work / "another" / "venv-b", second)
    kernels = work / "cache-a" / "kernels"
    cold, notice = scan(bin_a, kernels, args.mode, first)
    warm, _ = scan(bin_a, kernels, args.mode, first)
    restored_dir = work / "restored" / "kernels"
    shutil.copytree(kernels, restored_dir)
    before = files_of(restored_dir)
    restored, restored_err = scan(bin_b, restored_dir, args.mode, second)
    new_files = sorted(set(files_of(restored_dir)) - set(before))
    compiled = "compil" in restored_err or any(name.endswith((".nbi", ".nbc")) for name in new_files)
    print(f"{args.mode} quick-start scan, whole process:")
    print(f"  cold (empty kernel cache): {cold:6.1f} s   {notice.strip().splitlines()[0] if notice.strip() else ''}")
    print(f"  warm:                      {warm:6.1f} s")
    print(f"  restored cache, another venv at another path: {restored:6.1f} s, "
          f"{'COMPILED: ' + ', '.join(new_files) if compiled else 'compiled nothing'}")
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if compiled else 0


if __name__ == "__main__":
    sys.exit(main())
