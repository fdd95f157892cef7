"""Writing and reading contact files (``collide.contacts`` format v1).

Files are written atomically: to a hidden temporary file in the destination
folder (``.NAME.HOST-PID.RANDOM.tmp``), then renamed over the destination. A
failed or interrupted write (exception, Ctrl-C, SIGTERM, SIGHUP) removes the
temporary file and leaves any existing output untouched; temporary files of
killed runs (kill -9) on this machine are removed by the next write to the same
folder, once their process is gone. Only regular files (or new paths) are
written, never an input of the same run. A full disk or a file size limit is a
clean InputError (exit 2), never a crash inside HDF5.
"""
import _signal  # signal's C module (see _SignalsDeferred)
import errno
import hashlib
import io
import json
import logging
import os
import re
import signal
import socket
import stat
import tempfile
import threading
from contextlib import contextmanager, nullcontext
from pathlib import Path

import numpy as np

from . import config
from .contacts import CONTACT_COLUMNS, KIND_LABELS, TRIANGLE_PAIR_COLUMNS
from .errors import InputError, escape_text
from .files import (
    check_memory,
    declared_size,
    hdf5_object,
    memory_limit,
    not_regular,
    open_hdf5,
    os_problem,
)
from .result import ScanResult

log = logging.getLogger("collide")

FORMAT_NAME = "contacts"
FORMAT_VERSION = 1
CONTACTS_FILE = "a collide contacts file (from collide scan)"


#: a contacts file's content is a ScanResult (the name is kept for readers of older code)
Contacts = ScanResult


# --- where an output may go ---------------------------------------------------------------

def output_target(path):
    """The file a write to ``path`` replaces: ``path`` itself or, when it is a symbolic
    link, the file it points to (the link stays)."""
    path = Path(path)
    return Path(os.path.realpath(path)) if os.path.islink(path) else path


def check_output_path(path, inputs=()):
    """Raise InputError unless ``path`` can become an output file; returns the path
    that will be written (output_target).

    Refused: a missing or unwritable folder, a folder, anything but a regular file
    (devices such as /dev/null, FIFOs, sockets), and any of ``inputs`` (paths,
    compared by identity of the file: same inode, whatever the spelling or hard link).
    """
    target = output_target(path)
    folder = target.parent if str(target.parent) else Path(".")
    try:
        if not stat.S_ISDIR(os.stat(folder).st_mode):
            raise InputError(path, "output folder is not a folder", "a path in an existing folder")
    except OSError as exc:
        problem = "output folder does not exist" if exc.errno == errno.ENOENT else \
            f"output folder: {os_problem(exc)}"
        raise InputError(path, problem, "a path in an existing folder") from None
    try:
        mode = os.stat(target).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:
        raise InputError(path, os_problem(exc), "an output file path") from None
    if mode is not None and stat.S_ISDIR(mode):
        raise InputError(path, "is a folder", "an output file path")
    if mode is not None and not stat.S_ISREG(mode):
        raise InputError(path, f"{not_regular(mode)}: only regular files are replaced",
                         "the path of a regular file or of a new file")
    if mode is not None:
        _check_not_an_input(path, target, inputs)
    if not os.access(folder, os.W_OK):
        raise InputError(path, "output folder is not writable", "a writable folder")
    return target


def check_not_an_input(path, inputs):
    """Raise InputError if ``path`` exists and is one of ``inputs`` (check_output_path's
    identity test alone, for files written into a folder the caller has checked)."""
    target = output_target(path)
    if os.path.lexists(target):
        _check_not_an_input(path, target, inputs)


def _check_not_an_input(path, target, inputs):
    for source in inputs:
        try:
            same = os.path.samefile(target, source)
        except OSError:
            continue
        if same:
            where = "" if os.fspath(source) == os.fspath(path) else f" ({escape_text(source)})"
            raise InputError(path, f"is an input of this command{where}; writing it would destroy the input",
                             "an output path that is not one of the input files")


# --- temporary files ---------------------------------------------------------------------

