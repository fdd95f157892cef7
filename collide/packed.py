"""All meshes and their BVHs packed into flat arrays for the numba kernels.

M meshes, N objects (several objects may share one mesh). Per mesh m:
vertices ``vertices[vert_start[m]:vert_start[m+1]]``, faces
``faces[face_start[m]:face_start[m+1]]`` (mesh-local vertex indices), BVH nodes
from ``root[m]`` on, with ``first`` global (inner nodes: node index; leaves:
index into ``prim_ids``) and ``prim_ids`` holding mesh-local face indices.
Per object o: mesh ``object_mesh[o]``; its world vertices are rows
``world_start[o]:world_start[o+1]`` of a world buffer. Meshes of up to
config.LEAF_BOX_TRIANGLES triangles also get an oriented box per BVH leaf
(``leaf_box``, oriented_leaf_boxes), along the normal of the patch it holds.
"""
import time
from concurrent.futures import ThreadPoolExecutor
from typing import NamedTuple

import numpy as np

from . import config
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
    leaf_box: np.ndarray     #: float64 (rows, LEAF_BOX_WIDTH) leaves' oriented boxes (oriented_leaf_boxes) of
    #: the meshes that have them (config.LEAF_BOX_TRIANGLES), node by node
    leaf_box_shift: np.ndarray  #: int64 (M,) row of leaf_box = node + leaf_box_shift[m]; NO_LEAF_BOXES: none


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
        **_leaf_boxes(meshes, bvhs, node_start),
    )
    return packed, build_seconds


#: PackedScene.leaf_box_shift of a mesh without leaf boxes
NO_LEAF_BOXES = np.iinfo(np.int64).min


def _leaf_boxes(meshes, bvhs, node_start):
    """PackedScene's leaf_box and leaf_box_shift: oriented leaf boxes of the meshes of at most
    config.LEAF_BOX_TRIANGLES triangles."""
    boxes, shift, rows = [np.zeros((0, LEAF_BOX_WIDTH))], np.full(len(meshes), NO_LEAF_BOXES, np.int64), 0
    for m, (mesh, b) in enumerate(zip(meshes, bvhs)):
        if mesh.faces.shape[0] <= config.LEAF_BOX_TRIANGLES:
            boxes.append(oriented_leaf_boxes(b.first, b.count, b.prim_ids, mesh.faces, mesh.vertices))
            shift[m] = rows - node_start[m]
            rows += b.count.shape[0]
    return {"leaf_box": np.ascontiguousarray(np.concatenate(boxes)), "leaf_box_shift": shift}


#: columns of a leaf's oriented box (PackedScene.leaf_box): three orthonormal axes in the
#: body frame (the first along the leaf's triangles' summed normal), then its centre (body
#: coordinates), its half extents along the three axes, the range of the box along the
#: first axis (lo, hi: u . x for x in the box, u the first axis) and the size of the numbers
#: that range is computed from (for rounding bounds)
LEAF_BOX_WIDTH = 18
LEAF_AXES = 0
LEAF_CENTRE = 9
LEAF_HALF = 12
LEAF_NORMAL_LO = 15
LEAF_NORMAL_HI = 16
LEAF_SIZE = 17

#: slack added to every half extent of a leaf's oriented box, relative to the largest
#: |coordinate| of its vertices: far more than the rounding of the projections and of the
#: axes' orthonormality, so every vertex lies inside the box
_LEAF_SLACK = 2.0 ** -30


@njit(cache=True)
def oriented_leaf_boxes(first, count, prim_ids, faces, vertices):
    """float64 (nodes, LEAF_BOX_WIDTH): for each leaf (count > 0) of one mesh's BVH (first,
    count, prim_ids: mesh-local), a box holding its triangles (faces, vertices: the mesh),
    oriented along their summed normal (area-weighted; x, y, z when it vanishes) and two
    tangents: thin for the nearly flat patch a leaf usually is, where its axis-aligned box
    is as thick as the patch is tilted. Rows of inner nodes are zeros."""
    out = np.zeros((count.shape[0], LEAF_BOX_WIDTH))
    for node in range(count.shape[0]):
        if count[node] > 0:
            _leaf_box(first[node], count[node], prim_ids, faces, vertices, out, node)
    return out


