"""A disk cache of parsed meshes and their BVHs, so that warm runs skip re-parsing.

Parsing a mesh file (trimesh) and building its BVH take seconds for meshes of tens
of thousands of triangles; reading them back from an uncompressed ``.npz`` file
takes milliseconds. Results are exactly those of ``collide.load.load_mesh`` and
``collide.bvh.build_mesh_bvh`` (bit for bit): an entry is only used when its full
key matches and its arrays pass structural checks; anything else is a miss.

**Location**: ``$COLLIDE_CACHE_DIR`` if set (and not empty), else the platform's
user cache folder: ``$XDG_CACHE_HOME/collide`` or ``~/.cache/collide`` (Linux and
other Unix), ``~/Library/Caches/collide`` (macOS), ``%LOCALAPPDATA%\\collide\\Cache``
(Windows). A location that cannot be created or used turns caching off (one
``info`` line on the "collide" logger); one that cannot be written is still read.

**Keys** (a JSON object; its SHA-256 names the entry file):

- mesh entry ``mesh-<digest>.npz``: cache format, collide version, loader version
  (``LOADER_VERSION``), trimesh and numpy versions, the lower-case file suffix (the
  same bytes parse differently as .obj and .stl), the file's SHA-256 and the
  coordinate limit that ``load_mesh`` checks. Only suffixes whose triangles depend
  on the file's bytes alone are cached (``CACHEABLE_SUFFIXES``; a .gltf file's
  geometry lives in other files).
- BVH entry ``bvh-<digest>.npz``: cache format, collide version, builder version
  (``BVH_VERSION``), numba version, the SHA-256 of the mesh arrays themselves
  (dtype, shape and bytes of vertices and faces), split rule, leaf size and the SAH
  constants of ``collide.config``. Keyed by the arrays, not the file, so a BVH is
  reused whatever file (or suffix) the mesh came from, and never for other arrays.

**Entry files**: ``np.savez`` archives (stored, not compressed) of a ``header``
(uint8 array: UTF-8 JSON ``{"format": CACHE_FORMAT, "key": {...}}``) and the arrays:
``vertices`` float64 (V, 3), ``faces`` int64 (F, 3); or ``lo``, ``hi`` float64
(m, 3), ``first``, ``count`` int64 (m,), ``prim_ids`` int64 (F,). They are written
to a temporary file in the cache folder and renamed into place (``os.replace``),
so readers never see a partial file and concurrent writers of one key leave one
complete entry. Entries are read without pickles; dtypes and shapes are checked
before anything is allocated, and each member's zip CRC-32 is verified.

**Size**: an entry larger than ``config.CACHE_MAX_ENTRY_BYTES`` is not written;
after each write, the least recently used entries (file modification time, touched
on every hit) are deleted until the total is at most ``config.CACHE_MAX_BYTES``.
"""
import hashlib
import json
import logging
import os
import re
import tempfile
import threading
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import config
from ._version import __version__
from .bvh import BVH, build_mesh_bvh, in_smallest_id_order, triangle_boxes
from .errors import escape_text
from .files import open_regular
from .load import Mesh, lengths, load_mesh

log = logging.getLogger("collide")

#: Layout of entry files (members, header). Bump when it changes.
CACHE_FORMAT = 1

#: Behaviour of ``collide.load.load_mesh``. Bump whenever load_mesh (or what it
#: asks of trimesh) changes the arrays it returns for some file.
LOADER_VERSION = 3  # 2: faces in file order (OBJ with materials; PLY and OFF polygons); 3: files of quads only too

#: Behaviour of ``collide.bvh.build_mesh_bvh``. Bump whenever the builder can
#: return a different tree for the same arrays and options.
BVH_VERSION = 2

#: File suffixes whose vertices and faces depend on the file's bytes only (files
#: they reference, such as OBJ materials, change nothing but looks).
CACHEABLE_SUFFIXES = frozenset({".obj", ".stl", ".ply", ".off"})

#: Environment variable naming the cache folder.
from .files import CACHE_ENV, cache_dir, default_cache_dir  # noqa: E402,F401  (location lives in files.py)

#: The only file names this module writes, and so the only ones it ever deletes (the
#: cache folder may be shared with other files): entries and their temporary files.
_ENTRY_SUFFIX = ".npz"
_TEMP_SUFFIX = ".tmp"
_ENTRY_NAME = re.compile(r"(mesh|bvh)-[0-9a-f]{64}\.npz")
_TEMP_NAME = re.compile(r"\.(mesh|bvh)-[0-9a-f]{64}\.[A-Za-z0-9_]+\.tmp")

