"""How collide compiles its numba kernels, and where it keeps them compiled.

Every kernel module takes ``njit`` (and ``prange``, and the two variants below for helpers
that borrow their arrays or allocate their own: ``njit_borrowing``, ``njit_allocating``)
from here, so that importing any of them first installs collide's kernel cache: one folder per collide source, named by
the content of collide's source files, not by where they are installed. The same
kernels compiled by a test run in the repository, by the installed command line, or in
another virtual environment at another path are found and reused; and any change to
any source file (a kernel, or a helper it inlines from another file) makes a new
folder, so a stale compiled kernel is never loaded. numba itself keys entries by the
function's signature and the machine's CPU (name and features) within the folder.

Where: ``COLLIDE_KERNEL_CACHE_DIR`` if set; else ``$NUMBA_CACHE_DIR/collide-kernels``
if numba's own variable is set; else ``kernels/`` in collide's cache folder
(``COLLIDE_CACHE_DIR``, default the platform's user cache: ``~/.cache/collide`` on
Linux). Inside: ``<collide version>-<source digest>-py<X.Y>-numba<version>``. A folder
that cannot be written leaves numba's own choice (next to the sources, or its
per-user cache). Each process marks its folder used (its modification time); making a
new folder deletes older folders of the same Python and numba versions beyond the
KEEP_KERNEL_FOLDERS most recently used and unused for a day (prune_kernel_folders),
so upgrades do not pile up 20-30 MB of compiled kernels each.
"""
import functools
import hashlib
import os
import re
import shutil
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import llvmlite.binding as llvm
import numba
from numba import njit, prange  # noqa: F401  (re-exported: kernel modules import them from here)
from numba.core import caching

from ._version import __version__
from .files import cache_dir

PACKAGE = Path(__file__).resolve().parent


def njit_borrowing(function):
    """``njit(cache=True)`` without numba's reference counting, for a helper that only reads
    and writes the arrays it is handed (and views of them): it allocates none and returns
    none. numba would otherwise add an atomic increment and decrement, at every call, of
    every array argument, every view and every array field of a tuple it takes: 20-28 %
    of a continuous scan of 1000 bodies went to them (perf) before the geometric helpers
    used this. The helpers it calls are compiled the same way (numba hands the option
    down) unless marked njit_allocating; none may return an array
    (tests/test_kernel_cache.py checks every one that was compiled)."""
    return njit(cache=True, _nrt=False)(function)


def njit_allocating(function):
    """``njit(cache=True)`` with numba's runtime (allocation, reference counting) also when
    an njit_borrowing helper calls it, which would otherwise compile it without: for a
    helper that allocates scratch arrays of its own and returns none (the exact
    predicates' expansions)."""
    return njit(cache=True, _nrt=True)(function)


def njit_entry(function):
    """``njit(cache=True, nogil=True)`` for a kernel that Python calls and no other kernel
    does (the scan kernels): its cache entry keeps the machine code and only the *names*
    its code defines, not the LLVM bitcode numba also stores to inline a function into
    callers. Reading that bitcode back cost 150 ms of every continuous run (parsing
    2 MB, then listing its symbols), more than the scan of a small scene.

    In its place the entry holds a module that defines each of those names as a
    function that traps, so that numba registers the same symbols as before; a kernel
    that called an entry kernel would link those traps, which
    tests/test_kernel_cache.py rules out by checking that no kernel names one."""
    dispatcher = njit(cache=True, nogil=True)(function)
    dispatcher._cache = EntryKernelCache(dispatcher.py_func)
    return dispatcher


class _EntryKernelCacheImpl(caching.CompileResultCacheImpl):
    """numba's compile-result cache with the library's bitcode replaced by symbol stubs."""

    def reduce(self, cres):
        library, *rest = payload = super().reduce(cres)
        try:
            name, kind, (object_code, bitcode) = library
            if kind != "object" or not isinstance(bitcode, bytes):
                return payload
            return ((name, kind, (object_code, symbol_stubs(bitcode))), *rest)
        except Exception:  # a numba that stores libraries otherwise: its own entry, slower to load
            return payload


class EntryKernelCache(caching.FunctionCache):
    """The cache of an njit_entry kernel (see there)."""
    _impl_class = _EntryKernelCacheImpl


def symbol_stubs(bitcode):
    """LLVM bitcode (bytes) of a module defining, as functions that trap, every function
    and global variable that the module in ``bitcode`` defines and other modules can see
    (not internal or private), and nothing else."""
    module = llvm.parse_bitcode(bitcode)
    hidden = (llvm.Linkage.internal, llvm.Linkage.private)
    names = [value.name for values in (module.functions, module.global_variables)
             for value in values if not value.is_declaration and value.linkage not in hidden and value.name]
    stubs = "".join(f'define void @"{_llvm_escape(name)}"() {{\n  call void @llvm.trap()\n  unreachable\n}}\n'
                    for name in names)
    return llvm.parse_assembly(stubs + "declare void @llvm.trap()\n").as_bitcode()


def _llvm_escape(name):
    """``name`` for a quoted LLVM identifier: \\XX for every byte outside printable ASCII
    and for the quote and backslash."""
    return "".join(chr(b) if 32 <= b < 127 and b not in (34, 92) else f"\\{b:02X}" for b in name.encode())


