"""All meshes and their BVHs packed into flat arrays for the numba kernels.

M meshes, N objects (several objects may share one mesh). Per mesh m:
vertices ``vertices[vert_start[m]:vert_start[m+1]]``, faces
``faces[face_start[m]:face_start[m+1]]`` (mesh-local vertex indices), BVH nodes
from ``root[m]`` on, with ``first`` global (inner nodes: node index; leaves:
index into ``prim_ids``) and ``prim_ids`` holding mesh-local face indices.
Per object o: mesh ``object_mesh[o]``; its world vertices are rows
``world_start[o]:world_start[o+1]`` of a world buffer.
"""
import time
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from .bvh import build_mesh_bvh
from .jit import njit


class PackedScene(NamedTuple):
    vertices: np.ndarray     #: float64 (sum V, 3) body coordinates
    vert_start: np.ndarray   #: int64 (M + 1,)
    faces: np.ndarray        #: int64 (sum F, 3) mesh-local vertex indices
    face_start: np.ndarray   #: int64 (M + 1,)
    node_lo: np.ndarray      #: float64 (sum nodes, 3)
    node_hi: np.ndarray      #: float64 (sum nodes, 3)
    node_first: np.ndarray   #: int64 (sum nodes,)
    node_count: np.ndarray   #: int64 (sum nodes,)
    prim_ids: np.ndarray     #: int64 (sum F,) mesh-local face indices
    root: np.ndarray         #: int64 (M,) root node of each mesh
    radius: np.ndarray       #: float64 (M,) max |body coordinate| of each mesh
    centre: np.ndarray       #: float64 (M, 3) body centre of each mesh (its root box centre)
    sphere_radius: np.ndarray  #: float64 (M,) max distance of a vertex from ``centre``
    object_mesh: np.ndarray  #: int64 (N,)
    world_start: np.ndarray  #: int64 (N + 1,)


def pack_scene(meshes, object_mesh, split="sah", leaf_size=None, build_bvh=None, workers=1):
    """Build one BVH per mesh and pack everything. Returns (PackedScene, build seconds).

    ``build_bvh`` (default build_mesh_bvh; same signature) builds one mesh's BVH, e.g.
    meshcache.MeshCache().build_mesh_bvh; its trees must be in smallest-id order (see
    collide.bvh), which the search for each contact's smallest triangle pair relies on.
    With ``workers`` > 1 several meshes build at once in threads (the top-down builders
    release the GIL; lbvh is parallel inside one build instead). The result does not
    depend on ``workers``.
    """
    start = time.perf_counter()
    build_bvh = build_mesh_bvh if build_bvh is None else build_bvh

    def build(mesh):
        return build_bvh(mesh.vertices, mesh.faces, split, leaf_size)
    if workers > 1 and len(meshes) > 1 and split != "lbvh":
        with ThreadPoolExecutor(max_workers=min(workers, len(meshes))) as pool:
            bvhs = list(pool.map(build, meshes))
    else:
        bvhs = [build(m) for m in meshes]
    build_seconds = time.perf_counter() - start
    n_verts = np.array([m.vertices.shape[0] for m in meshes], dtype=np.int64)
    n_faces = np.array([m.faces.shape[0] for m in meshes], dtype=np.int64)
    n_nodes = np.array([b.count.shape[0] for b in bvhs], dtype=np.int64)
    node_start = np.concatenate([[0], np.cumsum(n_nodes)])
    face_start = np.concatenate([[0], np.cumsum(n_faces)])
    node_first = []
    for m, b in enumerate(bvhs):
        # inner nodes point at nodes, leaves at prim_ids: shift both to global rows
        node_first.append(np.where(b.count == 0, b.first + node_start[m], b.first + face_start[m]))
    object_mesh = np.ascontiguousarray(object_mesh, dtype=np.int64)
    centre = np.array([0.5 * (b.lo[0] + b.hi[0]) for b in bvhs], dtype=np.float64).reshape(-1, 3)
    packed = PackedScene(
        vertices=np.ascontiguousarray(np.concatenate([m.vertices for m in meshes]), dtype=np.float64),
        vert_start=np.concatenate([[0], np.cumsum(n_verts)]).astype(np.int64),
        faces=np.ascontiguousarray(np.concatenate([m.faces for m in meshes]), dtype=np.int64),
        face_start=face_start.astype(np.int64),
        node_lo=np.ascontiguousarray(np.concatenate([b.lo for b in bvhs])),
        node_hi=np.ascontiguousarray(np.concatenate([b.hi for b in bvhs])),
        node_first=np.ascontiguousarray(np.concatenate(node_first), dtype=np.int64),
        node_count=np.ascontiguousarray(np.concatenate([b.count for b in bvhs]), dtype=np.int64),
        prim_ids=np.ascontiguousarray(np.concatenate([b.prim_ids for b in bvhs]), dtype=np.int64),
        root=node_start[:-1].astype(np.int64),
        radius=np.array([np.abs(m.vertices).max() for m in meshes], dtype=np.float64),
        centre=centre,
        sphere_radius=np.array([np.linalg.norm(m.vertices - c, axis=1).max() for m, c in zip(meshes, centre)]),
        object_mesh=object_mesh,
        world_start=np.concatenate([[0], np.cumsum(n_verts[object_mesh])]).astype(np.int64),
    )
    return packed, build_seconds


@njit(cache=True)
def to_world(body, rp, out, out_start):
    """out[out_start + i] = R @ body[i] + p for rp = [R | p] (3, 4).

    Evaluated as p + R0 x + R1 y + R2 z, left to right, so the identity pose
    reproduces body coordinates exactly.
    """
    for i in range(body.shape[0]):
        x = body[i, 0]
        y = body[i, 1]
        z = body[i, 2]
        for r in range(3):
            out[out_start + i, r] = rp[r, 3] + rp[r, 0] * x + rp[r, 1] * y + rp[r, 2] * z


def world_vertices(vertices, rp):
    """World coordinates of body vertices (V, 3) under rp = [R | p] (3, 4) (as the scan computes them)."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    out = np.empty_like(vertices)
    to_world(vertices, np.ascontiguousarray(rp, dtype=np.float64), out, 0)
    return out