#: Temporary files older than this are left over from a killed writer. Seconds.
_STALE_TEMP_SECONDS = 3600.0

#: Largest header member read back. Bytes.
_MAX_HEADER_BYTES = 1 << 16

_MESH_MEMBERS = {"vertices": (np.float64, 2), "faces": (np.int64, 2)}
_BVH_MEMBERS = {"lo": (np.float64, 2), "hi": (np.float64, 2), "first": (np.int64, 1),
                "count": (np.int64, 1), "prim_ids": (np.int64, 1)}


# --- statistics -----------------------------------------------------------------------------

@dataclass
class CacheStats:
    """Counts of cache lookups, for a scan's summary (thread-safe counters)."""
    mesh_hits: int = 0      #: meshes read from the cache
    mesh_misses: int = 0    #: meshes parsed (absent, unusable entry, or caching off for them)
    bvh_hits: int = 0       #: BVHs read from the cache
    bvh_misses: int = 0     #: BVHs built
    rejected: int = 0       #: entries found but not used (corrupt, foreign, inconsistent)
    stored: int = 0         #: entries written
    evicted: int = 0        #: entries deleted to keep the cache within its size
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    def add(self, **counts):
        with self._lock:
            for name, n in counts.items():
                setattr(self, name, getattr(self, name) + n)

    def as_dict(self):
        """{"mesh_hits": int, ...}: every counter."""
        return {k: getattr(self, k) for k in ("mesh_hits", "mesh_misses", "bvh_hits", "bvh_misses",
                                              "rejected", "stored", "evicted")}


def _count(stats, **counts):
    if stats is not None:
        stats.add(**counts)


# --- location ----------------------------------------------------------------------------------

#: folder -> "unusable" | "read-only": what was found (and told, once) per process
_folder_state = {}
_state_lock = threading.Lock()


def _note_folder(folder, state, reason):
    """Remember ``state`` for ``folder``; say so (info) the first time."""
    with _state_lock:
        if _folder_state.get(str(folder)) is not None:
            return
        _folder_state[str(folder)] = state
    what = "caching is off" if state == "unusable" else "new meshes and BVHs are not cached"
    log.info("mesh cache %s: %s; %s (set %s to a writable folder)", escape_text(folder), reason, what,
             CACHE_ENV)


def _usable_folder():
    """The cache folder, created if needed, or None (caching off) when there is none
    or it cannot be used (said once per folder)."""
    folder = cache_dir()
    if folder is None:
        return None
    with _state_lock:
        state = _folder_state.get(str(folder))
    if state == "unusable":
        return None
    if state is None:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            _note_folder(folder, "unusable", _os_reason(exc))
            return None
        if not folder.is_dir():
            _note_folder(folder, "unusable", "not a folder")
            return None
    return folder


def _writable(folder):
    with _state_lock:
        return _folder_state.get(str(folder)) is None


def _os_reason(exc):
    text = exc.strerror or os.strerror(exc.errno or 0) or type(exc).__name__
    return text[0].lower() + text[1:]


# --- keys ------------------------------------------------------------------------------------

def file_sha256(path):
    """SHA-256 (lower-case hex str) of a regular file's bytes; InputError for anything
    that is not a readable regular file (never blocks on a FIFO)."""
    digest = hashlib.sha256()
    with open_regular(path, "a readable mesh file") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _check_hex(sha256_hex):
    text = str(sha256_hex).lower()
    if len(text) != 64 or any(c not in "0123456789abcdef" for c in text):
        raise ValueError(f"expected a SHA-256 hex digest (64 hex digits), got {sha256_hex!r}")
    return text


def mesh_key(suffix, sha256_hex):
    """Everything a parsed mesh depends on: dict of JSON values."""
    from .load import trimesh_version
    return {"kind": "mesh", "format": CACHE_FORMAT, "collide": __version__, "loader": LOADER_VERSION,
            "trimesh": trimesh_version(), "numpy": np.__version__, "suffix": suffix.lower(),
            "sha256": _check_hex(sha256_hex), "max_coordinate": config.MAX_COORDINATE}


def arrays_sha256(*arrays):
    """SHA-256 (hex str) of arrays' dtypes, shapes and bytes (C order)."""
    digest = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        digest.update(f"{a.dtype.str}{a.shape};".encode())
        digest.update(a.data)
    return digest.hexdigest()


