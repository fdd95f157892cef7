"""Loading and validating inputs: a folder of meshes and an HDF5 trajectory (README, "Inputs").

Every problem raises ``InputError(file, problem, expected, dataset)`` before
any work starts, so a bad input never costs a long run or a broken output.
"""
import contextlib
import errno
import fnmatch
import io
import itertools
import json
import logging
import os
import re
import stat
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import numpy as np

from . import config
from .errors import InputError, UsageError, escape_text
from .files import (
    cache_dir,
    check_memory,
    declared_size,
    hdf5_object,
    memory_limit,
    not_regular,
    open_hdf5,
    open_regular,
    os_problem,
)

log = logging.getLogger("collide")

QUATERNION_ORDERS = ("wxyz", "xyzw")


class Mesh(NamedTuple):
    name: str           #: file stem (or the name of a mesh given in memory)
    path: Path          #: its file; None for a mesh given in memory
    vertices: np.ndarray  #: float64 (V, 3), body coordinates
    faces: np.ndarray     #: int64 (F, 3), the file's faces in order


class Trajectory(NamedTuple):
    path: Path
    time: np.ndarray      #: float64 (T,), seconds (or the file's unit)
    names: list           #: N object names
    mesh_files: list      #: N mesh file names or stems from objects/mesh, or None
    poses: np.ndarray     #: float64 (S, N, 3, 4) at the S selected frames: rows [R | p], world = R @ body + p
    #: (None when load_trajectory was asked not to read them)
    pose_dataset: str = "poses/position"  #: where the positions came from (for messages)
    ignore: tuple = ()    #: (glob_a, glob_b) pairs of filters/ignore: object pairs never checked
    frame_index: np.ndarray = None  #: int64 (S,): the selected frames (indices into time)


# --- meshes -----------------------------------------------------------------------------

MESHES_FOLDER = "a folder of mesh files (STL, OBJ, PLY, OFF, GLB, ...)"
MESH_FILE = "a valid triangle mesh file"


def trimesh_version():
    """The installed trimesh's version, without importing trimesh (half a second)."""
    from importlib.metadata import version
    return version("trimesh")


def _mesh_suffixes():
    """File suffixes trimesh loads as meshes ({".stl", ".obj", ...}). Asking trimesh
    means importing it (half a second, most of a warm run's start-up), so the answer is
    kept in the cache folder per trimesh version and read from there when it is sound."""
    path = _suffix_file()
    try:
        known = json.loads(path.read_text()) if path is not None else None
        if isinstance(known, list) and known and all(
                isinstance(s, str) and re.fullmatch(r"\.[a-z0-9_]{1,15}", s) for s in known):
            return set(known)
    except (OSError, ValueError):
        pass  # not there yet, unreadable or not ours: ask trimesh
    import trimesh
    # point clouds (xyz) can never hold triangles; everything else trimesh reads as a mesh counts
    suffixes = {"." + ext.lower() for ext in trimesh.exchange.load.mesh_formats() if ext != "xyz"}
    if path is not None:
        temporary = path.with_name(f".{path.name}.{os.getpid()}")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            temporary.write_text(json.dumps(sorted(suffixes)))
            os.replace(temporary, path)
        except OSError:  # no writable cache folder: ask trimesh next time too
            try:
                temporary.unlink()
            except OSError:
                pass
    return suffixes


def _suffix_file():
    """Where _mesh_suffixes keeps trimesh's answer; None without a cache folder."""
    root = cache_dir()
    return None if root is None else root / f"trimesh-{trimesh_version()}-mesh-suffixes.json"


def mesh_files(folder, glob=None):
    """Mesh files of a folder, sorted by name: {stem: path}. Validates the folder.

    ``glob``: an fnmatch pattern on file names choosing which files are meshes (for
    folders holding the same mesh in several formats); default: every file with a
    suffix trimesh loads. Symbolic links are followed. A mesh-named entry that is
    not a regular file (FIFO, device, socket, dangling link) is an InputError;
    folders and files with other suffixes are ignored.
    """
    folder = Path(folder)
    try:
        info = os.stat(folder)
    except OSError as exc:
        problem = "no such folder" if exc.errno == errno.ENOENT else os_problem(exc)
        raise InputError(folder, problem, MESHES_FOLDER) from None
    if not stat.S_ISDIR(info.st_mode):
        raise InputError(folder, "not a folder", MESHES_FOLDER)
    suffixes = _mesh_suffixes()
    try:
        entries = sorted(folder.iterdir())
    except OSError as exc:
        raise InputError(folder, f"cannot list folder ({os_problem(exc)})", "a readable folder") from None
    found = {}
    for path in entries:
        if glob is not None and not fnmatch.fnmatchcase(path.name, glob):
            continue
        if path.name.startswith("."):
            log.info("%s: hidden file, ignored", escape_text(path))
            continue
        if path.suffix.lower() not in suffixes or not _is_mesh_entry(path):
            log.info("%s: not a mesh file, ignored", escape_text(path))
            continue
        if path.stem in found:
            raise InputError(path, f"duplicate mesh name {path.stem!r} (also {found[path.stem].name})",
                             f"one mesh file per object name (choose the files with --glob, e.g. "
                             f"--glob '*{path.suffix}' or --glob '*{found[path.stem].suffix}')")
        found[path.stem] = path
    if not found:
        if glob is not None:
            raise InputError(folder, f"no mesh files match --glob {glob!r}",
                             "a pattern matching mesh file names (e.g. '*.stl')")
        raise InputError(folder, "no mesh files found",
                         "mesh files trimesh can load (STL, OBJ, PLY, OFF, GLB, ...)")
    return found


def _is_mesh_entry(path):
    """True for a regular file (symlinks followed), False for a folder; InputError for
    anything else (a FIFO, device or socket named like a mesh, a dangling link)."""
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        problem = "dangling symbolic link" if os.path.islink(path) else os_problem(exc)
        raise InputError(path, problem, "a regular mesh file") from None
    if stat.S_ISDIR(mode):
        return False
    problem = not_regular(mode)
    if problem is not None:
        raise InputError(path, f"{problem}, not a regular file", "a regular mesh file")
    return True


