"""Mesh and BVH statistics (``collide inspect``)."""
from .bvh import bvh_stats, timed_build
from .config import SPLIT_RULES
from .load import load_mesh, mesh_files


def inspect_meshes(folder, splits=SPLIT_RULES, leaf_size=None):
    """One row per (mesh, split rule): triangles, nodes, depth, leaf sizes, SAH cost, build seconds.

    Build times are of a second build, so they exclude the one-off JIT compilation.
    """
    rows = []
    for stem, path in mesh_files(folder).items():
        mesh = load_mesh(path)
        for split in splits:
            timed_build(mesh.vertices, mesh.faces, split, leaf_size)  # warm-up (JIT, caches)
            bvh, seconds = timed_build(mesh.vertices, mesh.faces, split, leaf_size)
            rows.append({"mesh": path.name, "triangles": int(mesh.faces.shape[0]), "split": split,
                         **bvh_stats(bvh), "build_s": seconds})
    return rows