def _leaf_size(leaf_size):
    return config.DEFAULT_LEAF_SIZE if leaf_size is None else int(leaf_size)


def bvh_key(vertices, faces, split, leaf_size):
    """Everything a mesh BVH depends on: dict of JSON values. ``vertices`` float64
    (V, 3) and ``faces`` int64 (F, 3) enter through their SHA-256."""
    import numba
    return {"kind": "bvh", "format": CACHE_FORMAT, "collide": __version__, "builder": BVH_VERSION,
            "numba": numba.__version__, "mesh": arrays_sha256(vertices, faces), "split": str(split),
            "leaf_size": _leaf_size(leaf_size), "sah_bins": config.SAH_BINS,
            "sah_traversal_cost": config.SAH_TRAVERSAL_COST}


def _key_text(key):
    return json.dumps(key, sort_keys=True, separators=(",", ":"))


def _entry_path(folder, key):
    name = hashlib.sha256(_key_text(key).encode()).hexdigest()
    return folder / f"{key['kind']}-{name}{_ENTRY_SUFFIX}"


# --- reading entries ----------------------------------------------------------------------------

class _Unusable(Exception):
    """An entry that exists but must not be used (the message says why)."""


def _read_member(archive, name, dtype, ndim, limit):
    """Array ``name`` of an open npz ZipFile, refused unless stored uncompressed with
    exactly ``dtype`` (native), ``ndim`` dimensions, C order and a size that matches
    the member (checked before allocating). The zip CRC-32 is verified on reading."""
    try:
        info = archive.getinfo(name + ".npy")
    except KeyError:
        raise _Unusable(f"no member {name}") from None
    if info.compress_type != zipfile.ZIP_STORED or info.file_size > limit:
        raise _Unusable(f"member {name} is compressed or too large")
    with archive.open(info) as f:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, fortran, found = np.lib.format.read_array_header_1_0(f)
        elif version == (2, 0):
            shape, fortran, found = np.lib.format.read_array_header_2_0(f)
        else:
            raise _Unusable(f"member {name} has .npy version {version}")
        if found != np.dtype(dtype) or fortran or len(shape) != ndim:
            order = " in Fortran order" if fortran else ""
            raise _Unusable(f"member {name} is {found} {shape}{order}, expected C-ordered {np.dtype(dtype)} "
                            f"with {ndim} dimensions")
        n_bytes = int(np.prod(shape, dtype=np.int64)) * found.itemsize
        if n_bytes != info.file_size - f.tell():
            raise _Unusable(f"member {name} holds {info.file_size - f.tell()} bytes for shape {shape}")
        array = np.empty(shape, dtype=found)
        if (n_bytes and f.readinto(memoryview(array).cast("B")) != n_bytes) or f.read(1):
            raise _Unusable(f"member {name} is truncated")
    return array


def _read_entry(path, key, members):
    """{name: array} of the entry at ``path`` if its header holds exactly ``key``;
    None when there is no entry; _Unusable when there is one that cannot be used."""
    try:
        size = os.stat(path).st_size
    except FileNotFoundError:
        return None
    with zipfile.ZipFile(path) as archive:
        header = _read_member(archive, "header", np.uint8, 1, _MAX_HEADER_BYTES)
        try:
            found = json.loads(header.tobytes().decode("utf-8"))
        except ValueError:
            raise _Unusable("header is not JSON") from None
        if found != {"format": CACHE_FORMAT, "key": key}:
            raise _Unusable("header names another key or format")
        return {name: _read_member(archive, name, dtype, ndim, size)
                for name, (dtype, ndim) in members.items()}


def _lookup(path, key, members, check, stats):
    """Checked arrays of the entry at ``path``, or None (absent, or unusable: counted
    and logged at debug level). ``check(arrays)`` raises _Unusable."""
    try:
        arrays = _read_entry(path, key, members)
        if arrays is None:
            return None
        check(arrays)
    except FileNotFoundError:  # deleted (evicted, cleared) after the stat
        return None
    except Exception as exc:  # noqa: BLE001 -- a cache entry is never trusted, never an error
        reason = str(exc) if isinstance(exc, _Unusable) else f"{type(exc).__name__}: {str(exc)[:80]}"
        log.debug("mesh cache: %s: not used (%s)", path.name, reason)
        _count(stats, rejected=1)
        return None
    try:
        os.utime(path)  # recently used: evicted last
    except OSError:
        pass
    return arrays