def _mesh_resolver(folder):
    """A trimesh resolver for the files a mesh file references (GLTF buffers, OBJ
    materials): regular files inside ``folder`` only, never blocking on a FIFO."""
    import trimesh

    class FolderResolver(trimesh.resolvers.Resolver):
        def __init__(self, root):
            self.root = os.path.realpath(root)

        def get(self, name):
            for candidate in (str(name).strip(), os.path.basename(str(name).strip())):
                real = os.path.realpath(os.path.join(self.root, candidate.lstrip("/")))
                if os.path.commonpath([real, self.root]) == self.root and os.path.isfile(real):
                    try:
                        with open_regular(real, "an asset file") as f:
                            return f.read()
                    except InputError:
                        break
            raise FileNotFoundError(f"{name}: not a regular file in the meshes folder")

        def keys(self):
            return iter(())

        def namespaced(self, namespace):
            return self

        def write(self, name, data):
            raise OSError("collide never writes into the meshes folder")

    return FolderResolver(folder)


#: quoted text in a loader's message may be the file's own bytes: not echoed
_QUOTED = re.compile(r"'[^']*'|\"[^\"]*\"")


def _loader_message(exc, path):
    """A short description of why trimesh could not load ``path``, without quoting the
    file's content (a mesh file could be a symbolic link to a secret)."""
    if isinstance(exc, ImportError):  # trimesh's fallback for undecodable text files
        return f"content is not {path.suffix.lstrip('.').upper()} that trimesh can parse"
    text = str(exc).splitlines()[0] if str(exc).strip() else ""
    text = _QUOTED.sub("'...'", text)[:120]
    return text if re.search("[A-Za-z]{3}", text.replace("'...'", "")) else type(exc).__name__


def load_mesh(path):
    """Load one mesh file as triangles, faces exactly as the file lists them: triangle i
    is the file's i-th face, polygons fanned from their first corner in turn (trimesh's
    OBJ reader turns a quad's second triangle round: (c2, c3, c0), the same triangle).

    Multi-part files (scenes) are merged in order. Raises InputError for
    files that are not regular files, unreadable files, no triangles, non-finite
    vertices or coordinates beyond config.MAX_COORDINATE.
    """
    import trimesh
    path = Path(path)
    file_type = path.suffix.lstrip(".").lower()
    with open_regular(path, "a readable mesh file") as file_obj:
        try:
            if file_type == "obj":
                file_obj = _without_materials(file_obj)
            with _polygons_fanned_in_order():
                loaded = trimesh.load(file_obj, file_type=file_type, process=False, force="mesh",
                                      resolver=_mesh_resolver(path.parent))
        except Exception as exc:  # trimesh raises many exception types for bad files
            raise InputError(path, f"cannot load mesh ({_loader_message(exc, path)})", MESH_FILE) from None
    vertices = np.asarray(getattr(loaded, "vertices", np.empty((0, 3))))
    faces = np.asarray(getattr(loaded, "faces", np.empty((0, 3))))
    if file_type == "stl" and faces.size == 0:
        _check_binary_stl_size(path)  # trimesh reads a cut-off binary STL as an empty mesh
    return _checked_mesh(path.stem, path, vertices, faces, path)


def _check_binary_stl_size(path):
    """InputError if ``path`` is a binary STL whose size differs from what its header's
    triangle count needs (84 + 50 bytes per triangle): a file cut off, or padded. ASCII
    STL (starting with "solid" and holding "facet"; binary headers may start with "solid"
    too) is left to trimesh's reading."""
    with open_regular(path, "a readable mesh file") as f:
        head = f.read(1024)
        size = os.fstat(f.fileno()).st_size
    if len(head) < 84 or (head.lstrip().lower().startswith(b"solid") and b"facet" in head.lower()):
        return
    count = int.from_bytes(head[80:84], "little")
    expected = 84 + 50 * count
    if count > 0 and size != expected:
        how = "cut off?" if size < expected else f"{size - expected} bytes too many"
        raise InputError(path, f"binary STL header counts {count} triangles ({expected} bytes) but the file has "
                         f"{size} bytes ({how})", "a complete STL file")


def _without_materials(file_obj):
    """An OBJ file's bytes with every ``usemtl`` made inert, as a file object. trimesh splits
    an OBJ's faces into one part per material (at ``usemtl`` anywhere in the text, comments
    and names included) and merges the parts in another order than the file's; materials
    do not matter here, so the faces stay one part, in file order."""
    data = file_obj.read()
    return io.BytesIO(data.replace(b"usemtl", b"#semtl") if b"usemtl" in data else data)


@contextlib.contextmanager
def _polygons_fanned_in_order():
    """While trimesh reads a file here, it triangulates polygons with fans_in_order instead
    of its own triangulate_quads (in its PLY and OFF readers and where a mesh's faces are
    set), which puts the triangles first, then the quads' first halves, then their second
    halves, then other polygons (and fails on polygons of more than four corners read
    from OFF text). Restored afterwards, also when reading fails."""
    from trimesh import geometry
    from trimesh.exchange import off, ply
    with _TRIMESH_PATCH:
        saved = geometry.triangulate_quads, off.triangulate_quads, ply.triangulate_quads
        geometry.triangulate_quads = off.triangulate_quads = ply.triangulate_quads = fans_in_order
        try:
            yield
        finally:
            geometry.triangulate_quads, off.triangulate_quads, ply.triangulate_quads = saved


_TRIMESH_PATCH = threading.Lock()


def fans_in_order(polygons, dtype=np.int64, use_fan=True):
    """int64 (m, 3) triangles of polygons (a sequence of vertex index sequences, numbers or
    numeric text) in their order, each fanned from its first corner: polygon (c0, c1, ...,
    ck) gives (c0, c1, c2), (c0, c2, c3), ..., (c0, ck-1, ck). Polygons of fewer than
    three corners give none. (dtype and use_fan: triangulate_quads' parameters, ignored.)"""
    try:
        same = np.array(polygons, dtype=np.int64)  # one size: no Python loop over faces
    except (ValueError, TypeError):
        same = None
    if same is not None and same.ndim == 2:
        return _fans(same)
    sizes = np.fromiter(map(len, polygons), dtype=np.int64, count=len(polygons))
    corners = np.array(list(itertools.chain.from_iterable(polygons)), dtype=np.int64)
    starts = np.cumsum(sizes) - sizes  # each polygon's first corner in corners
    counts = np.maximum(sizes - 2, 0)
    out = np.empty((int(counts.sum()), 3), np.int64)
    first = np.cumsum(counts) - counts  # each polygon's first triangle row
    for size in np.unique(sizes[sizes >= 3]):
        which = np.flatnonzero(sizes == size)
        rows_of = first[which][:, None] + np.arange(size - 2)
        out[rows_of.reshape(-1)] = _fans(corners[starts[which][:, None] + np.arange(size)])
    return out