@njit(cache=True, inline="always")
def _leaf_box(start, n, prim_ids, faces, vertices, out, node):
    """Row ``node`` of oriented_leaf_boxes, for the triangles prim_ids[start:start + n]."""
    nx = ny = nz = 0.0
    for j in range(start, start + n):
        f = prim_ids[j]
        a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
        u0, u1, u2 = vertices[b, 0] - vertices[a, 0], vertices[b, 1] - vertices[a, 1], vertices[b, 2] - vertices[a, 2]
        v0, v1, v2 = vertices[c, 0] - vertices[a, 0], vertices[c, 1] - vertices[a, 1], vertices[c, 2] - vertices[a, 2]
        nx += u1 * v2 - u2 * v1
        ny += u2 * v0 - u0 * v2
        nz += u0 * v1 - u1 * v0
    axes = _leaf_axes(nx, ny, nz)
    lo0 = lo1 = lo2 = np.inf
    hi0 = hi1 = hi2 = -np.inf
    largest = 0.0
    for j in range(start, start + n):
        for corner in range(3):
            v = faces[prim_ids[j], corner]
            x, y, z = vertices[v, 0], vertices[v, 1], vertices[v, 2]
            d0 = axes[0] * x + axes[1] * y + axes[2] * z
            d1 = axes[3] * x + axes[4] * y + axes[5] * z
            d2 = axes[6] * x + axes[7] * y + axes[8] * z
            lo0, hi0 = min(lo0, d0), max(hi0, d0)
            lo1, hi1 = min(lo1, d1), max(hi1, d1)
            lo2, hi2 = min(lo2, d2), max(hi2, d2)
            largest = max(largest, abs(x), abs(y), abs(z))
    mids = (0.5 * (lo0 + hi0), 0.5 * (lo1 + hi1), 0.5 * (lo2 + hi2))
    halves = (0.5 * (hi0 - lo0), 0.5 * (hi1 - lo1), 0.5 * (hi2 - lo2))
    for i in range(3):
        out[node, LEAF_HALF + i] = halves[i] + _LEAF_SLACK * largest
        for k in range(3):
            out[node, LEAF_AXES + 3 * i + k] = axes[3 * i + k]
    for k in range(3):
        out[node, LEAF_CENTRE + k] = mids[0] * axes[k] + mids[1] * axes[3 + k] + mids[2] * axes[6 + k]
    lo, hi, size = extent_along(out, node, IDENTITY_POSE, axes[0], axes[1], axes[2])
    out[node, LEAF_NORMAL_LO] = lo
    out[node, LEAF_NORMAL_HI] = hi
    out[node, LEAF_SIZE] = size


#: the identity pose as a pose tuple (motion.pose_tuple: [R | t] row by row)
IDENTITY_POSE = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)


@njit(cache=True, inline="always")
def extent_along(leaf_box, node, rp, u0, u1, u2):
    """The range of u . x over the oriented box of leaf ``node`` (rows of leaf_box) placed
    by pose tuple rp ([R | t] row by row), u a unit vector of the frame it is placed in:
    (lo, hi, the size of the numbers they are computed from, for rounding bounds)."""
    v0 = rp[0] * u0 + rp[4] * u1 + rp[8] * u2  # v = R^T u: u . (R x + t) = v . x + u . t
    v1 = rp[1] * u0 + rp[5] * u1 + rp[9] * u2
    v2 = rp[2] * u0 + rp[6] * u1 + rp[10] * u2
    c0, c1, c2 = leaf_box[node, LEAF_CENTRE], leaf_box[node, LEAF_CENTRE + 1], leaf_box[node, LEAF_CENTRE + 2]
    centre = (rp[3] * u0 + rp[7] * u1 + rp[11] * u2) + (v0 * c0 + v1 * c1 + v2 * c2)
    extent = 0.0
    for i in range(3):
        a = LEAF_AXES + 3 * i
        extent += leaf_box[node, LEAF_HALF + i] * abs(v0 * leaf_box[node, a] + v1 * leaf_box[node, a + 1]
                                                      + v2 * leaf_box[node, a + 2])
    size = abs(rp[3]) + abs(rp[7]) + abs(rp[11]) + abs(c0) + abs(c1) + abs(c2) + extent
    return centre - extent, centre + extent, size


@njit(cache=True, inline="always")
def _leaf_axes(nx, ny, nz):
    """Three orthonormal axes (a 9-tuple, axis by axis), the first along (nx, ny, nz); x, y
    and z when it is zero."""
    length = np.sqrt(nx * nx + ny * ny + nz * nz)
    if not length > 0.0:  # a leaf of degenerate triangles only
        return (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
    nx, ny, nz = nx / length, ny / length, nz / length
    # the first tangent: across the normal and the coordinate axis least along it
    if abs(nx) <= abs(ny) and abs(nx) <= abs(nz):
        tx, ty, tz = 0.0, nz, -ny
    elif abs(ny) <= abs(nz):
        tx, ty, tz = -nz, 0.0, nx
    else:
        tx, ty, tz = ny, -nx, 0.0
    t = np.sqrt(tx * tx + ty * ty + tz * tz)
    tx, ty, tz = tx / t, ty / t, tz / t
    sx, sy, sz = ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx
    s = np.sqrt(sx * sx + sy * sy + sz * sz)
    return (nx, ny, nz, tx, ty, tz, sx / s, sy / s, sz / s)


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
