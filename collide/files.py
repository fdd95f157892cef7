"""Careful reading of input files: regular files only, HDF5 data that stays inside
its file, and a memory budget checked against declared sizes before reading.

A trajectory or contacts file from someone else must not make collide read other
files (HDF5 external links, external storage, virtual datasets), block on a FIFO
or a device, or allocate memory it does not have. Every refusal is an
``InputError`` (exit 2) that names the file and, where there is one, the dataset.
"""
import errno
import os
import re
import stat
import sys
from pathlib import Path

from . import config
from .errors import InputError

#: what a file that is not a regular file is, by the type bits of os.stat
_FILE_KINDS = ((stat.S_ISDIR, "is a folder"), (stat.S_ISFIFO, "is a FIFO (named pipe)"),
               (stat.S_ISCHR, "is a character device"), (stat.S_ISBLK, "is a block device"),
               (stat.S_ISSOCK, "is a socket"))


def os_problem(exc):
    """A short lower-case description of an OSError ("permission denied", ...)."""
    if exc.errno == errno.ENOENT:
        return "no such file"
    text = exc.strerror or os.strerror(exc.errno or 0) or type(exc).__name__
    return text[0].lower() + text[1:]


def not_regular(mode):
    """Why a file of this st_mode is not a regular file, or None when it is one."""
    if stat.S_ISREG(mode):
        return None
    for test, problem in _FILE_KINDS:
        if test(mode):
            return problem
    return "is not a regular file"


def stat_regular(path, expected):
    """os.stat of ``path`` (symlinks followed); raises InputError unless it is a
    readable regular file. ``expected`` completes the message ("an HDF5 ...")."""
    try:
        info = os.stat(path)
    except OSError as exc:
        raise InputError(path, os_problem(exc), expected) from None
    problem = not_regular(info.st_mode)
    if problem is not None:
        raise InputError(path, f"{problem}, not a regular file", expected)
    if not os.access(path, os.R_OK):
        raise InputError(path, "cannot read file (permission denied)", expected)
    return info


def open_regular(path, expected):
    """Open ``path`` for reading (binary file object) without blocking on FIFOs or
    devices: opened non-blocking, then refused unless fstat says it is a regular file."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise InputError(path, f"cannot open ({os_problem(exc)})", expected) from None
    problem = not_regular(os.fstat(fd).st_mode)
    if problem is not None:
        os.close(fd)
        raise InputError(path, f"{problem}, not a regular file", expected)
    file_obj = os.fdopen(fd, "rb")
    file_obj.raw.name = os.fspath(path)  # readers (trimesh) name things after it
    return file_obj


# --- HDF5 -------------------------------------------------------------------------------

def open_hdf5(path, expected):
    """Open a regular file as HDF5 for reading (h5py.File); InputError when it is not one."""
    import h5py
    stat_regular(path, expected)
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        text = str(exc)
        if "errno = 13" in text or "Permission denied" in text:
            detail = "permission denied"
        elif "signature" in text or "truncated" in text or "eof" in text.lower():
            detail = "not an HDF5 file or truncated"
        else:
            detail = "not a readable HDF5 file"
        raise InputError(path, f"cannot open as HDF5 ({detail})", expected) from None


#: soft links followed in a row before a path is refused (loops end here)
_MAX_SOFT_LINKS = 16
_EXTERNAL_HINT = "data stored in the file itself (or pass --allow-external-data)"


def hdf5_object(h5, path, name, allow_external=False):
    """The group or dataset at ``name`` ("poses/matrix") of an open h5py.File, or None
    when there is none.

    Unless ``allow_external``, nothing outside the file is touched: the path is
    walked link by link (soft links within the file are followed), and an external
    link, a dataset with external storage or a virtual dataset is an InputError
    naming ``name``. ``path`` is the file's path, for messages.
    """
    import h5py
    if allow_external:
        return h5.get(name)
    node = _walk_links(h5, path, name)
    if isinstance(node, h5py.Dataset):
        _check_dataset_storage(node, path, name)
    return node


def _walk_links(h5, path, name):
    """Follow ``name`` from the root one link at a time (see hdf5_object)."""
    import h5py
    todo = [p for p in name.split("/") if p not in ("", ".")]
    node, hops = h5["/"], 0
    while todo:
        part = todo.pop(0)
        if not isinstance(node, h5py.Group) or not node.id.links.exists(part.encode()):
            return None
        info = node.id.links.get_info(part.encode())
        if info.type == h5py.h5l.TYPE_HARD:
            node = node[part]
            continue
        if info.type == h5py.h5l.TYPE_EXTERNAL:
            target_file, target = (v.decode(errors="replace") for v in node.id.links.get_val(part.encode()))
            raise InputError(path, f"is an external link to {target_file!r}:{target!r}", _EXTERNAL_HINT,
                             dataset=name)
        if info.type != h5py.h5l.TYPE_SOFT:
            raise InputError(path, f"is a user-defined link (type {info.type})", "plain HDF5 groups and datasets",
                             dataset=name)
        hops += 1
        if hops > _MAX_SOFT_LINKS:
            raise InputError(path, f"soft links nest more than {_MAX_SOFT_LINKS} deep (a loop?)",
                             "a dataset the soft links lead to", dataset=name)
        target = node.id.links.get_val(part.encode()).decode(errors="replace")
        if target.startswith("/"):
            node = h5["/"]
        todo = [p for p in target.split("/") if p not in ("", ".")] + todo
    return node


def _check_dataset_storage(ds, path, name):
    """Refuse a dataset whose data lives outside the file (virtual or external storage)."""
    if ds.is_virtual:
        raise InputError(path, "is a virtual dataset (its data lives in other files)", _EXTERNAL_HINT,
                         dataset=name)
    if ds.external:
        files = ", ".join(repr(os.fsdecode(e[0])) for e in ds.external[:3])
        raise InputError(path, f"has external storage in {files}", _EXTERNAL_HINT, dataset=name)


# --- memory -----------------------------------------------------------------------------

_SIZE = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([kKmMgGtTpP]?)(i?[bB])?\s*$")
_UNITS = {"": 1, "k": 2**10, "m": 2**20, "g": 2**30, "t": 2**40, "p": 2**50}


def parse_size(text):
    """Bytes (int) of a size like "4G", "512M", "1.5GiB", "2e9" (K/M/G/T/P are powers
    of 1024); ValueError when it is not one or not positive."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value, unit = float(text), ""
    else:
        match = _SIZE.match(str(text))
        if match is None:
            raise ValueError(f"{text!r} is not a size")
        value, unit = float(match.group(1)), match.group(2).lower()
    size = value * _UNITS[unit]
    if not 1 <= size < 2**63:
        raise ValueError(f"{text!r} is not a size between 1 byte and 8 EiB")
    return int(size)