def _require(condition, problem):
    if not condition:
        raise _Unusable(problem)


def check_mesh_arrays(arrays):
    """Raise _Unusable unless vertices float64 (V, 3) are finite and within
    config.MAX_COORDINATE of the origin and faces int64 (F, 3), F >= 1, index them."""
    vertices, faces = arrays["vertices"], arrays["faces"]
    _require(vertices.shape[1:] == (3,) and faces.shape[1:] == (3,) and faces.shape[0] >= 1,
             f"shapes {vertices.shape}, {faces.shape}")
    _require(np.isfinite(vertices).all(), "non-finite vertices")
    _require(float(lengths(vertices).max(initial=0.0)) <= config.MAX_COORDINATE, "vertices too far out")
    _require(faces.min() >= 0 and faces.max() < vertices.shape[0], "faces index missing vertices")


def check_bvh_arrays(arrays, vertices, faces, leaf_size):
    """Raise _Unusable unless the BVH arrays are a tree that build_mesh_bvh could have
    built over these triangles: shapes agree, every non-root node is the child of
    exactly one inner node that comes before it, leaves hold at most ``leaf_size``
    primitives and partition ``prim_ids`` (a permutation of range(F)), every box is
    exactly the box of its triangles (so also finite), and the tree is in smallest-id
    order (collide.bvh). Vectorised but for one O(nodes) kernel, O(F log F)."""
    lo, hi, first, count, prim = (arrays[k] for k in ("lo", "hi", "first", "count", "prim_ids"))
    n, m = faces.shape[0], count.shape[0]
    _require(lo.shape == hi.shape == (m, 3) and first.shape == (m,) and prim.shape == (n,)
             and 1 <= m <= max(2 * n - 1, 1), "array shapes do not match")
    leaf = count > 0
    _require(((count >= 0) & (count <= leaf_size)).all(), "leaf sizes out of range")
    _check_tree(first, leaf, m)
    leaf_nodes, starts = _check_leaves(first, count, leaf, prim, n)
    tri_lo, tri_hi, _ = triangle_boxes(vertices, faces[prim])  # in leaf order
    _require(np.array_equal(lo[leaf_nodes], np.minimum.reduceat(tri_lo, starts, axis=0))
             and np.array_equal(hi[leaf_nodes], np.maximum.reduceat(tri_hi, starts, axis=0)),
             "leaf boxes are not their triangles' boxes")
    inner = np.flatnonzero(~leaf)
    left = first[inner]
    _require(np.array_equal(lo[inner], np.minimum(lo[left], lo[left + 1]))
             and np.array_equal(hi[inner], np.maximum(hi[left], hi[left + 1])),
             "inner boxes are not their children's boxes")
    _require(in_smallest_id_order(first, count, prim), "the tree is not in smallest-id order")


def _check_tree(first, leaf, m):
    """Inner node k's children first[k], first[k] + 1 lie after k, inside the array, and
    every node but the root is exactly one node's child (so: one tree from node 0)."""
    inner = np.flatnonzero(~leaf)
    left = first[inner]
    _require(((left > inner) & (left <= m - 2)).all(), "children out of range")
    children = np.bincount(np.concatenate([left, left + 1]), minlength=m)
    _require(children[0] == 0 and (children[1:] == 1).all(), "nodes are not one tree")


def _check_leaves(first, count, leaf, prim, n):
    """(leaf nodes, their starts) in prim_ids order, after checking that the leaves'
    ranges tile prim_ids exactly and prim_ids is a permutation of range(n)."""
    leaf_nodes = np.flatnonzero(leaf)
    order = np.argsort(first[leaf_nodes], kind="stable")
    leaf_nodes = leaf_nodes[order]
    starts, sizes = first[leaf_nodes], count[leaf_nodes]
    _require(starts.size > 0 and starts[0] == 0 and (starts <= n - sizes).all()
             and np.array_equal(starts[1:], (starts + sizes)[:-1]) and starts[-1] + sizes[-1] == n,
             "leaves do not tile the primitives")
    _require(prim.min() >= 0 and prim.max() < n and (np.bincount(prim, minlength=n) == 1).all(),
             "prim_ids is not a permutation")
    return leaf_nodes, starts


# --- writing entries ---------------------------------------------------------------------------

