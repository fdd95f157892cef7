"""Loading and validating inputs (SPEC §2): a folder of meshes and an HDF5 trajectory.

Every problem raises ``InputError(file, problem, expected, dataset)`` before
any work starts, so a bad input never costs a long run or a broken output.
"""
import logging
import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from . import config
from .errors import InputError

log = logging.getLogger("collide")

QUATERNION_ORDERS = ("wxyz", "xyzw")


class Mesh(NamedTuple):
    name: str           #: file stem
    path: Path
    vertices: np.ndarray  #: float64 (V, 3), body coordinates
    faces: np.ndarray     #: int64 (F, 3), the file's faces in order


class Trajectory(NamedTuple):
    path: Path
    time: np.ndarray      #: float64 (T,), seconds (or the file's unit)
    names: list           #: N object names
    mesh_files: list      #: N mesh file names or stems from objects/mesh, or None
    poses: np.ndarray     #: float64 (T, N, 3, 4): rows [R | p], world = R @ body + p


# --- meshes -----------------------------------------------------------------------------

def _mesh_suffixes():
    import trimesh
    # point clouds (xyz) can never hold triangles; everything else trimesh reads as a mesh counts
    return {"." + ext.lower() for ext in trimesh.exchange.load.mesh_formats() if ext != "xyz"}


def mesh_files(folder):
    """Mesh files of a folder, sorted by name: {stem: path}. Validates the folder."""
    folder = Path(folder)
    if not folder.exists():
        raise InputError(folder, "no such folder", "a folder of mesh files")
    if not folder.is_dir():
        raise InputError(folder, "not a folder", "a folder of mesh files (STL, OBJ, PLY, OFF, GLB, ...)")
    suffixes = _mesh_suffixes()
    try:
        entries = sorted(folder.iterdir())
    except OSError as exc:
        raise InputError(folder, f"cannot list folder ({exc.strerror})", "a readable folder") from None
    found = {}
    for path in entries:
        if path.name.startswith(".") or not path.is_file() or path.suffix.lower() not in suffixes:
            log.info("%s: not a mesh file, ignored", path)
            continue
        if path.stem in found:
            raise InputError(path, f"duplicate mesh name {path.stem!r} (also {found[path.stem].name})",
                             "one mesh file per object name")
        found[path.stem] = path
    if not found:
        raise InputError(folder, "no mesh files found",
                         "mesh files trimesh can load (STL, OBJ, PLY, OFF, GLB, ...)")
    return found


def load_mesh(path):
    """Load one mesh file as triangles, faces exactly as the file lists them.

    Multi-part files (scenes) are merged in order. Raises InputError for
    unreadable files, no triangles or non-finite vertices.
    """
    import trimesh
    path = Path(path)
    if not os.access(path, os.R_OK):
        raise InputError(path, "cannot read file (permission denied)", "a readable mesh file")
    try:
        loaded = trimesh.load(str(path), process=False, force="mesh")
    except Exception as exc:  # trimesh raises many exception types for bad files
        if isinstance(exc, ImportError):  # trimesh's fallback for undecodable text files
            msg = f"content is not {path.suffix.lstrip('.').upper()} that trimesh can parse"
        else:
            msg = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
        raise InputError(path, f"cannot load mesh ({msg})", "a valid triangle mesh file") from None
    vertices = np.asarray(getattr(loaded, "vertices", np.empty((0, 3))), dtype=np.float64)
    faces = np.asarray(getattr(loaded, "faces", np.empty((0, 3))), dtype=np.int64)
    if faces.ndim != 2 or faces.shape[0] == 0 or faces.shape[1] != 3:
        raise InputError(path, "mesh has no triangles", "at least one triangle")
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(path, f"vertices have shape {vertices.shape}", "(V, 3) vertices")
    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices)).any(axis=1).sum())
        raise InputError(path, f"{bad} vertices are NaN or infinite", "finite vertex coordinates")
    if faces.min() < 0 or faces.max() >= vertices.shape[0]:
        raise InputError(path, "faces index missing vertices", f"indices in [0, {vertices.shape[0]})")
    return Mesh(path.stem, path, np.ascontiguousarray(vertices), np.ascontiguousarray(faces))