def _fans(polygons):
    """fans_in_order of int64 (n, k) polygons of one size k."""
    n, k = polygons.shape
    if k < 3:
        return np.zeros((0, 3), np.int64)
    out = np.empty((n, k - 2, 3), np.int64)
    out[:, :, 0] = polygons[:, :1]
    out[:, :, 1] = polygons[:, 1:-1]
    out[:, :, 2] = polygons[:, 2:]
    return out.reshape(-1, 3)


def _checked_mesh(name, path, vertices, faces, where):
    """A Mesh of these arrays, converted to float64 (V, 3) and int64 (F, 3), or InputError
    (naming ``where``) for no triangles, non-finite or huge coordinates, bad indices."""
    if vertices.dtype.kind not in "fiu" or faces.dtype.kind not in "iu":
        raise InputError(where, f"vertices of dtype {vertices.dtype} and faces of dtype {faces.dtype}",
                         "numeric vertices and integer faces")
    vertices = vertices.astype(np.float64)
    faces = faces.astype(np.int64)
    if faces.ndim != 2 or faces.shape[0] == 0 or faces.shape[1] != 3:
        raise InputError(where, "mesh has no triangles", "at least one triangle")
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(where, f"vertices have shape {vertices.shape}", "(V, 3) vertices")
    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices)).any(axis=1).sum())
        raise InputError(where, f"{bad} vertices are NaN or infinite", "finite vertex coordinates")
    largest = float(lengths(vertices).max(initial=0.0))
    if not largest <= config.MAX_COORDINATE:
        raise InputError(where, f"a vertex lies {largest:.3g} from the origin",
                         f"vertices within {config.MAX_COORDINATE:g} of the origin")
    if faces.min() < 0 or faces.max() >= vertices.shape[0]:
        raise InputError(where, "faces index missing vertices", f"indices in [0, {vertices.shape[0]})")
    return Mesh(name, path, np.ascontiguousarray(vertices), np.ascontiguousarray(faces))


# --- trajectory ----------------------------------------------------------------------------

TRAJECTORY = "an HDF5 trajectory file (time, objects/name, poses/...)"


class _Source(NamedTuple):
    """An open trajectory: the h5py.File, its path, and whether data outside it may be read."""
    h5: object
    path: Path
    allow_external: bool


def _dataset(src, name, expected):
    """The h5py.Dataset ``name``, refusing groups, missing names and data outside the file."""
    import h5py
    obj = hdf5_object(src.h5, src.path, name, src.allow_external)
    if obj is None:
        raise InputError(src.path, "missing dataset", expected, dataset=name)
    if not isinstance(obj, h5py.Dataset):
        raise InputError(src.path, "is a group, not a dataset", expected, dataset=name)
    return obj


def _exists(src, name):
    """Whether ``name`` exists (checked link by link, see files.hdf5_object)."""
    return hdf5_object(src.h5, src.path, name, src.allow_external) is not None


