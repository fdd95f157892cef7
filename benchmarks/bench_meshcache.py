"""Mesh cache: cold vs warm load + BVH build of one mesh.

    python benchmarks/bench_meshcache.py [MESH ...] [--sphere-triangles 200000] [--repeats 5]

Default meshes: tests/data/env.obj and a generated UV sphere of about 200k triangles
(saved as OBJ in a temporary folder). For each mesh, medians over the repeats of:

- parse: ``collide.load.load_mesh``; build: ``collide.bvh.build_mesh_bvh`` (SAH,
  default leaf size; numba kernels compiled before timing);
- first cached run: an empty cache, so a miss that parses, builds and writes both entries;
- warm: ``load_mesh_cached`` and ``mesh_bvh_cached`` reading the entries back (checks
  included). The file's SHA-256 is passed in, as a scan has it anyway (its time is shown).

The cache lives in a temporary folder (COLLIDE_CACHE_DIR), removed at the end.
"""
import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from collide import meshcache as mc  # noqa: E402
from collide.bvh import build_mesh_bvh  # noqa: E402
from collide.load import load_mesh  # noqa: E402

DATA = HERE.parent / "tests" / "data"


def median_seconds(function, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def first_cached_run(path, digest, workdir):
    os.environ[mc.CACHE_ENV] = tempfile.mkdtemp(dir=workdir)
    mesh = mc.load_mesh_cached(path, digest)
    mc.mesh_bvh_cached(mesh)
    shutil.rmtree(os.environ[mc.CACHE_ENV])


def bench(path, repeats, workdir):
    mesh = load_mesh(path)
    build_mesh_bvh(mesh.vertices, mesh.faces)  # compile or load the numba builder
    digest = mc.file_sha256(path)
    rows = {"sha256 of the file": median_seconds(lambda: mc.file_sha256(path), repeats),
            "parse (load_mesh)": median_seconds(lambda: load_mesh(path), repeats),
            "build (build_mesh_bvh)": median_seconds(lambda: build_mesh_bvh(mesh.vertices, mesh.faces), repeats),
            "first cached run (miss, store)": median_seconds(lambda: first_cached_run(path, digest, workdir),
                                                             max(1, repeats // 2))}
    os.environ[mc.CACHE_ENV] = tempfile.mkdtemp(dir=workdir)
    first_stats = mc.CacheStats()
    mc.mesh_bvh_cached(mc.load_mesh_cached(path, digest, stats=first_stats), stats=first_stats)
    stats = mc.CacheStats()
    rows["warm mesh (hit)"] = median_seconds(lambda: mc.load_mesh_cached(path, digest, stats=stats), repeats)
    rows["warm BVH (hit)"] = median_seconds(lambda: mc.mesh_bvh_cached(mesh, stats=stats), repeats)
    assert (stats.mesh_hits, stats.bvh_hits, stats.rejected) == (repeats, repeats, 0), stats
    _, entry_bytes = mc.cache_size()
    print(f"{path.name}: {mesh.faces.shape[0]} triangles, file {path.stat().st_size / 1e6:.2f} MB, "
          f"cache entries {entry_bytes / 1e6:.2f} MB")
    rows["cold total (parse + build)"] = rows["parse (load_mesh)"] + rows["build (build_mesh_bvh)"]
    rows["warm total (hits)"] = rows["warm mesh (hit)"] + rows["warm BVH (hit)"]
    for name, seconds in rows.items():
        print(f"  {name:32s} {seconds * 1000:9.1f} ms")


def sphere(triangles, folder):
    import trimesh
    count = max(4, int(round((triangles / 2) ** 0.5)) + 1)
    path = Path(folder) / f"sphere{triangles // 1000}k.obj"
    trimesh.creation.uv_sphere(count=[count, count]).export(path)
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("meshes", nargs="*", type=Path)
    parser.add_argument("--sphere-triangles", type=int, default=200_000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    workdir = tempfile.mkdtemp(prefix="collide-bench-cache-")
    try:
        meshes = args.meshes or [DATA / "env.obj", sphere(args.sphere_triangles, workdir)]
        for path in meshes:
            bench(path, args.repeats, workdir)
    finally:
        shutil.rmtree(workdir)


if __name__ == "__main__":
    main()