# --- trajectory ----------------------------------------------------------------------------

def _open_hdf5(path):
    import h5py
    path = Path(path)
    if not path.exists():
        raise InputError(path, "no such file", "an HDF5 trajectory file")
    if path.is_dir():
        raise InputError(path, "is a folder", "an HDF5 trajectory file")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        detail = "not an HDF5 file or truncated" if "signature" in str(exc) or "truncated" in str(exc) \
            else str(exc).split("(")[0].strip()[:100]
        raise InputError(path, f"cannot open as HDF5 ({detail})", "an HDF5 trajectory file (SPEC §2.2)") \
            from None


def _dataset(h5, path, name, expected):
    import h5py
    if name not in h5:
        raise InputError(path, "missing dataset", expected, dataset=name)
    obj = h5[name]
    if not isinstance(obj, h5py.Dataset):
        raise InputError(path, "is a group, not a dataset", expected, dataset=name)
    return obj


def _float_array(h5, path, name, shape, expected):
    """Read a numeric dataset as float64, checking shape (None = any) and finiteness."""
    ds = _dataset(h5, path, name, expected)
    if ds.dtype.kind not in "fiu":
        raise InputError(path, f"has dtype {ds.dtype}", f"numbers: {expected}", dataset=name)
    try:
        data = np.asarray(ds[()], dtype=np.float64)
    except (OSError, ValueError) as exc:
        raise InputError(path, f"cannot read ({str(exc)[:80]})", expected, dataset=name) from None
    if len(shape) != data.ndim or any(s is not None and s != d for s, d in zip(shape, data.shape)):
        want = "(" + ", ".join("T" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise InputError(path, f"has shape {data.shape}", f"shape {want}: {expected}", dataset=name)
    if not np.isfinite(data).all():
        idx = np.argwhere(~np.isfinite(data))[0]
        raise InputError(path, f"non-finite value at index {tuple(int(i) for i in idx)}",
                         "finite numbers", dataset=name)
    return np.ascontiguousarray(data)


def _strings(h5, path, name, expected):
    ds = _dataset(h5, path, name, expected)
    if ds.dtype.kind not in "SOU" or ds.ndim != 1:
        raise InputError(path, f"has dtype {ds.dtype} and shape {ds.shape}", expected, dataset=name)
    try:
        values = ds.asstr()[()] if ds.dtype.kind in "SO" else ds[()]
    except (OSError, ValueError, TypeError, UnicodeDecodeError):
        raise InputError(path, "cannot read as UTF-8 strings", expected, dataset=name) from None
    return [str(v) for v in values]


def _read_time(h5, path):
    time = _float_array(h5, path, "time", (None,), "strictly increasing float times (T,), T >= 1")
    if time.shape[0] < 1:
        raise InputError(path, "is empty", "at least one frame time", dataset="time")
    steps = np.diff(time)
    if (steps <= 0).any():
        k = int(np.argmax(steps <= 0))
        raise InputError(path, f"not strictly increasing at index {k + 1} ({float(time[k])!r} then {float(time[k + 1])!r})",
                         "strictly increasing times", dataset="time")
    return time


def _read_names(h5, path):
    names = _strings(h5, path, "objects/name", "a 1-D string dataset of unique object names")
    seen = set()
    for name in names:
        if name in seen:
            raise InputError(path, f"duplicate object name {name!r}", "unique names",
                             dataset="objects/name")
        if not name:
            raise InputError(path, "empty object name", "non-empty names", dataset="objects/name")
        seen.add(name)
    mesh_entries = None
    if "objects/mesh" in h5:
        mesh_entries = _strings(h5, path, "objects/mesh", "a 1-D string dataset of mesh file names")
        if len(mesh_entries) != len(names):
            raise InputError(path, f"has {len(mesh_entries)} entries but objects/name has {len(names)}",
                             "one mesh file name per object", dataset="objects/mesh")
    return names, mesh_entries


def quaternions_to_matrices(q, order):
    """Unit quaternions (..., 4) in ``order`` ("wxyz" or "xyzw") -> rotations (..., 3, 3)."""
    if order == "xyzw":
        x, y, z, w = np.moveaxis(q, -1, 0)
    else:
        w, x, y, z = np.moveaxis(q, -1, 0)
    r = np.empty(q.shape[:-1] + (3, 3))
    r[..., 0, 0] = 1 - 2 * (y * y + z * z)
    r[..., 0, 1] = 2 * (x * y - w * z)
    r[..., 0, 2] = 2 * (x * z + w * y)
    r[..., 1, 0] = 2 * (x * y + w * z)
    r[..., 1, 1] = 1 - 2 * (x * x + z * z)
    r[..., 1, 2] = 2 * (y * z - w * x)
    r[..., 2, 0] = 2 * (x * z - w * y)
    r[..., 2, 1] = 2 * (y * z + w * x)
    r[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def _poses_from_quaternions(h5, path, n_frames, n_objects):
    position = _float_array(h5, path, "poses/position", (n_frames, n_objects, 3),
                            f"positions (T={n_frames}, N={n_objects}, 3)")
    orientation = _float_array(h5, path, "poses/orientation", (n_frames, n_objects, 4),
                               f"unit quaternions (T={n_frames}, N={n_objects}, 4)")
    order = h5["poses/orientation"].attrs.get("quaternion_order")
    if order is None:
        raise InputError(path, "missing attribute quaternion_order", 'quaternion_order = "wxyz" or "xyzw"',
                         dataset="poses/orientation")
    order = order.decode() if isinstance(order, bytes) else str(order)
    if order not in QUATERNION_ORDERS:
        raise InputError(path, f"unknown quaternion_order {order!r}", '"wxyz" or "xyzw"',
                         dataset="poses/orientation")
    norm = np.linalg.norm(orientation, axis=-1)
    off = np.abs(norm - 1.0)
    if (off > config.QUATERNION_NORM_TOL).any():
        t, o = np.unravel_index(int(np.argmax(off)), off.shape)
        raise InputError(path, f"quaternion of norm {norm[t, o]:.6g} at frame {t}, object {o}",
                         f"unit quaternions (norm within {config.QUATERNION_NORM_TOL} of 1)",
                         dataset="poses/orientation")
    if (off > 1e-12).any():
        log.warning("%s:poses/orientation: normalising quaternions (largest norm error %.2g)",
                    path, float(off.max()))
    rotation = quaternions_to_matrices(orientation / norm[..., None], order)
    return np.concatenate([rotation, position[..., None]], axis=-1)


def _poses_from_matrices(h5, path, n_frames, n_objects):
    matrix = _float_array(h5, path, "poses/matrix", (n_frames, n_objects, 4, 4),
                          f"rigid 4x4 transforms (T={n_frames}, N={n_objects}, 4, 4)")
    last_row = np.abs(matrix[..., 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=-1)
    if (last_row > config.MATRIX_LAST_ROW_TOL).any():
        t, o = np.unravel_index(int(np.argmax(last_row)), last_row.shape)
        raise InputError(path, f"last row is {matrix[t, o, 3].tolist()} at frame {t}, object {o}",
                         "last row 0 0 0 1", dataset="poses/matrix")
    rotation = matrix[..., :3, :3]
    gram = np.einsum("...ki,...kj->...ij", rotation, rotation)
    error = np.abs(gram - np.eye(3)).max(axis=(-2, -1))
    det = np.linalg.det(rotation)
    bad = (error > config.ROTATION_ORTHONORMAL_TOL) | (det <= 0)
    if bad.any():
        t, o = np.argwhere(bad)[0]
        raise InputError(path, f"not a rigid transform at frame {t}, object {o} "
                         f"(|R^T R - I| = {error[t, o]:.3g}, det = {det[t, o]:.3g})",
                         f"a rotation (orthonormal within {config.ROTATION_ORTHONORMAL_TOL}, det > 0) "
                         "and a translation", dataset="poses/matrix")
    return np.ascontiguousarray(matrix[..., :3, :])


def load_trajectory(path):
    """Read and validate a trajectory file (SPEC §2.2)."""
    path = Path(path)
    with _open_hdf5(path) as h5:
        try:
            time = _read_time(h5, path)
            names, mesh_entries = _read_names(h5, path)
            has_quat = "poses/position" in h5 or "poses/orientation" in h5
            has_matrix = "poses/matrix" in h5
            if has_quat and has_matrix:
                raise InputError(path, "has both poses/matrix and poses/position + poses/orientation",
                                 "one of the two pose encodings", dataset="poses")
            if has_matrix:
                poses = _poses_from_matrices(h5, path, time.shape[0], len(names))
            elif has_quat:
                poses = _poses_from_quaternions(h5, path, time.shape[0], len(names))
            else:
                raise InputError(path, "missing dataset",
                                 "poses/position + poses/orientation, or poses/matrix", dataset="poses")
        except InputError:
            raise
        except (OSError, KeyError, RuntimeError) as exc:
            raise InputError(path, f"cannot read ({str(exc)[:100]})", "a readable HDF5 trajectory") \
                from None
    return Trajectory(path, time, names, mesh_entries, poses)


# --- scene: meshes + trajectory ------------------------------------------------------------

class Scene(NamedTuple):
    names: list            #: N object names: trajectory objects, then static meshes
    meshes: list           #: M distinct Mesh objects
    object_mesh: np.ndarray  #: int64 (N,), index into meshes
    time: np.ndarray       #: float64 (T,)
    poses: np.ndarray      #: float64 (T, N, 3, 4)
    static: np.ndarray     #: bool (N,): identity pose at every frame
    trajectory_path: Path


def _resolve_mesh(files, entry, traj_path, dataset):
    """Mesh path for an objects/name or objects/mesh entry (stem or file name)."""
    if entry in files:
        return files[entry]
    for path in files.values():
        if path.name == entry:
            return path
    known = ", ".join(sorted(files)[:10]) + (", ..." if len(files) > 10 else "")
    raise InputError(traj_path, f"unknown mesh {entry!r}", f"a mesh file in the meshes folder ({known})",
                     dataset=dataset)


def load_scene(meshes_folder, trajectory_path):
    """Validate and load everything a scan needs."""
    files = mesh_files(meshes_folder)
    traj = load_trajectory(trajectory_path)
    dataset = "objects/name" if traj.mesh_files is None else "objects/mesh"
    entries = traj.names if traj.mesh_files is None else traj.mesh_files
    used = [_resolve_mesh(files, entry, traj.path, dataset) for entry in entries]
    used_set = set(used)
    static_paths = [p for stem, p in sorted(files.items()) if p not in used_set]
    taken = set(traj.names)
    for p in static_paths:
        if p.stem in taken:
            raise InputError(traj.path, f"object name {p.stem!r} is also an unused mesh file",
                             "names that do not clash with static meshes", dataset="objects/name")
    mesh_paths = sorted(used_set) + static_paths
    meshes = [load_mesh(p) for p in mesh_paths]
    index = {p: i for i, p in enumerate(mesh_paths)}
    object_mesh = np.array([index[p] for p in used + static_paths], dtype=np.int64)
    names = list(traj.names) + [p.stem for p in static_paths]
    n_frames = traj.time.shape[0]
    identity = np.zeros((3, 4))
    identity[:, :3] = np.eye(3)
    static_poses = np.broadcast_to(identity, (n_frames, len(static_paths), 3, 4))
    poses = np.ascontiguousarray(np.concatenate([traj.poses, static_poses], axis=1))
    static = (poses == identity).all(axis=(0, 2, 3))
    return Scene(names, meshes, object_mesh, traj.time, poses, static, traj.path)