def _shape_text(shape):
    return "(" + ", ".join("T" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"


def _numeric(src, name, shape, expected):
    """A numeric dataset whose declared shape matches ``shape`` (None = any extent);
    nothing is read yet."""
    ds = _dataset(src, name, expected)
    if ds.dtype.kind not in "fiu":
        raise InputError(src.path, f"has dtype {ds.dtype}", f"numbers: {expected}", dataset=name)
    declared = ds.shape
    if declared is None:
        raise InputError(src.path, "has no dataspace (empty)", f"shape {_shape_text(shape)}: {expected}",
                         dataset=name)
    if len(shape) != len(declared) or any(s is not None and s != d for s, d in zip(shape, declared)):
        raise InputError(src.path, f"has shape {declared}", f"shape {_shape_text(shape)}: {expected}",
                         dataset=name)
    return ds


def _read_float(src, ds, name, expected):
    """Read a dataset (already checked by _numeric) as finite float64."""
    try:
        data = np.asarray(ds[()], dtype=np.float64)
    except (OSError, ValueError, TypeError, RuntimeError) as exc:
        raise InputError(src.path, f"cannot read ({str(exc)[:80]})", expected, dataset=name) from None
    if not np.isfinite(data).all():
        idx = np.argwhere(~np.isfinite(data))[0]
        raise InputError(src.path, f"non-finite value at index {tuple(int(i) for i in idx)}",
                         "finite numbers", dataset=name)
    return np.ascontiguousarray(data)


def _strings(src, name, expected):
    """A 1-D string dataset (declared; read later by _read_strings)."""
    ds = _dataset(src, name, expected)
    if ds.dtype.kind not in "SOU" or ds.shape is None or len(ds.shape) != 1:
        raise InputError(src.path, f"has dtype {ds.dtype} and shape {ds.shape}", expected, dataset=name)
    return ds


def _read_strings(src, ds, name, expected):
    try:
        values = ds.asstr()[()] if ds.dtype.kind in "SO" else ds[()]
    except (OSError, ValueError, TypeError, UnicodeDecodeError, RuntimeError):
        raise InputError(src.path, "cannot read as UTF-8 strings", expected, dataset=name) from None
    return [str(v) for v in values]


def _string_attr(src, obj, name, dataset):
    """A scalar string attribute of ``obj`` (None when absent); a large or non-string
    attribute is an InputError (it is never read in full)."""
    if name not in obj.attrs:
        return None
    try:
        shape = obj.attrs.get_id(name).shape
        if declared_size(shape) > 1:
            raise InputError(src.path, f"attribute {name} has shape {shape}", f"a single string {name}",
                             dataset=dataset)
        value = obj.attrs[name]
    except (OSError, ValueError, TypeError, KeyError, RuntimeError):
        raise InputError(src.path, f"cannot read attribute {name}", f"a string {name}", dataset=dataset) from None
    if isinstance(value, np.ndarray):
        value = value.reshape(-1)[0] if value.size else ""
    return value.decode(errors="replace") if isinstance(value, bytes) else str(value)


TIME = "strictly increasing float times (T,), T >= 1"
NAMES = "a 1-D string dataset of unique object names"
IGNORE = "a string dataset (K, 2) of object name glob pairs"
MESH_NAMES = "a 1-D string dataset of mesh file names"


def _read_time(src, ds):
    time = _read_float(src, ds, "time", TIME)
    if time.shape[0] < 1:
        raise InputError(src.path, "is empty", "at least one frame time", dataset="time")
    if not np.isfinite(time[-1] - time[0]):
        raise InputError(src.path, f"spans {float(time[0])!r} to {float(time[-1])!r}, beyond float64",
                         "times whose span (last - first) is a finite number", dataset="time")
    steps = np.diff(time)
    if (steps <= 0).any():
        k = int(np.argmax(steps <= 0))
        raise InputError(src.path, f"not strictly increasing at index {k + 1} ({float(time[k])!r} then "
                         f"{float(time[k + 1])!r})", "strictly increasing times", dataset="time")
    return time


def _read_names(src, names_ds, mesh_ds):
    names = _read_strings(src, names_ds, "objects/name", NAMES)
    seen = set()
    for name in names:
        if name in seen:
            raise InputError(src.path, f"duplicate object name {name!r}", "unique names", dataset="objects/name")
        if not name:
            raise InputError(src.path, "empty object name", "non-empty names", dataset="objects/name")
        seen.add(name)
    mesh_entries = None
    if mesh_ds is not None:
        mesh_entries = _read_strings(src, mesh_ds, "objects/mesh", MESH_NAMES)
    return names, mesh_entries


def _read_ignore(src):
    """filters/ignore as a tuple of (glob_a, glob_b) pairs (an allowed-collision list)."""
    ds = _dataset(src, "filters/ignore", IGNORE)
    if ds.dtype.kind not in "SOU" or ds.shape is None or len(ds.shape) != 2 or ds.shape[1] != 2:
        raise InputError(src.path, f"has dtype {ds.dtype} and shape {ds.shape}", IGNORE,
                         dataset="filters/ignore")
    check_memory(src.path, ds.shape[0] * 2 * config.STRING_BYTES, memory_limit(None), "an ignore list",
                 dataset="filters/ignore")
    try:
        values = ds.asstr()[()] if ds.dtype.kind in "SO" else ds[()]
    except (OSError, ValueError, TypeError, UnicodeDecodeError, RuntimeError):
        raise InputError(src.path, "cannot read as UTF-8 strings", IGNORE, dataset="filters/ignore") from None
    pairs = tuple((str(a), str(b)) for a, b in values)
    for a, b in pairs:
        if not a or not b:
            raise InputError(src.path, "empty pattern", IGNORE, dataset="filters/ignore")
    return pairs


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


def select_frames(frames, n_frames):
    """The frames selected by ``frames`` (None: all; a slice; or "START:STOP[:STEP]", a
    Python slice with a positive step), as a range of frame indices (nothing allocated:
    n_frames may be any declared size)."""
    if frames is None:
        return range(n_frames)
    if isinstance(frames, str):
        parts = frames.split(":")
        if len(parts) not in (2, 3):
            raise UsageError(f"--frames {frames!r}: not a slice; expected START:STOP[:STEP] (Python slice, "
                             "e.g. 0:100, -50: or ::2)")
        try:
            frames = slice(*(int(p) if p.strip() else None for p in parts))
        except ValueError:
            raise UsageError(f"--frames {frames!r}: not integers; expected integers in START:STOP[:STEP]") \
                from None
    parts = (frames.start, frames.stop) + (() if frames.step is None else (frames.step,))
    text = ":".join("" if v is None else str(v) for v in parts)
    if frames.step is not None and frames.step <= 0:
        raise UsageError(f"--frames {text}: the step is {frames.step}; expected a positive step")
    index = range(n_frames)[frames]
    if len(index) == 0:
        raise UsageError(f"--frames {text} selects no frame of the {n_frames} in the trajectory; expected "
                         f"a slice of frames 0 to {n_frames - 1} holding at least one (e.g. 0:{n_frames} or -10:)")
    return index


def _pose_datasets(src, n_frames, n_objects):
    """("quaternion" | "matrix", {name: dataset}) with declared shapes checked; nothing read."""
    has_quat = _exists(src, "poses/position") or _exists(src, "poses/orientation")
    has_matrix = _exists(src, "poses/matrix")
    if has_quat and has_matrix:
        raise InputError(src.path, "has both poses/matrix and poses/position + poses/orientation",
                         "one of the two pose encodings", dataset="poses")
    if has_matrix:
        return "matrix", {"poses/matrix": _numeric(src, "poses/matrix", (n_frames, n_objects, 4, 4),
                                                   f"rigid 4x4 transforms (T={n_frames}, N={n_objects}, 4, 4)")}
    if has_quat:
        return "quaternion", {
            "poses/position": _numeric(src, "poses/position", (n_frames, n_objects, 3),
                                       f"positions (T={n_frames}, N={n_objects}, 3)"),
            "poses/orientation": _numeric(src, "poses/orientation", (n_frames, n_objects, 4),
                                          f"unit quaternions (T={n_frames}, N={n_objects}, 4)")}
    raise InputError(src.path, "missing dataset", "poses/position + poses/orientation, or poses/matrix",
                     dataset="poses")


def lengths(vectors):
    """Euclidean lengths of float64 (..., 3) vectors -> (...,), without overflow for any
    finite input (scaled by the largest coordinate first)."""
    scale = np.abs(vectors).max(axis=-1, initial=0.0)
    safe = np.where(scale > 0, scale, 1.0)
    with np.errstate(all="ignore"):
        return scale * np.sqrt(((vectors / safe[..., None]) ** 2).sum(axis=-1))


def _check_positions(src, position, frames, dataset):
    """Refuse positions (S, N, 3) at file frames ``frames`` (S,) farther than
    config.MAX_COORDINATE from the origin (world coordinates that large overflow the
    exact tests)."""
    if not position.size or np.abs(position).max() <= config.MAX_COORDINATE / 2:  # then |p| <= 0.87 max
        return
    magnitude = lengths(position)
    if magnitude.size and not magnitude.max() <= config.MAX_COORDINATE:
        t, o = np.unravel_index(int(np.argmax(magnitude)), magnitude.shape)
        raise InputError(src.path, f"position at frame {frames[t]}, object {o} lies {magnitude[t, o]:.3g} from "
                         "the origin", f"positions within {config.MAX_COORDINATE:g} of the origin", dataset=dataset)


def _read_frames(src, ds, name, frames, expected):
    """float64 rows of ``ds`` (frames first) at the file frames ``frames`` (int64,
    increasing; read as one slice when evenly spaced), checked finite; errors name file
    frame numbers."""
    step = int(frames[1] - frames[0]) if frames.size > 1 else 1
    even = frames.size < 3 or bool((np.diff(frames) == step).all())
    try:
        rows = ds[int(frames[0]):int(frames[-1]) + 1:step] if even else ds[frames]
        data = np.asarray(rows, dtype=np.float64)
    except (OSError, ValueError, TypeError, RuntimeError) as exc:
        raise InputError(src.path, f"cannot read ({str(exc)[:80]})", expected, dataset=name) from None
    if not np.isfinite(data).all():
        idx = np.argwhere(~np.isfinite(data))[0]
        idx = (int(frames[idx[0]]),) + tuple(int(i) for i in idx[1:])
        raise InputError(src.path, f"non-finite value at index {idx}", "finite numbers", dataset=name)
    return data


def _quaternion_order(src, datasets):
    orientation_ds = datasets["poses/orientation"]
    order = _string_attr(src, orientation_ds, "quaternion_order", "poses/orientation")
    if order is None:
        raise InputError(src.path, "missing attribute quaternion_order", 'quaternion_order = "wxyz" or "xyzw"',
                         dataset="poses/orientation")
    if order not in QUATERNION_ORDERS:
        raise InputError(src.path, f"unknown quaternion_order {order!r}", '"wxyz" or "xyzw"',
                         dataset="poses/orientation")
    return order


def _poses_from_quaternions(src, datasets, frames, order, out):
    """Fill ``out`` (S, N, 3, 4) with the poses at file frames ``frames`` (S,) from
    poses/position and poses/orientation; returns the largest quaternion norm error."""
    position = _read_frames(src, datasets["poses/position"], "poses/position", frames, "finite positions")
    _check_positions(src, position, frames, "poses/position")
    orientation = _read_frames(src, datasets["poses/orientation"], "poses/orientation", frames,
                               "finite unit quaternions")
    norm = np.linalg.norm(orientation, axis=-1)
    off = np.abs(norm - 1.0)
    if (off > config.QUATERNION_NORM_TOL).any():
        t, o = np.unravel_index(int(np.argmax(off)), off.shape)
        raise InputError(src.path, f"quaternion of norm {norm[t, o]:.6g} at frame {frames[t]}, object {o}",
                         f"unit quaternions (norm within {config.QUATERNION_NORM_TOL} of 1)",
                         dataset="poses/orientation")
    out[..., :3] = quaternions_to_matrices(orientation / norm[..., None], order)
    out[..., 3] = position
    return float(off.max(initial=0.0))


def rotation_errors(matrix):
    """(max |R^T R - I| over the entries, det R), float64 (...,) each, of the 3 x 3
    blocks R = matrix[..., :3, :3] (matrix (..., >=3, >=3)): element-wise products of
    the columns, a few times faster than einsum and linalg.det on many small matrices."""
    r = [[matrix[..., k, i] for i in range(3)] for k in range(3)]  # r[row][column]
    error = np.zeros(matrix.shape[:-2])
    for i in range(3):
        for j in range(i, 3):  # R^T R is symmetric: its upper triangle holds every entry
            entry = r[0][i] * r[0][j] + r[1][i] * r[1][j] + r[2][i] * r[2][j]
            np.maximum(error, np.abs(entry - 1.0 if i == j else entry), out=error)
    det = (r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
           + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]))
    return error, det


