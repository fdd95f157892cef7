"""Truthful start-up messages: say so when numba really compiles collide's kernels.

The first run on a machine (or after collide changed, or with a new numba cache folder)
compiles the numba kernels, which takes a minute or two with no other sign of life;
later runs load them from numba's cache in a fraction of a second. ``compile_notice``
listens to numba's own compile events (``numba.core.event``, kind ``"numba:compile"``)
while a scan prepares its kernels, so the notice appears exactly when numba compiles,
never on a warm run however slow the machine:

* by default (library use): one log line (``collide`` logger, WARNING) when
  compiling starts;
* after ``report_to(stream)`` (the command line, stderr not a terminal): that line
  written to ``stream`` without a level, so that a CI log explains a slow first run;
* after ``report_to(stream, live=True)`` (the command line on a terminal): one line
  kept up to date in place, naming the kernel being compiled, "n of m" (m: the
  top-level kernels given to ``compile_notice``) and the seconds so far, ended by a
  line saying how long compiling took.

``cache_folder()`` tells where numba keeps (and looks for) collide's compiled kernels.
Imports numba only when called.
"""
import logging
import shutil
import threading
import time
from contextlib import contextmanager, nullcontext

from .errors import escape_text

log = logging.getLogger("collide")

NOTICE = ("compiling collide's numba kernels for this machine (first run only: a minute or two; "
          "later runs load them from numba's cache{where})")

_settings = {"stream": None, "live": False}


def report_to(stream=None, live=False):
    """Where compile notices go: None, the ``collide`` log (the default); else one line
    on ``stream``, or with ``live`` (a terminal) a progress line kept up to date."""
    _settings["stream"], _settings["live"] = stream, bool(live and stream is not None)


def _cache_path(dispatcher):
    """The folder numba caches ``dispatcher`` in (None: not cached, or unknown)."""
    try:
        return dispatcher.stats.cache_path
    except AttributeError:
        return None


def kernel_name(dispatcher):
    """``module.function`` of a numba dispatcher (module without its package)."""
    func = getattr(dispatcher, "py_func", None)
    if func is None:
        return str(dispatcher)
    return f"{func.__module__.rpartition('.')[2]}.{func.__qualname__}"


def compile_notice(kernels):
    """Context manager: while its body runs, announce numba compiling in this thread
    (nothing when every kernel loads from the cache). ``kernels``: the top-level
    dispatchers the body prepares, counted as "n of m" in the progress line."""
    try:
        from numba.core import event
    except ImportError:  # a numba without the event API: no notice rather than a wrong one
        return nullcontext()
    return _notice(event, list(kernels), _settings["stream"], _settings["live"])


@contextmanager
def _notice(event, kernels, stream, live):
    folder = next((_cache_path(k) for k in kernels if _cache_path(k)), None)
    notice = NOTICE.format(where=f" in {folder}" if folder else "")
    if stream is None:
        report = _LogReport(notice)
    else:
        report = _TerminalReport(stream, len(kernels)) if live else _LineReport(notice, stream)
    listener = _listener_class(event)(kernels, report)
    try:
        with event.install_listener("numba:compile", listener):
            yield
    except BaseException:
        report.close(success=False)
        raise
    report.close(success=True)


def announce(text):
    """Say ``text`` where compile notices go (see report_to): the collide log, or a line
    on the stream."""
    stream = _settings["stream"]
    if stream is None:
        log.warning("%s", text)
        return
    try:
        stream.write(escape_text(f"collide: {text}") + "\n")
        stream.flush()
    except (OSError, ValueError):
        pass


_LISTENER = {}


def _listener_class(event):
    """The numba Listener subclass (made on first use: numba is imported only then)."""
    if "class" not in _LISTENER:
        class CompileListener(event.Listener):
            """Counts top-level compiles (nested ones are the kernels' helpers and numba's
            own overloads) of the thread that installed it."""

            def __init__(self, kernels, report):
                self.kernels = kernels
                self.report = report
                self.thread = threading.get_ident()
                self.depth = 0
                self.seen = []

            def on_start(self, event):
                if threading.get_ident() != self.thread:
                    return
                self.depth += 1
                if self.depth > 1:
                    return
                dispatcher = event.data.get("dispatcher") if isinstance(event.data, dict) else None
                index = next((i for i, k in enumerate(self.kernels) if k is dispatcher), None)
                if index is not None and index not in self.seen:
                    self.seen.append(index)
                self.report.compiling(kernel_name(dispatcher),  # n: the kernel's place in compile order
                                      self.seen.index(index) + 1 if index is not None else None)

            def on_end(self, event):
                if threading.get_ident() == self.thread:
                    self.depth = max(0, self.depth - 1)

        _LISTENER["class"] = CompileListener
    return _LISTENER["class"]


