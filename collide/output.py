"""Writing and reading contact files (SPEC §4, ``collide.contacts`` format v1).

Files are written atomically: to a hidden temporary file in the destination
folder, then renamed over the destination. A failed or interrupted write
removes the temporary file and leaves any existing output untouched.
"""
import json
import os
import signal
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .contacts import CONTACT_COLUMNS, KIND_LABELS, TRIANGLE_PAIR_COLUMNS
from .errors import InputError

FORMAT_NAME = "contacts"
FORMAT_VERSION = 1


class Contacts(NamedTuple):
    """A contact file's content (all arrays numpy)."""
    contacts: dict          #: columns of SPEC §4 contacts/
    objects: dict           #: name, mesh (lists of str), triangles int64 (N,)
    frame_time: np.ndarray  #: float64 (T,)
    triangle_pairs: dict    #: columns of triangle_pairs/, or None
    attrs: dict             #: file attributes (mode, interpolation, versions, ...)
    provenance: dict        #: provenance/ attributes


def check_output_path(path):
    """Raise InputError unless ``path`` can become an output file; returns its folder."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(path, "output folder does not exist", "a path in an existing folder")
    if path.is_dir():
        raise InputError(path, "is a folder", "an output file path")
    if not os.access(folder, os.W_OK):
        raise InputError(path, "output folder is not writable", "a writable folder")
    return folder


@contextmanager
def _interrupt_deferred():
    """Hold Ctrl-C (SIGINT) back while the body runs; yields a dict whose key
    "interrupted" tells whether one came.

    A KeyboardInterrupt raised inside h5py's cleanup callbacks is printed and
    dropped by Python, so an interrupt during writing could be lost and the
    file renamed into place anyway. Only the main thread can set signal
    handlers; elsewhere interrupts are not deferred.
    """
    state = {"interrupted": False}
    if threading.current_thread() is not threading.main_thread():
        yield state
        return

    def note(signum, frame):
        state["interrupted"] = True

    previous = signal.signal(signal.SIGINT, note)
    try:
        yield state
    finally:
        signal.signal(signal.SIGINT, previous)


@contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; rename it to ``path`` on success.

    On any exception, and on Ctrl-C during the body (raised as KeyboardInterrupt
    once the body is done), the temporary file is removed and ``path`` is left
    as it was.
    """
    path = Path(path)
    folder = check_output_path(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    except OSError as exc:
        raise InputError(path, f"cannot write in its folder ({exc.strerror})", "a writable folder") from None
    os.close(fd)
    try:
        with _interrupt_deferred() as state:
            yield Path(tmp)
        if state["interrupted"]:
            raise KeyboardInterrupt
        os.chmod(tmp, _file_mode(path))
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def _file_mode(path):
    """Permission bits for a new output file: those of the file it replaces, else
    0o666 minus the umask (mkstemp's temporary files are private, 0o600)."""
    try:
        return os.stat(path).st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def _write_columns(h5, group_name, columns, layout):
    group = h5.create_group(group_name)
    for name, dtype in layout.items():
        data = np.ascontiguousarray(columns[name], dtype=dtype)
        group.create_dataset(name, data=data, compression="gzip" if data.size > 4096 else None)
    return group


def write_contacts(path, result):
    """Write a ScanResult (see pipeline.py) to ``path`` atomically."""
    import h5py
    strings = h5py.string_dtype()
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w") as h5:
            h5.attrs["collide_format"] = FORMAT_NAME
            h5.attrs["format_version"] = FORMAT_VERSION
            h5.attrs["collide_version"] = result.versions["collide"]
            h5.attrs["mode"] = result.mode
            h5.attrs["interpolation"] = result.interpolation
            objects = h5.create_group("objects")
            objects.create_dataset("name", data=np.array(result.object_names, dtype=object), dtype=strings)
            objects.create_dataset("mesh", data=np.array(result.object_meshes, dtype=object), dtype=strings)
            objects.create_dataset("triangles", data=np.asarray(result.object_triangles, dtype=np.int64))
            frames = h5.create_group("frames")
            frames.create_dataset("time", data=np.asarray(result.frame_time, dtype=np.float64))
            frames.create_dataset("index", data=np.asarray(result.frame_index, dtype=np.int64))
            contacts = _write_columns(h5, "contacts", result.contacts, CONTACT_COLUMNS)
            contacts["kind"].attrs["labels"] = json.dumps({str(k): v for k, v in KIND_LABELS.items()})
            if result.triangle_pairs is not None:
                _write_columns(h5, "triangle_pairs", result.triangle_pairs, TRIANGLE_PAIR_COLUMNS)
            provenance = h5.create_group("provenance")
            for key, value in result.provenance.items():
                provenance.attrs[key] = value if isinstance(value, str) else json.dumps(value)


def _bad(path, problem, dataset=None):
    return InputError(path, problem, "a collide contacts file (SPEC §4)", dataset=dataset)


def _read_columns(h5, path, group, layout):
    if group not in h5:
        raise _bad(path, "missing group", dataset=group)
    columns = {}
    for name in layout:
        key = f"{group}/{name}"
        if key not in h5:
            raise _bad(path, "missing dataset", dataset=key)
        column = np.asarray(h5[key][()])
        if column.ndim != 1:
            raise _bad(path, f"has shape {column.shape}, not 1-D", dataset=key)
        wanted = np.dtype(layout[name])
        if column.dtype.kind not in ("iu" if wanted.kind in "iu" else "iuf"):
            raise InputError(path, f"has dtype {column.dtype}", f"{wanted.name} values (SPEC §4)", dataset=key)
        columns[name] = column.astype(wanted)
    lengths = {c.shape[0] for c in columns.values()}
    if len(lengths) > 1:
        raise _bad(path, f"columns have different lengths {sorted(lengths)}", dataset=group)
    return columns


def read_contacts(path):
    """Read a contacts file; raises InputError if it is not one."""
    import h5py
    path = Path(path)
    if path.is_dir():
        raise InputError(path, "is a folder", "a collide contacts file (SPEC §4)")
    if not path.is_file():
        raise InputError(path, "no such file", "a collide contacts file (SPEC §4)")
    try:
        h5 = h5py.File(path, "r")
    except OSError:
        raise _bad(path, "cannot open as HDF5 (not an HDF5 file or truncated)") from None
    with h5:
        try:
            attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in h5.attrs.items()}
            if attrs.get("collide_format") != FORMAT_NAME:
                raise _bad(path, "not a collide contacts file (attribute collide_format is missing)")
            if int(attrs.get("format_version", -1)) != FORMAT_VERSION:
                raise _bad(path, f"unsupported format_version {attrs.get('format_version')}")
            for key in ("objects/name", "objects/mesh", "objects/triangles", "frames/time"):
                if key not in h5:
                    raise _bad(path, "missing dataset", dataset=key)
            objects = {
                "name": [str(s) for s in h5["objects/name"].asstr()[()]],
                "mesh": [str(s) for s in h5["objects/mesh"].asstr()[()]],
                "triangles": np.asarray(h5["objects/triangles"][()], dtype=np.int64),
            }
            contacts = _read_columns(h5, path, "contacts", CONTACT_COLUMNS)
            pairs = (_read_columns(h5, path, "triangle_pairs", TRIANGLE_PAIR_COLUMNS)
                     if "triangle_pairs" in h5 else None)
            provenance = dict(h5["provenance"].attrs) if "provenance" in h5 else {}
            frame_time = np.asarray(h5["frames/time"][()], dtype=np.float64)
        except (OSError, KeyError, TypeError, ValueError) as exc:
            raise _bad(path, f"cannot read ({str(exc)[:80]})") from None
    n = len(objects["name"])
    for side in ("object_a", "object_b"):
        col = contacts[side]
        if col.size and (col.min() < 0 or col.max() >= n):
            raise _bad(path, f"{side} index out of range of objects/name", dataset=f"contacts/{side}")
    return Contacts(contacts, objects, frame_time, pairs, attrs, provenance)