def _source_digest():
    """sha256 (first 16 hex digits) of every .py file of the package, names and bytes."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


SOURCE_DIGEST = _source_digest()


def cache_root():
    """The folder holding collide's kernel caches (see module docstring)."""
    explicit = os.environ.get("COLLIDE_KERNEL_CACHE_DIR")
    if explicit:
        return Path(explicit)
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        return Path(numba_dir) / "collide-kernels"
    root = cache_dir()
    return (root if root is not None else PACKAGE / "__pycache__") / "kernels"


def kernel_cache_dir():
    """This collide source's kernel folder: <root>/<version>-<digest>-py<X.Y>-numba<version>."""
    python = f"py{sys.version_info[0]}.{sys.version_info[1]}"
    return cache_root() / f"{__version__}-{SOURCE_DIGEST}-{python}-numba{numba.__version__}"


class ContentKeyedLocator(caching._CacheLocator):
    """numba cache locator for collide's own functions: kernel_cache_dir(), with the
    source digest as freshness stamp."""

    def __init__(self, py_func, py_file, cache_path=None):
        self._py_file = py_file  # numba names it in its "cannot cache" warning
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = cache_path or str(kernel_cache_dir())

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return SOURCE_DIGEST

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        path = str(kernel_cache_dir())
        if not _in_package(py_file) or not _usable_folder(path):
            return None  # not ours, or not writable: numba's own locators decide
        return cls(py_func, py_file, path)


@functools.lru_cache(maxsize=None)
def _in_package(py_file):
    """Whether the source file ``py_file`` is one of collide's (asked once per file, not
    once per function: importing collide creates about 280 compiled functions)."""
    try:
        return Path(py_file).resolve().parent == PACKAGE
    except OSError:
        return False


@functools.lru_cache(maxsize=None)
def _usable_folder(path):
    """Whether the kernel folder ``path`` exists or can be made, and can be written (numba's
    check, a temporary file, once per process rather than once per function). Marks it
    used; when it is new, prunes old kernel folders next to it (prune_kernel_folders)."""
    new = not os.path.isdir(path)
    try:
        caching._CacheLocator.ensure_cache_path(_FolderOnly(path))
    except OSError:
        return False
    try:
        os.utime(path)  # last use (best effort: a folder whose time cannot be set still caches)
    except OSError:
        pass
    if new:
        prune_kernel_folders(path)
    return True


#: kernel folders of one Python and numba version kept when a new one is made: it and the
#: most recently used others (other collide versions)
KEEP_KERNEL_FOLDERS = 3
#: a kernel folder used this recently (seconds) is never deleted: a process may be using it
KEEP_RECENT_SECONDS = 24 * 3600

#: the names kernel_cache_dir gives: <version>-<16 hex digits>-<py and numba tag>
_KERNEL_FOLDER_NAME = re.compile(r"[0-9][0-9A-Za-z.+_!]*-[0-9a-f]{16}-(py[0-9]+\.[0-9]+-numba[0-9].*)")


def prune_kernel_folders(current, keep=KEEP_KERNEL_FOLDERS, recent=KEEP_RECENT_SECONDS):
    """Delete the kernel folders next to the kernel folder ``current`` that belong to the
    same Python and numba versions (the end of their names), come after the ``keep``
    most recently used (modification time, ``current`` counted) and have not been used
    for ``recent`` seconds. Never ``current`` itself, nor folders of other Python or
    numba versions (other environments sharing the cache, used in turn, would otherwise
    compile afresh every time), nor anything not named as kernel_cache_dir names
    folders. What cannot be deleted stays (housekeeping never fails a scan). Returns
    the paths deleted."""
    current = Path(current)
    match = _KERNEL_FOLDER_NAME.fullmatch(current.name)
    if match is None:
        return []
    try:
        entries = list(os.scandir(current.parent))
    except OSError:
        return []
    folders = []
    for entry in entries:
        other = _KERNEL_FOLDER_NAME.fullmatch(entry.name)
        if other is None or other.group(1) != match.group(1):
            continue
        try:
            if entry.is_dir(follow_symlinks=False):
                folders.append((entry.stat(follow_symlinks=False).st_mtime, entry.path))
        except OSError:
            continue
    folders.sort(reverse=True)
    now = time.time()
    deleted = []
    for used, path in folders[keep:]:
        if now - used < recent or Path(path) == current:
            continue
        shutil.rmtree(path, ignore_errors=True)
        if not os.path.lexists(path):
            deleted.append(path)
    return deleted


class _FolderOnly:
    """What _CacheLocator.ensure_cache_path asks of a locator: the folder."""

    def __init__(self, path):
        self._path = path

    def get_cache_path(self):
        return self._path


@contextmanager
def thread_limit(n):
    """Within the block, numba's parallel kernels (``prange``, e.g. the lbvh BVH builder)
    called from this thread use at most ``n`` threads (and at most NUMBA_NUM_THREADS)."""
    previous = numba.get_num_threads()
    numba.set_num_threads(max(1, min(int(n), numba.config.NUMBA_NUM_THREADS)))
    try:
        yield
    finally:
        numba.set_num_threads(previous)


def _install():
    classes = caching.CacheImpl._locator_classes
    if not any(cls.__name__ == ContentKeyedLocator.__name__ for cls in classes):
        classes.insert(0, ContentKeyedLocator)


_install()