def _store(folder, path, key, arrays, stats):
    """Write an entry atomically (temporary file + os.replace), then trim the cache.
    Too-large entries are skipped; a failure to write turns writing off (said once)."""
    if not _writable(folder):
        return
    size = sum(a.nbytes for a in arrays.values())
    if size > config.CACHE_MAX_ENTRY_BYTES:
        log.debug("mesh cache: %s not stored (%d bytes, limit %d)", path.name, size,
                  config.CACHE_MAX_ENTRY_BYTES)
        return
    header = np.frombuffer(json.dumps({"format": CACHE_FORMAT, "key": key}).encode(), np.uint8)
    temp = None
    try:
        fd, temp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=_TEMP_SUFFIX, dir=folder)
        with os.fdopen(fd, "wb") as f:
            np.savez(f, header=header, **{k: np.ascontiguousarray(a) for k, a in arrays.items()})
        try:
            os.replace(temp, path)
        except OSError as exc:  # this name only (a folder in the way; on Windows, a reader)
            log.debug("mesh cache: %s not stored (%s)", path.name, _os_reason(exc))
            return
        temp = None
    except OSError as exc:  # cannot create or fill files here (permissions, full disk, ...)
        _note_folder(folder, "read-only", f"cannot write ({_os_reason(exc)})")
        return
    finally:
        if temp is not None:  # also on Ctrl-C
            _remove(Path(temp))
    _count(stats, stored=1)
    _count(stats, evicted=trim_cache(folder, config.CACHE_MAX_BYTES))


def _remove(path):
    try:
        os.unlink(path)
        return True
    except OSError:
        return False


def _entries(folder):
    """[(mtime, size, path)] of the cache's entry files, and stale temporary files."""
    entries, stale = [], []
    now = time.time()
    try:
        with os.scandir(folder) as it:
            for item in it:
                name = item.name
                try:
                    info = item.stat(follow_symlinks=False)
                except OSError:
                    continue
                if not item.is_file(follow_symlinks=False):
                    continue
                if _ENTRY_NAME.fullmatch(name):
                    entries.append((info.st_mtime, info.st_size, Path(item.path)))
                elif _TEMP_NAME.fullmatch(name) and now - info.st_mtime > _STALE_TEMP_SECONDS:
                    stale.append(Path(item.path))
    except OSError:
        pass
    return entries, stale


def trim_cache(folder, max_bytes):
    """Delete least recently used entries of ``folder`` until they total at most
    ``max_bytes`` (and temporary files left by killed writers). Returns the number
    of entries deleted."""
    entries, stale = _entries(folder)
    for path in stale:
        _remove(path)
    total = sum(size for _, size, _ in entries)
    deleted = 0
    for _, size, path in sorted(entries, key=lambda e: e[0]):
        if total <= max_bytes:
            break
        if _remove(path):
            deleted += 1
        total -= size
    return deleted


# --- the API -------------------------------------------------------------------------------------

def load_mesh_cached(path, sha256_hex=None, use_cache=True, stats=None):
    """``collide.load.load_mesh(path)``, read from the cache when possible.

    ``sha256_hex``: SHA-256 (hex) of the file's bytes, when the caller has it
    (file_sha256(path) otherwise). Returns a Mesh with vertices float64 (V, 3) and
    faces int64 (F, 3) identical to load_mesh's; raises what load_mesh raises. A
    parsed mesh is stored only if the file still has that hash after parsing.
    ``stats``: a CacheStats to count hits and misses in.
    """
    path = Path(path)
    folder = _usable_folder() if use_cache and path.suffix.lower() in CACHEABLE_SUFFIXES else None
    if folder is None:
        _count(stats, mesh_misses=1)
        return load_mesh(path)
    if sha256_hex is None:
        try:
            sha256_hex = file_sha256(path)
        except Exception:  # let load_mesh describe the problem
            _count(stats, mesh_misses=1)
            return load_mesh(path)
    key = mesh_key(path.suffix, sha256_hex)
    entry = _entry_path(folder, key)
    arrays = _lookup(entry, key, _MESH_MEMBERS, check_mesh_arrays, stats)
    if arrays is not None:
        _count(stats, mesh_hits=1)
        return Mesh(path.stem, path, arrays["vertices"], arrays["faces"])
    _count(stats, mesh_misses=1)
    mesh = load_mesh(path)
    if _same_file(path, key["sha256"]):
        _store(folder, entry, key, {"vertices": mesh.vertices, "faces": mesh.faces}, stats)
    return mesh