#: identifies this machine in temporary file names (a PID means nothing on another host)
HOST_TAG = hashlib.sha1(socket.gethostname().encode(errors="replace")).hexdigest()[:8]
_TEMPORARY = re.compile(r"^\.(?P<name>.*)\.(?P<host>[0-9a-f]{8})-(?P<pid>[0-9]{1,10})\.[A-Za-z0-9_]+\.tmp$")
#: characters of the output's name kept in a temporary file's name
_NAME_CHARS = 80


def temporary_prefix(target):
    """Prefix of this process's temporary files for ``target``: ``.NAME.HOST-PID.``."""
    return f".{target.name[:_NAME_CHARS]}.{HOST_TAG}-{os.getpid()}."


def _process_alive(pid):
    """Whether a process with this PID exists on this machine (any owner)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except (OverflowError, OSError):
        return False
    return True


def remove_stale_temporaries(folder):
    """Remove temporary files that collide runs on this machine left in ``folder`` when
    they were killed (their process no longer exists); returns the paths removed.

    Files of live processes, of other machines, of other users and anything not a
    regular file are left alone.
    """
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        match = _TEMPORARY.match(entry.name)
        if match is None or match["host"] != HOST_TAG or _process_alive(int(match["pid"])):
            continue
        try:
            info = entry.stat(follow_symlinks=False)
            if not stat.S_ISREG(info.st_mode) or info.st_uid != os.getuid():
                continue
            os.unlink(entry.path)
        except OSError:
            continue
        removed.append(Path(entry.path))
        log.warning("removed %s, a temporary file left by an earlier collide run (process %s) that was killed",
                    escape_text(entry.path), match["pid"])
    return removed


#: signals that end a run: during a write they are held back until the file is
#: complete or removed, then delivered again (plain ints: see _SignalsDeferred)
_STOP_SIGNALS = tuple(int(getattr(signal, name)) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class _SignalsDeferred:
    """Hold Ctrl-C (SIGINT), SIGTERM and SIGHUP back while the body runs; ``with`` gives a
    list that holds the signal numbers that came (first first).

    A KeyboardInterrupt raised inside h5py's cleanup callbacks is printed and
    dropped by Python, so an interrupt during writing could be lost and the file
    renamed into place anyway. Only the main thread can set signal handlers;
    elsewhere nothing is deferred. Ignored signals stay ignored. It runs around every
    one-worker kernel call, so it is a plain class (a generator-based context manager
    costs several µs more per use) and uses signal's C module (_signal), which takes and
    returns plain ints: signal's enum conversions cost 30 µs per use, the C calls 2 µs.
    """

    __slots__ = ("came", "previous")

    def __init__(self):
        self.came = []
        self.previous = []

    def note(self, signum, frame):
        self.came.append(signum)

    def __enter__(self):
        if threading.get_ident() == _MAIN_THREAD:
            try:
                for signum in _STOP_SIGNALS:
                    handler = _signal.getsignal(signum)
                    if handler != _signal.SIG_IGN and handler is not None:
                        self.previous.append((signum, _signal.signal(signum, self.note)))
            except BaseException:
                self._restore()
                raise
        return self.came

    def __exit__(self, *exc_info):
        self._restore()
        return False

    def _restore(self):
        for signum, handler in self.previous:
            _signal.signal(signum, handler)
        self.previous.clear()


_MAIN_THREAD = threading.main_thread().ident


class signals_held(_SignalsDeferred):
    """Hold stop signals back during a short write or kernel call (see _SignalsDeferred),
    then, unless the body raised, deliver the first that came."""

    __slots__ = ()

    def __exit__(self, *exc_info):
        self._restore()
        if self.came and exc_info[0] is None:
            _redeliver(self.came[0])
        return False


def _redeliver(signum):
    """Deliver a signal that was held back to its own handler (KeyboardInterrupt,
    collide's Terminated, or the default action); if that handler returns, the
    write still counts as interrupted."""
    signal.raise_signal(signum)
    raise KeyboardInterrupt


def _remove(path):
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


_NO_ROOM = (errno.ENOSPC, errno.EFBIG, getattr(errno, "EDQUOT", errno.ENOSPC))


def write_error(path, exc):
    """The InputError for an OSError while writing ``path`` (full disk, size limit, ...)."""
    if exc.errno in _NO_ROOM:
        return InputError(path, f"cannot write ({os_problem(exc)})",
                          "a destination with enough free space and no file size limit below the result's size")
    return InputError(path, f"cannot write ({os_problem(exc)})", "a writable destination")


@contextmanager
def atomic_path(path, inputs=(), defer_signals=True):
    """Yield a temporary path next to ``path``; rename it to ``path`` on success.

    ``path`` is checked first (check_output_path, with ``inputs`` that must not be
    overwritten). On any exception, and on Ctrl-C, SIGTERM or SIGHUP during the
    body (delivered once the body is done, unless not ``defer_signals``: a long body
    that holds signals back only while it writes, with signals_held), the temporary
    file is removed and ``path`` is left as it was. An OSError with an errno from the
    body or the rename (full disk, file size limit) becomes an InputError.
    """
    target = check_output_path(path, inputs)
    folder = target.parent if str(target.parent) else Path(".")
    remove_stale_temporaries(folder)
    tmp = None
    try:
        with signals_held():  # a stop signal before tmp is known would leave the file behind
            try:
                fd, tmp = tempfile.mkstemp(prefix=temporary_prefix(target), suffix=".tmp", dir=folder)
            except OSError as exc:
                raise InputError(path, f"cannot write in its folder ({os_problem(exc)})", "a writable folder") \
                    from None
            os.close(fd)
        with _SignalsDeferred() if defer_signals else nullcontext([]) as came:
            try:
                yield Path(tmp)
            except OSError as exc:
                if exc.errno is None:
                    raise
                raise write_error(path, exc) from None
        if came:
            _remove(tmp)
            _redeliver(came[0])
        try:
            os.chmod(tmp, _file_mode(target))
            os.replace(tmp, target)
        except OSError as exc:
            raise write_error(path, exc) from None
    except BaseException:
        if tmp is not None:
            _remove(tmp)
        raise


def write_bytes_atomic(path, data, inputs=()):
    """Write ``data`` (bytes) to ``path`` atomically (see atomic_path), synced to disk."""
    with atomic_path(path, inputs) as tmp:
        fd = os.open(tmp, os.O_WRONLY | getattr(os, "O_CLOEXEC", 0))
        try:
            view = memoryview(data).cast("B")
            while view:
                view = view[os.write(fd, view):]
            os.fsync(fd)
        finally:
            os.close(fd)


class _FileSink(io.RawIOBase):
    """The file object h5py writes an output through (its "fileobj" driver).

    The first failed write (full disk, file size limit) is recorded in ``error``
    and everything after it is dropped while HDF5 is told it succeeded, so HDF5
    never meets a write error (after one, closing an h5py file can crash the
    process). Reads of dropped regions give zeros. The caller raises ``error``.
    """

    def __init__(self, fd):
        super().__init__()
        self.fd, self.pos, self.size, self.error = fd, 0, 0, None

    def readable(self):
        return True

    def writable(self):
        return True

    def seekable(self):
        return True

    def seek(self, offset, whence=io.SEEK_SET):
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self.pos, io.SEEK_END: self.size}[whence]
        self.pos = base + offset
        return self.pos

    def tell(self):
        return self.pos

    def readinto(self, buffer):
        view = memoryview(buffer).cast("B")
        data = os.pread(self.fd, len(view), self.pos) if self.error is None else b""
        if self.pos < self.size and len(data) < len(view):
            data = data + bytes(min(len(view), self.size - self.pos) - len(data))
        view[:len(data)] = data
        self.pos += len(data)
        return len(data)

    def write(self, buffer):
        view = memoryview(buffer).cast("B")
        n = len(view)
        offset = self.pos
        while self.error is None and view:
            try:
                written = os.pwrite(self.fd, view, offset)
            except OSError as exc:
                self.error = exc
                break
            view, offset = view[written:], offset + written
        self.pos += n
        self.size = max(self.size, self.pos)
        return n

    def truncate(self, size=None):
        size = self.pos if size is None else size
        if self.error is None:
            try:
                os.ftruncate(self.fd, size)
            except OSError as exc:
                self.error = exc
        self.size = size
        return size


@contextmanager
def atomic_hdf5(path, inputs=(), defer_signals=True):
    """Yield a new h5py.File that becomes ``path`` once the block completes (see
    atomic_path, also for ``defer_signals``). A full disk or file size limit during the
    write is an InputError; the data is synced to disk before the rename."""
    import h5py
    with atomic_path(path, inputs, defer_signals) as tmp:
        fd = os.open(tmp, os.O_RDWR | getattr(os, "O_CLOEXEC", 0))
        sink = _FileSink(fd)
        try:
            try:
                with nullcontext() if defer_signals else signals_held():  # HDF5 must not be interrupted
                    h5 = h5py.File(sink, "w")
                try:
                    yield h5
                finally:
                    with nullcontext() if defer_signals else signals_held():
                        h5.close()
            except Exception:
                if sink.error is not None:  # the cause, whatever HDF5 made of it
                    raise sink.error from None
                raise
            if sink.error is not None:
                raise sink.error
            os.fsync(fd)
        finally:
            os.close(fd)


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


def write_contacts(path, result, inputs=()):
    """Write a ScanResult (see pipeline.py) to ``path`` atomically; ``inputs`` are
    paths the output must not replace (the scan's trajectory and mesh files)."""
    with atomic_hdf5(path, inputs) as h5:
        write_result(h5, result)


class TrianglePairWriter:
    """Appends triangle-pair columns (TRIANGLE_PAIR_COLUMNS) to the output file's
    triangle_pairs/ group as a scan produces them (chunked, resizable datasets), so
    they never need to be in memory all at once."""

    def __init__(self, h5):
        with signals_held():  # a stop signal inside HDF5 can leave it in pieces
            group = h5.create_group("triangle_pairs")
            self.datasets = {name: group.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype,
                                                        chunks=(1 << 16,), compression="gzip")
                             for name, dtype in TRIANGLE_PAIR_COLUMNS.items()}
        self.rows = 0

    def __call__(self, columns):
        n = len(columns["frame"])
        if n == 0:
            return
        with signals_held():
            for name, ds in self.datasets.items():
                ds.resize((self.rows + n,))
                ds[self.rows:] = np.asarray(columns[name], dtype=TRIANGLE_PAIR_COLUMNS[name])
        self.rows += n


def write_result(h5, result):
    """Write a ScanResult into an open output file (h5py.File) in the contacts format
    (triangle pairs only when the result holds them: a TrianglePairWriter may have
    written them already)."""
    import h5py
    strings = h5py.string_dtype()
    with signals_held():
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


# --- reading -----------------------------------------------------------------------------

def _bad(path, problem, dataset=None):
    return InputError(path, problem, CONTACTS_FILE, dataset=dataset)


def _dataset(h5, path, name):
    """A 1-D dataset of the file (never data outside it); InputError otherwise."""
    import h5py
    ds = hdf5_object(h5, path, name)
    if ds is None:
        raise _bad(path, "missing dataset", dataset=name)
    if not isinstance(ds, h5py.Dataset):
        raise _bad(path, "is a group, not a dataset", dataset=name)
    if ds.shape is None or len(ds.shape) != 1:
        raise _bad(path, f"has shape {ds.shape}, not 1-D", dataset=name)
    return ds


def _column_datasets(h5, path, group, layout):
    """{name: dataset} of a group's columns: present, 1-D, numeric, equal lengths."""
    if hdf5_object(h5, path, group) is None:
        raise _bad(path, "missing group", dataset=group)
    datasets = {}
    for name in layout:
        ds = _dataset(h5, path, f"{group}/{name}")
        wanted = np.dtype(layout[name])
        if ds.dtype.kind not in ("iu" if wanted.kind in "iu" else "iuf"):
            raise InputError(path, f"has dtype {ds.dtype}", f"{wanted.name} values", dataset=f"{group}/{name}")
        datasets[name] = ds
    lengths = {ds.shape[0] for ds in datasets.values()}
    if len(lengths) > 1:
        raise _bad(path, f"columns have different lengths {sorted(lengths)}", dataset=group)
    return datasets


def _read(path, ds, strings=False):
    """All of dataset ds (as str when ``strings``); a dataset that cannot be read (a
    corrupt chunk, say) is an InputError naming it."""
    try:
        return ds.asstr()[()] if strings else ds[()]
    except (OSError, ValueError, RuntimeError) as exc:
        raise _bad(path, f"cannot read ({str(exc)[:80]})", dataset=ds.name.lstrip("/")) from None


def _read_column(path, ds, dtype):
    """A column converted to ``dtype``; integers that do not fit become -1 (out of range)."""
    data = np.asarray(_read(path, ds))
    wanted = np.dtype(dtype)
    if wanted.kind in "iu" and data.size:
        info = np.iinfo(wanted)
        if data.min() < info.min or data.max() > info.max:
            data = np.where((data < info.min) | (data > info.max), -1, data)
    return data.astype(wanted)


def _contacts_bytes(declared):
    """Estimated memory (bytes) of reading datasets of these declared (shape, is_string) pairs."""
    return sum(declared_size(shape) * (config.STRING_BYTES if is_string else config.NUMBER_BYTES)
               for shape, is_string in declared)


def read_contacts(path, max_memory=None):
    """Read a contacts file; raises InputError if it is not a valid one.

    Declared sizes are checked against ``max_memory`` (bytes or "4G"; default
    files.memory_limit()) before reading; data stored outside the file is
    refused; indices must point at existing objects, frames and triangles, and
    times must be finite.
    """
    path = Path(path)
    with open_hdf5(path, CONTACTS_FILE) as h5:
        try:
            cf = _read_contacts(h5, path, memory_limit(max_memory))
        except InputError:
            raise
        except (OSError, KeyError, TypeError, ValueError, RuntimeError) as exc:
            raise _bad(path, f"cannot read ({str(exc)[:80]})") from None
    _check_contacts(path, cf)
    return cf


def _read_contacts(h5, path, limit):
    attrs = {k: (v.decode(errors="replace") if isinstance(v, bytes) else v) for k, v in h5.attrs.items()}
    if attrs.get("collide_format") != FORMAT_NAME:
        found = attrs.get("collide_format")
        why = "is missing" if found is None else f"is {str(found)[:40]!r}, not {FORMAT_NAME!r}"
        raise _bad(path, f"not a collide contacts file (attribute collide_format {why})")
    if str(attrs.get("format_version")) != str(FORMAT_VERSION):
        raise _bad(path, f"unsupported format_version {attrs.get('format_version')}")
    names = {key: _dataset(h5, path, key) for key in ("objects/name", "objects/mesh", "objects/triangles",
                                                      "frames/time")}
    contacts = _column_datasets(h5, path, "contacts", CONTACT_COLUMNS)
    pairs = (_column_datasets(h5, path, "triangle_pairs", TRIANGLE_PAIR_COLUMNS)
             if hdf5_object(h5, path, "triangle_pairs") is not None else {})
    declared = [(ds.shape, key in ("objects/name", "objects/mesh")) for key, ds in names.items()]
    declared += [(ds.shape, False) for ds in list(contacts.values()) + list(pairs.values())]
    check_memory(path, _contacts_bytes(declared), limit, "reading this contacts file")
    objects = {
        "name": [str(s) for s in _read(path, names["objects/name"], strings=True)],
        "mesh": [str(s) for s in _read(path, names["objects/mesh"], strings=True)],
        "triangles": _read_column(path, names["objects/triangles"], np.int64),
    }
    provenance = {}
    group = hdf5_object(h5, path, "provenance")
    if group is not None:
        provenance = {key: _provenance_value(value) for key, value in group.attrs.items()}
    frame_time = np.asarray(_read(path, names["frames/time"]), dtype=np.float64)
    return ScanResult.from_file({k: _read_column(path, ds, CONTACT_COLUMNS[k]) for k, ds in contacts.items()},
                                objects,
                                frame_time, _frame_index(h5, path, frame_time.shape),
                                {k: _read_column(path, ds, TRIANGLE_PAIR_COLUMNS[k]) for k, ds in pairs.items()}
                                or None,
                                attrs, provenance)


def _provenance_value(value):
    """A provenance attribute as the scan's result holds it: the mappings and lists that
    write_result stored as JSON text parsed back, other text as str."""
    if isinstance(value, bytes):
        value = value.decode(errors="replace")
    if isinstance(value, str) and value[:1] in ("{", "["):
        try:
            return json.loads(value)
        except ValueError:
            return value
    return value


def _frame_index(h5, path, shape):
    """frames/index (int64, the analysed frames' indices in the trajectory) when the file
    has a valid one, else 0, 1, 2, ..."""
    import h5py
    ds = hdf5_object(h5, path, "frames/index")
    if isinstance(ds, h5py.Dataset) and ds.shape == shape and ds.dtype.kind in "iu":
        return np.asarray(_read(path, ds), dtype=np.int64)
    return np.arange(shape[0], dtype=np.int64)


def _first_bad(path, dataset, bad, problem):
    """Raise for the first True of the boolean array ``bad`` (row index in the message)."""
    if bad.any():
        raise _bad(path, f"{problem} at row {int(np.argmax(bad))}", dataset=dataset)


def _check_contacts(path, cf):
    """Every index in range, every time finite (see read_contacts)."""
    n = len(cf.objects["name"])
    if len(cf.objects["mesh"]) != n or cf.objects["triangles"].shape[0] != n:
        raise _bad(path, "objects/name, objects/mesh and objects/triangles differ in length", dataset="objects")
    triangles = cf.objects["triangles"]
    _first_bad(path, "objects/triangles", triangles < 0, "negative triangle count")
    _first_bad(path, "frames/time", ~np.isfinite(cf.frame_time), "non-finite frame time")
    n_frames = cf.frame_time.shape[0]
    c = cf.contacts
    for column in ("t_begin", "t_end"):
        _first_bad(path, f"contacts/{column}", ~np.isfinite(c[column]), "non-finite time")
    _first_bad(path, "contacts/t_end", c["t_end"] < c["t_begin"], "t_end before t_begin")
    _first_bad(path, "contacts/kind", ~np.isin(c["kind"], list(KIND_LABELS)), "unknown kind")
    for group, columns in (("contacts", c), ("triangle_pairs", cf.triangle_pairs)):
        if columns is None:
            continue
        for side in ("object_a", "object_b"):
            _first_bad(path, f"{group}/{side}", (columns[side] < 0) | (columns[side] >= n),
                       f"object index out of range of objects/name ({n} objects)")
        _first_bad(path, f"{group}/object_b", columns["object_a"] >= columns["object_b"],
                   "object_a not below object_b")
        for side, tri in (("object_a", "tri_a"), ("object_b", "tri_b")):
            limit = triangles[columns[side]]
            _first_bad(path, f"{group}/{tri}", (columns[tri] < 0) | (columns[tri] >= limit),
                       "triangle index out of range of the object's objects/triangles")
        frame_columns = ("frame_begin", "frame_end") if group == "contacts" else ("frame",)
        for column in frame_columns:
            _first_bad(path, f"{group}/{column}", (columns[column] < 0) | (columns[column] >= n_frames),
                       f"frame index out of range of frames/time ({n_frames} frames)")