def _poses_from_matrices(src, datasets, frames, order, out):
    """Fill ``out`` (S, N, 3, 4) with the rigid transforms of poses/matrix at file frames
    ``frames`` (S,), checked; returns 0.0 (no normalisation)."""
    matrix = _read_frames(src, datasets["poses/matrix"], "poses/matrix", frames, "finite rigid 4x4 transforms")
    _check_positions(src, matrix[..., :3, 3], frames, "poses/matrix")
    last_row = np.abs(matrix[..., 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=-1)
    if (last_row > config.MATRIX_LAST_ROW_TOL).any():
        t, o = np.unravel_index(int(np.argmax(last_row)), last_row.shape)
        raise InputError(src.path, f"last row is {matrix[t, o, 3].tolist()} at frame {frames[t]}, object {o}",
                         "last row 0 0 0 1", dataset="poses/matrix")
    error, det = rotation_errors(matrix)
    bad = ~(error <= config.ROTATION_ORTHONORMAL_TOL) | ~(det > 0)
    if bad.any():
        t, o = np.argwhere(bad)[0]
        raise InputError(src.path, f"not a rigid transform at frame {frames[t]}, object {o} "
                         f"(|R^T R - I| = {error[t, o]:.3g}, det = {det[t, o]:.3g})",
                         f"a rotation (orthonormal within {config.ROTATION_ORTHONORMAL_TOL}, det > 0) "
                         "and a translation", dataset="poses/matrix")
    out[...] = matrix[..., :3, :]
    return 0.0


def _read_poses(src, encoding, datasets, frames, n_objects, n_static=0):
    """Poses float64 (S, N + n_static, 3, 4) at the file frames ``frames`` (S,) of the N
    objects the file lists, followed by n_static static meshes' objects at identity
    (filled here: no second array of the poses' size). Read and converted
    config.POSE_CHUNK object-frames at a time, so that the conversion's temporaries stay
    small whatever the number of frames (memory: the result, plus one chunk). Returns
    (poses, largest quaternion norm error: 0.0 for matrices)."""
    poses = np.empty((frames.size, n_objects + n_static, 3, 4))
    _set_static(poses, n_objects)
    order = _quaternion_order(src, datasets) if encoding == "quaternion" else None
    convert = _poses_from_quaternions if encoding == "quaternion" else _poses_from_matrices
    chunk = max(1, config.POSE_CHUNK // max(n_objects, 1))
    norm_error = 0.0
    for start in range(0, frames.size, chunk):
        stop = min(start + chunk, frames.size)
        norm_error = max(norm_error, convert(src, datasets, frames[start:stop], order,
                                             poses[start:stop, :n_objects]))
    return poses, norm_error


def _set_static(poses, n_listed):
    """poses (S, N, 3, 4): objects n_listed.. at identity [I | 0]."""
    if poses.shape[1] > n_listed:
        poses[:, n_listed:] = 0.0
        poses[:, n_listed:, :, :3] = np.eye(3)


def _warn_normalising(path, norm_error):
    if norm_error > 1e-12:
        log.warning("%s:poses/orientation: normalising quaternions (largest norm error %.2g)",
                    escape_text(path), norm_error)


def _trajectory_bytes(n_frames, n_selected, n_objects, n_string_columns):
    """Estimated peak memory (bytes) of reading and scanning a trajectory of these
    declared sizes, ``n_selected`` of its frames scanned (see config.POSE_BYTES and friends)."""
    return (n_frames * config.NUMBER_BYTES + n_objects * n_string_columns * config.STRING_BYTES
            + n_selected * n_objects * config.POSE_BYTES)


def load_trajectory(path, allow_external=False, max_memory=None, frames=None, read_poses=True):
    """Read and validate a trajectory file (see README, "Trajectory").

    ``frames`` (None, a slice or "START:STOP[:STEP]") selects the frames whose poses
    are read and checked (all by default); the others are never read.

    Declared shapes are checked, and the memory they need estimated against
    ``max_memory`` (bytes or "4G"; default: files.memory_limit()), before any
    data is read. Unless ``allow_external``, data stored outside the file
    (external links, external storage, virtual datasets) is refused. Without
    ``read_poses`` the poses are left unread (None; read them with PoseFile). Returns
    a Trajectory; raises InputError for anything else that is not as described.
    """
    path = Path(path)
    with open_hdf5(path, TRAJECTORY) as h5:
        return _read_trajectory(h5, path, allow_external, max_memory, frames, read_poses)


def _read_trajectory(h5, path, allow_external, max_memory, frames=None, read_poses=True):
    """A Trajectory from an open h5py.File (a file's or an in-memory one); ``path`` names
    it in messages. Without ``read_poses`` its poses are left unread (None; see
    PoseFile)."""
    with np.errstate(all="ignore"):
        src = _Source(h5, path, allow_external)
        try:
            time_ds = _numeric(src, "time", (None,), TIME)
            names_ds = _strings(src, "objects/name", NAMES)
            mesh_ds = _strings(src, "objects/mesh", MESH_NAMES) if _exists(src, "objects/mesh") else None
            n_frames, n_objects = time_ds.shape[0], names_ds.shape[0]
            if n_frames < 1:
                raise InputError(path, "is empty", "at least one frame time", dataset="time")
            if mesh_ds is not None and mesh_ds.shape[0] != n_objects:
                raise InputError(path, f"has {mesh_ds.shape[0]} entries but objects/name has {n_objects}",
                                 "one mesh file name per object", dataset="objects/mesh")
            encoding, pose_ds = _pose_datasets(src, n_frames, n_objects)
            selected = select_frames(frames, n_frames)
            check_memory(path, _trajectory_bytes(n_frames, len(selected) if read_poses else 0, n_objects,
                                                 1 + (mesh_ds is not None)),
                         memory_limit(max_memory), f"a trajectory of {len(selected)} frames and {n_objects} objects")
            index = np.arange(selected.start, selected.stop, selected.step, dtype=np.int64)
            time = _read_time(src, time_ds)
            names, mesh_entries = _read_names(src, names_ds, mesh_ds)
            ignore = _read_ignore(src) if _exists(src, "filters/ignore") else ()
            poses = None
            if read_poses:
                poses, norm_error = _read_poses(src, encoding, pose_ds, index, n_objects)
                _warn_normalising(path, norm_error)
        except InputError:
            raise
        except (OSError, KeyError, RuntimeError, ValueError, TypeError) as exc:
            raise InputError(path, f"cannot read ({str(exc)[:100]})", "a readable HDF5 trajectory") from None
    return Trajectory(path, time, names, mesh_entries, poses, next(iter(pose_ds)), ignore, index)


# --- poses, block by block ----------------------------------------------------------------------

#: float64 values per pose: the rows [R | p] of a 3 x 4 transform
POSE_VALUES = 12


def block_frames(n_objects):
    """Frames per block of poses (at least 2: a block holds a motion step), so that a block
    of n_objects' poses takes about config.POSE_BLOCK_BYTES."""
    return max(2, config.POSE_BLOCK_BYTES // (max(n_objects, 1) * POSE_VALUES * 8))


def _with_static(listed, n_objects):
    """Poses of the trajectory's objects (S, L, 3, 4) followed by those of the static
    meshes' objects, at identity: float64 (S, n_objects, 3, 4)."""
    if listed.shape[1] == n_objects:
        return listed
    poses = np.empty((listed.shape[0], n_objects, 3, 4))
    poses[:, :listed.shape[1]] = listed
    _set_static(poses, listed.shape[1])
    return poses


class PoseSource:
    """The poses of a scene's S selected frames, float64 (S, N, 3, 4) (rows [R | p],
    world = R @ body + p), handed out a block of frames at a time: ``block`` frames of
    N objects take about config.POSE_BLOCK_BYTES, whatever the trajectory's length."""
    n_frames: int
    n_objects: int
    block: int

    def read(self, start, stop):
        """float64 (stop - start, N, 3, 4), C-contiguous: the poses of selected frames
        [start, stop)."""
        raise NotImplementedError

    def read_checked(self, start, stop):
        """(read(start, stop), largest quaternion norm error met reading them: 0.0 unless
        they are read from a file)."""
        return self.read(start, stop), 0.0

    def at(self, frames):
        """(poses, rows): the poses of the selected frames ``frames`` (int64, sorted, unique,
        at most ``block`` of them) are poses[rows]."""
        raise NotImplementedError

    def blocks(self, overlap=0):
        """Yield (start, poses) block by block, in order: the poses of selected frames
        [start, start + block + overlap), cut at the last frame (overlap 1: each block also
        holds the next block's first frame, so that it holds the motion steps in between)."""
        for start in range(0, self.n_frames, self.block):
            yield start, self.read(start, min(start + self.block + overlap, self.n_frames))


class PoseArray(PoseSource):
    """Poses held in memory: float64 (S, N, 3, 4), C-contiguous (one block)."""

    def __init__(self, poses):
        self.array = np.ascontiguousarray(poses, dtype=np.float64)
        self.n_frames, self.n_objects = self.array.shape[:2]
        self.block = max(self.n_frames, 1)

    def read(self, start, stop):
        return self.array[start:stop]

    def at(self, frames):
        return self.array, frames


class PoseFile(PoseSource):
    """Poses of a trajectory file's selected frames, read, checked and converted from the
    file when asked for (the file is opened for each read), block by block.

    frame_index int64 (S,): the selected frames (indices into the file's T frames);
    n_listed: objects in the file; n_objects: with the static meshes' objects after
    them, at identity.
    """

    def __init__(self, path, allow_external, n_file_frames, frame_index, n_listed, n_objects):
        self.path, self.allow_external = Path(path), allow_external
        self.n_file_frames, self.frame_index, self.n_listed = n_file_frames, frame_index, n_listed
        self.n_frames, self.n_objects = frame_index.size, n_objects
        self.block = block_frames(n_objects)

    def read(self, start, stop):
        return self.read_checked(start, stop)[0]

    def at(self, frames):
        return self._read(self.frame_index[frames])[0], np.arange(frames.size)

    def read_checked(self, start, stop):
        return self._read(self.frame_index[start:stop])

    def _read(self, file_frames):
        with np.errstate(all="ignore"), open_hdf5(self.path, TRAJECTORY) as h5:
            src = _Source(h5, self.path, self.allow_external)
            try:
                encoding, datasets = _pose_datasets(src, self.n_file_frames, self.n_listed)
                poses, norm_error = _read_poses(src, encoding, datasets, file_frames, self.n_listed,
                                                self.n_objects - self.n_listed)
            except InputError:
                raise
            except (OSError, KeyError, RuntimeError, ValueError, TypeError) as exc:
                raise InputError(self.path, f"cannot read ({str(exc)[:100]})", "a readable HDF5 trajectory") \
                    from None
        return poses, norm_error


def check_trajectory(path, allow_external=False, max_memory=None):
    """Validate a trajectory file as load_trajectory does, reading its poses a block at a
    time (memory does not grow with its length beyond the frame times). Returns its
    Trajectory, poses unread (None)."""
    traj = load_trajectory(path, allow_external=allow_external, max_memory=max_memory, read_poses=False)
    poses = PoseFile(traj.path, allow_external, traj.time.shape[0], traj.frame_index, len(traj.names),
                     len(traj.names))
    _warn_normalising(traj.path, _read_every_block(poses, lambda start, stop, block: None))
    return traj


def _read_every_block(poses, each):
    """Read every pose of PoseSource ``poses`` once, block by block (a PoseFile checks what
    it reads), calling each(start, stop, block) on the poses of selected frames [start,
    stop). Returns the largest quaternion norm error met."""
    norm_error = 0.0
    for start in range(0, poses.n_frames, poses.block):
        stop = min(start + poses.block, poses.n_frames)
        block, error = poses.read_checked(start, stop)
        norm_error = max(norm_error, error)
        each(start, stop, block)
    return norm_error


# --- inputs in memory (Python API) ------------------------------------------------------------

#: how in-memory trajectories name what files store as datasets
MEMORY_TRAJECTORY_KEYS = {"time": "time", "names": "objects/name", "mesh": "objects/mesh",
                          "matrix": "poses/matrix", "position": "poses/position",
                          "orientation": "poses/orientation", "ignore": "filters/ignore"}
MEMORY_TRAJECTORY = Path("<trajectory in memory>")


def trajectory_from_arrays(data, max_memory=None, frames=None):
    """Validate an in-memory trajectory exactly as a file is validated.

    data: a mapping with ``time`` (T,), ``names`` (N,) and either ``matrix`` (T, N, 4,
    4) or ``position`` (T, N, 3) + ``orientation`` (T, N, 4) + ``quaternion_order``
    ("wxyz" or "xyzw"); optionally ``mesh`` (N,) and ``ignore`` (K, 2) (the file's
    objects/mesh and filters/ignore). The file's own dataset names ("poses/matrix",
    ...) are accepted too. Returns a Trajectory named "<trajectory in memory>".
    """
    import h5py
    known = set(MEMORY_TRAJECTORY_KEYS) | set(MEMORY_TRAJECTORY_KEYS.values()) | {"quaternion_order"}
    unknown = sorted(str(k) for k in data if k not in known)
    if unknown:
        raise UsageError(f"trajectory: unknown key(s) {', '.join(unknown)}; expected {', '.join(sorted(known))}")
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as h5:
        for key, value in data.items():
            if key == "quaternion_order" or value is None:
                continue
            name = MEMORY_TRAJECTORY_KEYS.get(key, key)
            array = np.asarray(value)
            if array.dtype.kind in "OUS":
                h5.create_dataset(name, data=array.astype(str).astype(object), dtype=h5py.string_dtype())
            else:
                h5.create_dataset(name, data=array)
        if "quaternion_order" in data and "poses/orientation" in h5:
            h5["poses/orientation"].attrs["quaternion_order"] = str(data["quaternion_order"])
        return _read_trajectory(h5, MEMORY_TRAJECTORY, False, max_memory, frames)


def mesh_from_arrays(name, mesh):
    """A Mesh from an in-memory mesh: a trimesh.Trimesh or a (vertices, faces) pair (V, 3)
    and (F, 3), validated as mesh files are. Its path is None."""
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        vertices, faces = mesh.vertices, mesh.faces
    else:
        try:
            vertices, faces = mesh
        except (TypeError, ValueError):
            raise UsageError(f"mesh {name!r}: expected a trimesh.Trimesh or a (vertices, faces) pair, "
                             f"not {type(mesh).__name__}") from None
    return _checked_mesh(str(name), None, np.asarray(vertices), np.asarray(faces), f"<mesh {name} in memory>")


# --- scene: meshes + trajectory ------------------------------------------------------------

class Scene(NamedTuple):
    names: list            #: N object names: trajectory objects, then static meshes
    meshes: list           #: M distinct Mesh objects
    object_mesh: np.ndarray  #: int64 (N,), index into meshes
    time: np.ndarray       #: float64 (T,): every frame's time
    poses: PoseSource      #: float64 (S, N, 3, 4) at the S selected frames, block by block
    static: np.ndarray     #: bool (N,): identity pose at every selected frame
    trajectory_path: Path
    ignore: tuple = ()     #: the trajectory's filters/ignore pattern pairs
    unlisted: tuple = ()   #: names of the meshes the trajectory does not list (static at identity)
    frame_index: np.ndarray = None  #: int64 (S,): the selected frames (indices into time)


class MemoryMeshKey(NamedTuple):
    """Stands for a mesh given in memory where a scene expects a file's Path (name, stem)."""
    name: str
    stem: str


def _resolve_mesh(files, entry, traj_path, dataset):
    """Mesh path (or MemoryMeshKey) for an objects/name or objects/mesh entry (stem or file
    name)."""
    if entry in files:
        return files[entry]
    for path in files.values():
        if path.name == entry:
            return path
    known = ", ".join(sorted(files)[:10]) + (", ..." if len(files) > 10 else "")
    raise InputError(traj_path, f"unknown mesh {entry!r}", f"a mesh file in the meshes folder ({known})",
                     dataset=dataset)


def input_files(meshes_folder, trajectory_path, glob=None):
    """The files a scan reads: the trajectory and every mesh file of the folder (for
    refusing an output path that is one of them). A folder that cannot be listed
    contributes nothing here; loading reports it. Inputs in memory have no files."""
    meshes = []
    if not isinstance(meshes_folder, Mapping):
        try:
            meshes = list(mesh_files(meshes_folder, glob).values())
        except InputError:
            pass
    return ([] if isinstance(trajectory_path, Mapping) else [Path(trajectory_path)]) + meshes


def _check_reach(scene_names, meshes, object_mesh, poses, frames, path, dataset):
    """Refuse a scene where |position| + |vertex| of some object at some frame exceeds
    config.MAX_COORDINATE (world coordinates up to that size cannot overflow). poses
    (S, N, 3, 4) are those of the file frames ``frames`` (S,)."""
    radius = np.array([float(lengths(m.vertices).max(initial=0.0)) for m in meshes])[object_mesh]
    chunk = max(1, config.POSE_CHUNK // max(poses.shape[1], 1))
    for start in range(0, poses.shape[0], chunk):  # chunks of frames: small temporaries
        distance = lengths(poses[start:start + chunk, :, :, 3])                   # (chunk, N)
        reach = distance + radius[None, :]
        if reach.size and not reach.max() <= config.MAX_COORDINATE:
            t, o = np.unravel_index(int(np.argmax(reach)), reach.shape)
            _refuse_reach(scene_names[o], frames[start + t], reach[t, o], distance[t, o], radius[o], path, dataset)


def _refuse_reach(name, frame, reach, distance, radius, path, dataset):
    raise InputError(path, f"object {name!r} at frame {frame} reaches {reach:.3g} from the "
                     f"origin (|position| {distance:.3g} + mesh radius "
                     f"{radius:.3g})", f"world coordinates of magnitude at most {config.MAX_COORDINATE:g}",
                     dataset=dataset)


def load_scene(meshes_folder, trajectory_path, allow_external=False, max_memory=None, glob=None,
               mesh_loader=None, frames=None):
    """Validate and load everything a scan needs.

    meshes_folder: a folder of mesh files, or a mapping {name: trimesh.Trimesh or
    (vertices, faces)} (mesh_from_arrays); trajectory_path: an HDF5 file, or a mapping
    of arrays (trajectory_from_arrays). ``allow_external`` and ``max_memory`` are those
    of load_trajectory; the memory estimate is checked again with the static meshes'
    objects added. ``glob``: see mesh_files. mesh_loader(path) -> Mesh loads a mesh
    file (default load_mesh; e.g. a cached loader). ``frames``: the frames to read (see
    load_trajectory).
    """
    if isinstance(meshes_folder, Mapping):
        in_memory = {str(k): mesh_from_arrays(k, m) for k, m in meshes_folder.items()}
        if not in_memory:
            raise UsageError("meshes: no meshes given")
        files = {k: MemoryMeshKey(k, k) for k in in_memory}
    else:
        in_memory = {}
        files = mesh_files(meshes_folder, glob)
    if isinstance(trajectory_path, Mapping):
        traj = trajectory_from_arrays(trajectory_path, max_memory, frames)
    else:
        traj = load_trajectory(trajectory_path, allow_external=allow_external, max_memory=max_memory, frames=frames,
                               read_poses=False)
    dataset = "objects/name" if traj.mesh_files is None else "objects/mesh"
    entries = traj.names if traj.mesh_files is None else traj.mesh_files
    used = [_resolve_mesh(files, entry, traj.path, dataset) for entry in entries]
    used_set = set(used)
    static_paths = [p for stem, p in sorted(files.items()) if p not in used_set]
    taken = set(traj.names)
    for p in static_paths:
        if p.stem in taken:
            raise InputError(traj.path, f"object name {p.stem!r} is also an unused mesh",
                             "names that do not clash with static meshes", dataset="objects/name")
    n_frames, n_selected = traj.time.shape[0], traj.frame_index.size
    n_objects = len(traj.names) + len(static_paths)
    check_memory(traj.path, _trajectory_bytes(n_frames, min(n_selected, block_frames(n_objects)), n_objects, 2),
                 memory_limit(max_memory), f"a scene of {n_selected} frames and {n_objects} objects")
    poses, norm_error = _pose_source(traj, allow_external, n_objects)
    mesh_paths = sorted(used_set) + static_paths
    mesh_loader = mesh_loader or load_mesh
    meshes = [in_memory[p.stem] if isinstance(p, MemoryMeshKey) else mesh_loader(p) for p in mesh_paths]
    index = {p: i for i, p in enumerate(mesh_paths)}
    object_mesh = np.array([index[p] for p in used + static_paths], dtype=np.int64)
    names = list(traj.names) + [p.stem for p in static_paths]
    static, block_error = _check_poses(poses, names, meshes, object_mesh, traj)
    _warn_normalising(traj.path, max(norm_error, block_error))
    return Scene(names, meshes, object_mesh, traj.time, poses, static, traj.path, traj.ignore,
                 tuple(p.stem for p in static_paths), traj.frame_index)


def _pose_source(traj, allow_external, n_objects):
    """(PoseSource of the scene's n_objects, largest quaternion norm error of what was
    read): poses held in memory when they were given in memory or fill one block (read
    now), else a PoseFile that reads them block by block."""
    if traj.poses is not None:  # given in memory, read and checked
        return PoseArray(_with_static(traj.poses, n_objects)), 0.0
    source = PoseFile(traj.path, allow_external, traj.time.shape[0], traj.frame_index, len(traj.names), n_objects)
    if source.n_frames > source.block:
        return source, 0.0
    poses, norm_error = source.read_checked(0, source.n_frames)
    return PoseArray(poses), norm_error


def _check_poses(poses, names, meshes, object_mesh, traj):
    """Read every pose once, block by block (PoseSource ``poses``), and check them
    (_check_reach; a PoseFile checks what it reads). Returns (static: bool (N,), which
    objects stay at identity at every selected frame, largest quaternion norm error)."""
    identity = np.zeros((3, 4))
    identity[:, :3] = np.eye(3)
    static = np.ones(poses.n_objects, dtype=bool)

    def check(start, stop, block):
        _check_reach(names, meshes, object_mesh, block, traj.frame_index[start:stop], traj.path, traj.pose_dataset)
        static[:] &= (block == identity).all(axis=(0, 2, 3))
    norm_error = _read_every_block(poses, check)
    return static, norm_error