def format_size(n_bytes):
    """'1.5 GiB' style text of a byte count."""
    value = float(n_bytes)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if value < 1024 or unit == "PiB":
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.3g} {unit}"
        value /= 1024
    return f"{value:.3g} EiB"


def physical_memory():
    """Bytes of physical memory of this machine, or None when unknown."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def memory_limit(max_memory=None):
    """The memory budget in bytes: ``max_memory`` (bytes or a size text like "4G"),
    or by default config.MAX_MEMORY_FRACTION of the machine's memory (no limit
    when that is unknown)."""
    if max_memory is not None:
        return parse_size(max_memory)
    total = physical_memory()
    return None if total is None else int(config.MAX_MEMORY_FRACTION * total)


def check_memory(path, needed, limit, what, dataset=None):
    """Raise InputError when ``needed`` bytes (an estimate from declared shapes) exceed
    ``limit`` (bytes, None = no limit). ``what`` says what needs it."""
    if limit is not None and needed > limit:
        raise InputError(path, f"{what} needs about {format_size(needed)} of memory, more than the limit "
                         f"of {format_size(limit)}", "smaller data, or a higher --max-memory", dataset=dataset)


def declared_size(shape):
    """Number of elements of a declared HDF5 shape (Python int: no overflow)."""
    size = 1
    for extent in shape or ():
        size *= int(extent)
    return size


# --- collide's cache folder (meshes and compiled kernels) --------------------------------------

#: environment variable naming collide's cache folder
CACHE_ENV = "COLLIDE_CACHE_DIR"


def default_cache_dir():
    """The platform's user cache folder for collide (Path), or None without a home folder."""
    try:
        home = Path.home()
    except (RuntimeError, KeyError, OSError):
        home = None
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or (home and home / "AppData" / "Local")
        return Path(base) / "collide" / "Cache" if base else None
    if sys.platform == "darwin":
        return home / "Library" / "Caches" / "collide" if home else None
    xdg = os.environ.get("XDG_CACHE_HOME", "")
    if os.path.isabs(xdg):  # the XDG spec ignores relative paths
        return Path(xdg) / "collide"
    return home / ".cache" / "collide" if home else None


def cache_dir():
    """Where the cache lives: ``$COLLIDE_CACHE_DIR`` if set and not empty, else
    default_cache_dir(). A Path (which may not exist yet), or None when there is no
    location at all. Nothing is created or checked here."""
    configured = os.environ.get(CACHE_ENV, "")
    if configured:
        return Path(configured).expanduser()
    return default_cache_dir()
