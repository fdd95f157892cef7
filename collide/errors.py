"""Exceptions that the command line turns into exit codes, and the escaping of
text (file names, dataset names) that goes into one-line messages."""


def escape_text(text):
    """``text`` (str) with every non-printable character written as an escape, so a
    message stays on one line and cannot drive the terminal: newline -> ``\\n``, tab
    -> ``\\t``, other control or format characters -> ``\\xNN`` / ``\\uNNNN``, and
    undecodable bytes of a file name (surrogate escapes) -> ``\\xNN``. Spaces stay."""
    text = str(text)
    if text.isprintable():
        return text
    return "".join(_escape_char(c) for c in text)


_NAMED_ESCAPES = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _escape_char(c):
    if c.isprintable() or c == " ":
        return c
    if c in _NAMED_ESCAPES:
        return _NAMED_ESCAPES[c]
    code = ord(c)
    if 0xDC80 <= code <= 0xDCFF:  # an undecodable byte of a file name (os.fsdecode)
        return f"\\x{code - 0xDC00:02x}"
    if code < 0x100:
        return f"\\x{code:02x}"
    return f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


class CollideError(Exception):
    """Base class of collide's own errors."""


class InputError(CollideError):
    """Bad input: exit code 2.

    The message reads ``<file>[:<dataset>]: <problem>; expected <what>``, on one
    line (control characters in any part are escaped).
    """

    def __init__(self, file, problem, expected=None, dataset=None):
        self.file = str(file)
        self.dataset = dataset
        self.problem = problem
        self.expected = expected
        where = escape_text(self.file) if dataset is None else f"{escape_text(self.file)}:{escape_text(dataset)}"
        text = f"{where}: {escape_text(problem)}"
        if expected:
            text += f"; expected {escape_text(expected)}"
        super().__init__(text)


class UsageError(CollideError):
    """A valid input asked for something collide cannot do: exit code 2."""


class Terminated(BaseException):
    """The process was asked to stop (SIGTERM, SIGHUP): like KeyboardInterrupt, it
    unwinds everything (temporary files are removed) and the command line exits
    with 128 + the signal number. Not an Exception, so ``except Exception`` does
    not swallow it."""

    def __init__(self, signum):
        super().__init__(f"terminated by signal {signum}")
        self.signum = signum


def stop_request(error):
    """The stop request (KeyboardInterrupt, Terminated) hidden in ``error``, or None.

    A signal that arrives while a numba kernel runs in the main thread is handled by
    Python as the kernel's result is converted back to Python objects; numba then
    reports "returned a result with an exception set" (a SystemError) with the
    handler's exception at the end of its chain of causes (each Python call made while
    converting adds a SystemError). The stop request is what the run must unwind with."""
    cause = error
    while isinstance(cause, SystemError):
        cause = cause.__cause__
    return cause if isinstance(cause, (KeyboardInterrupt, Terminated)) else None