class _LogReport:
    """One log line when compiling starts."""

    def __init__(self, notice):
        self.notice = notice
        self.said = False

    def compiling(self, name, n):
        if not self.said:
            self.said = True
            log.warning("%s", self.notice)

    def close(self, success):
        pass


class _LineReport(_LogReport):
    """One line on a stream (not a terminal) when compiling starts."""

    def __init__(self, notice, stream):
        super().__init__(notice)
        self.stream = stream

    def compiling(self, name, n):
        if not self.said:
            self.said = True
            try:
                self.stream.write(escape_text(f"collide: {self.notice}") + "\n")
                self.stream.flush()
            except (OSError, ValueError):
                pass


class _TerminalReport:
    """One line on a terminal, rewritten in place (``\\r``, no escape sequences): the
    kernel being compiled, n of m, seconds so far (redrawn every second by a
    ticker thread, since one kernel can take most of a minute). Log records written
    meanwhile clear the line first, so they start at the left margin."""

    def __init__(self, stream, total):
        self.stream = stream
        self.total = total
        self.lock = threading.Lock()
        self.start = None
        self.head = self.name = ""
        self.shown = 0  # characters of the line now on screen
        self.stop = threading.Event()
        self.ticker = None
        self.handlers = []
        self.filter = _ClearLine(self)

    def compiling(self, name, n):
        with self.lock:
            if self.start is None:
                self.start = time.monotonic()
                self._watch_log()
                self.ticker = threading.Thread(target=self._tick, name="collide-compile-progress", daemon=True)
                self.ticker.start()
            self.head = (f"collide: compiling kernel {n} of {self.total} (first run only): " if n is not None
                         else "collide: compiling kernels (first run only): ")
            self.name = name
            self._draw()

    def _tick(self):
        while not self.stop.wait(1.0):
            with self.lock:
                self._draw()

    def _draw(self):
        """Write the line (call with the lock held)."""
        tail = f", {time.monotonic() - self.start:.0f} s"
        width = shutil.get_terminal_size((80, 24)).columns - 1  # never wrap: \r redraws one row
        room = max(12, width - len(self.head) - len(tail))
        name = self.name if len(self.name) <= room else "..." + self.name[-(room - 3):]
        line = self.head + name + tail
        self._write("\r" + line.ljust(self.shown))
        self.shown = len(line)

    def clear(self):
        with self.lock:
            if self.shown:
                self._write("\r" + " " * self.shown + "\r")
                self.shown = 0

    def _write(self, text):
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):  # the terminal went away: nothing to show it on
            pass

    def _watch_log(self):
        """Clear the line before each collide log record (warnings of the scan)."""
        self.handlers = [h for h in logging.getLogger("collide").handlers if self.filter not in h.filters]
        for handler in self.handlers:
            handler.addFilter(self.filter)

    def close(self, success):
        if self.start is None:
            return  # nothing compiled: nothing was shown
        self.stop.set()
        if self.ticker is not None:
            self.ticker.join()
        for handler in self.handlers:
            handler.removeFilter(self.filter)
        self.clear()
        if success:
            self._write(f"collide: compiled numba kernels in {time.monotonic() - self.start:.0f} s "
                        "(later runs load them from numba's cache)\n")


class _ClearLine(logging.Filter):
    def __init__(self, report):
        super().__init__()
        self.report = report

    def filter(self, record):
        self.report.clear()
        return True


# --- where numba keeps the compiled kernels ---------------------------------------------------

_LOCATOR_WORDS = {
    "ContentKeyedLocator": "collide's kernel cache, one folder per collide source (COLLIDE_KERNEL_CACHE_DIR, "
                           "else NUMBA_CACHE_DIR/collide-kernels, else kernels/ in collide's cache folder)",
    "UserProvidedCacheLocator": "NUMBA_CACHE_DIR",
    "InTreeCacheLocator": "next to collide's source files",
    "UserWideCacheLocator": "numba's per-user cache: collide's own folder is not writable",
}


def cache_folder():
    """(folder, why) of numba's cache of collide's kernels, as numba itself chose it for
    them (the locator of a cached kernel): ``NUMBA_CACHE_DIR/collide_<hash>`` when that is
    set, else ``__pycache__`` beside collide's modules when writable (an editable install:
    the source tree; an installed one: site-packages), else numba's per-user cache folder
    (``~/.cache/numba/collide_<hash>``). ``why`` may be empty. Imports numba."""
    from .closest import contact_point  # a cached kernel; all of collide's share one folder
    folder = _cache_path(contact_point)
    try:
        locator = type(contact_point._cache._impl.locator).__name__.lstrip("_")
    except AttributeError:  # numba's internals moved: the folder is still right
        locator = ""
    return folder, _LOCATOR_WORDS.get(locator, "")