def _same_file(path, sha256_hex):
    """Whether the file still has this hash (it may have changed while it was parsed)."""
    try:
        same = file_sha256(path) == sha256_hex
    except Exception:
        same = False
    if not same:
        log.debug("mesh cache: %s changed while it was read; not stored", path)
    return same


def build_mesh_bvh_cached(vertices, faces, split="sah", leaf_size=None, use_cache=True, stats=None):
    """``collide.bvh.build_mesh_bvh(vertices, faces, split, leaf_size)``, read from the
    cache when possible (same arguments; vertices float64 (V, 3), faces int64 (F, 3)).
    Returns a BVH identical to the builder's; raises what it raises."""
    vertices, faces = np.asarray(vertices), np.asarray(faces)
    folder = _usable_folder() if use_cache else None
    if folder is None or faces.ndim != 2 or faces.shape[0] == 0:
        _count(stats, bvh_misses=1)
        return build_mesh_bvh(vertices, faces, split, leaf_size)
    key = bvh_key(vertices, faces, split, leaf_size)
    entry = _entry_path(folder, key)
    size = _leaf_size(leaf_size)
    arrays = _lookup(entry, key, _BVH_MEMBERS,
                     lambda found: check_bvh_arrays(found, vertices, faces, size), stats)
    if arrays is not None:
        _count(stats, bvh_hits=1)
        return BVH(*(arrays[k] for k in BVH._fields))
    _count(stats, bvh_misses=1)
    bvh = build_mesh_bvh(vertices, faces, split, leaf_size)
    _store(folder, entry, key, bvh._asdict(), stats)
    return bvh


def mesh_bvh_cached(mesh, split="sah", leaf_size=None, use_cache=True, stats=None):
    """build_mesh_bvh_cached over a Mesh's vertices and faces."""
    return build_mesh_bvh_cached(mesh.vertices, mesh.faces, split, leaf_size, use_cache, stats)


class MeshCache:
    """What a scan needs in one object: a mesh loader and a BVH builder with the
    signatures of load_mesh and build_mesh_bvh, the SHA-256 of every mesh file loaded
    (``digests``: {Path: hex str}, for provenance) and the counts (``stats``).

    ``enabled=False`` (``--no-cache``) parses and builds everything, still recording
    the digests.
    """

    def __init__(self, enabled=True):
        self.enabled = enabled
        self.stats = CacheStats()
        self.digests = {}

    def load_mesh(self, path):
        """Like collide.load.load_mesh(path)."""
        path = Path(path)
        try:
            self.digests[path] = file_sha256(path)
        except Exception:  # load_mesh describes the problem
            return load_mesh(path)
        return load_mesh_cached(path, self.digests[path], self.enabled, self.stats)

    def build_mesh_bvh(self, vertices, faces, split="sah", leaf_size=None):
        """Like collide.bvh.build_mesh_bvh(vertices, faces, split, leaf_size)."""
        return build_mesh_bvh_cached(vertices, faces, split, leaf_size, self.enabled, self.stats)


# --- housekeeping (for a future `collide cache` command) ----------------------------------------

def cache_size(folder=None):
    """(number of entries, total bytes) in the cache folder (default: cache_dir())."""
    folder = cache_dir() if folder is None else Path(folder)
    if folder is None:
        return 0, 0
    entries, _ = _entries(folder)
    return len(entries), sum(size for _, size, _ in entries)


def clear_cache(folder=None):
    """Delete every entry (and stale temporary file) of the cache folder (default:
    cache_dir()); other files are left alone. Returns (entries deleted, bytes freed)."""
    folder = cache_dir() if folder is None else Path(folder)
    if folder is None:
        return 0, 0
    entries, stale = _entries(folder)
    for path in stale:
        _remove(path)
    deleted = [(size, path) for _, size, path in entries if _remove(path)]
    return len(deleted), sum(size for size, _ in deleted)


__all__ = ["CACHE_FORMAT", "LOADER_VERSION", "BVH_VERSION", "CACHEABLE_SUFFIXES", "CACHE_ENV",
           "CacheStats", "MeshCache", "cache_dir", "default_cache_dir", "file_sha256", "mesh_key",
           "bvh_key", "arrays_sha256", "load_mesh_cached", "build_mesh_bvh_cached", "mesh_bvh_cached",
           "check_mesh_arrays", "check_bvh_arrays", "trim_cache", "cache_size", "clear_cache"]
