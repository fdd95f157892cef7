"""The ``collide`` command line: parse, call the collide API, report.

Exit codes: 0 success, 1 findings (--fail-on-contact, diff), 2 usage error or
bad input, 3 internal error, 130 interrupted (Ctrl-C), 128 + N for signal N
(143 SIGTERM, 129 SIGHUP). Data goes to stdout; logs, warnings, progress and
errors to stderr.
"""
import gc
import os
import signal
import sys


def _stop_quietly(signum, frame):
    """A stop signal while nothing needs cleaning up (modules still loading, or the
    work is done): say so and end at once, without a traceback."""
    message = "interrupted" if signum == signal.SIGINT else f"terminated by {signal.Signals(signum).name}"
    os.write(2, f"collide: {message}\n".encode())
    os._exit(128 + signum)


def _running_as_program():
    """True when this module runs as the collide program (console script or
    ``python -m collide_cli.main``), not when other code imports it."""
    program = os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else ""
    return __name__ == "__main__" or program in ("collide", "collide.exe")


_STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
_AS_PROGRAM = _running_as_program()
# Before any other import (click here; numpy, h5py, numba once a command runs, where main's
# handlers take over): Ctrl-C while starting up gives no traceback.
if _AS_PROGRAM:
    for _signum in _STOP_SIGNALS:
        if signal.getsignal(_signum) in (signal.default_int_handler, signal.SIG_DFL):
            signal.signal(_signum, _stop_quietly)
    # Starting up creates hundreds of thousands of objects that live as long as the process
    # (click here; numpy, numba, h5py and trimesh once a command runs), which the garbage
    # collector would go through again and again while they are made: 0.1-0.2 s of a scan.
    # It runs again, leaving them out, once the engine is imported (_engine_imported).
    gc.disable()
    # numba colours its error messages through colorama when installed, which then writes a
    # colour reset to standard output at exit (into pipes that a terminal records): no colours
    os.environ.setdefault("NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING", "1")
    # numpy's OpenBLAS starts a thread per core as it loads, each spinning about 0.1 s of CPU
    # before it sleeps, though collide's work runs in numba's kernels and needs no BLAS (0.13 s
    # of CPU per run on two cores, taken from whatever else runs: parallel jobs, CI). Unless
    # the user set it, one thread: the caller's.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import logging  # noqa: E402
import math  # noqa: E402
import threading  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402

import click  # noqa: E402

# Only light modules here: ``collide --help``, ``--version`` and shell completion must
# start quickly, so numpy, numba, h5py, trimesh, matplotlib and scipy are imported
# inside the commands that use them (``collide`` itself imports its engine lazily).
import collide  # noqa: E402
from collide import config  # noqa: E402
from collide.errors import CollideError, Terminated, escape_text, stop_request  # noqa: E402
from collide.files import format_size, memory_limit, parse_size  # noqa: E402

EXIT_FINDINGS = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3
EXIT_INTERRUPTED = 130

_state = {"verbosity": 0}


# --- shared options ----------------------------------------------------------------------

def _set_verbosity(ctx, param, value):
    if value:
        _state["verbosity"] += value if param.name == "verbose" else -value
        _configure_logging()
    return value


class _OneLineFormatter(logging.Formatter):
    """collide's log lines: control characters in names and paths are escaped; on a
    terminal, a status line in progress (scan's stages) is cleared first."""

    def format(self, record):
        text = escape_text(super().format(record))
        return "\r\033[K" + text if sys.stderr.isatty() else text


#: log level of notes (facts shown by default that are not warnings; collide.pipeline.NOTE)
NOTE = 25
logging.addLevelName(NOTE, "note")


def _configure_logging():
    """collide's log on stderr at the -q/-v level; other libraries' logs (trimesh,
    matplotlib, ...) only with -vv, never Python's bare last-resort output."""
    logger = logging.getLogger("collide")
    if not logger.handlers:
        handler = _StderrHandler()
        handler.setFormatter(_OneLineFormatter("collide: %(levelname)s: %(message)s"))
        logger.addHandler(handler)
        logger.propagate = False
        root = logging.getLogger()
        root.addHandler(logging.NullHandler())
        _state["library_handler"] = handler
    level = {-1: logging.ERROR, 0: NOTE, 1: logging.INFO}.get(
        max(-1, min(1, _state["verbosity"])))
    logger.setLevel(logging.DEBUG if _state["verbosity"] > 1 else level)
    root = logging.getLogger()
    handler = _state.get("library_handler")
    if _state["verbosity"] > 1 and handler is not None and handler not in root.handlers:
        root.addHandler(handler)
        root.setLevel(logging.DEBUG)
    elif _state["verbosity"] <= 1 and handler in root.handlers:
        root.removeHandler(handler)


class _StderrHandler(logging.StreamHandler):
    """A log handler writing to whatever ``sys.stderr`` is when a line is logged (as
    click.echo does), so that a caller redirecting stderr around ``main`` gets the log
    lines too."""

    def __init__(self):
        super().__init__(sys.stderr)

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):
        pass


def _warning_to_log(message, category, filename, lineno, file=None, line=None):
    """Python warnings (numpy floating-point warnings, library deprecations) go to the
    debug log (-vv), never bare onto stderr."""
    logging.getLogger("collide").debug("%s: %s (%s:%s)", category.__name__, message, filename, lineno)


def _unraisable(info):
    """Exceptions Python cannot raise (in finalizers, HDF5 callbacks): an interrupt is
    sent again so that it is not lost; anything else goes to the debug log instead
    of an "Exception ignored" traceback."""
    exc = info.exc_value
    if isinstance(exc, (KeyboardInterrupt, Terminated)):
        signum = exc.signum if isinstance(exc, Terminated) else signal.SIGINT
        threading.Thread(target=os.kill, args=(os.getpid(), signum), daemon=True).start()
        return
    logging.getLogger("collide").debug("ignored %s in %r: %s", type(exc).__name__, info.object, exc)


def _terminate(signum, frame):
    """Ctrl-C, SIGTERM, SIGHUP during a command: unwind it (see main)."""
    raise Terminated(signum)


def verbosity_options(command):
    command = click.option("-v", "--verbose", count=True, expose_value=False, callback=_set_verbosity,
                           help="More output on stderr (-vv for debug; tracebacks on errors).")(command)
    return click.option("-q", "--quiet", count=True, expose_value=False, callback=_set_verbosity,
                        help="Less output on stderr (no progress, no warnings).")(command)


#: steps of scan's progress bar (its work units are weighted by cost, not counted)
_BAR_STEPS = 1000


def _progress_bar(total, label):
    """A click progress bar on stderr when it is a terminal and not quiet, else None."""
    if _state["verbosity"] < 0 or not sys.stderr.isatty():
        return None
    return click.progressbar(length=total, label=label, file=sys.stderr, show_eta=True)


class _ByteSize(click.ParamType):
    """A memory size: bytes, or with a K/M/G/T suffix (powers of 1024), e.g. 4G, 512M."""
    name = "SIZE"

    def convert(self, value, param, ctx):
        try:
            return parse_size(value)
        except ValueError:
            self.fail(f"{value!r} is not a size; expected a positive size such as 4G, 512M or 1500000000",
                      param, ctx)


class _NonEmptyPath(click.Path):
    """A path argument (str, not checked here: collide's own checks say what is wrong
    with it); only the empty string is refused (it would mean the current folder)."""

    def __init__(self):
        super().__init__(path_type=str)

    def convert(self, value, param, ctx):
        if isinstance(value, str) and value == "":
            self.fail("the path is empty", param, ctx)
        return super().convert(value, param, ctx)


PATH = _NonEmptyPath()


class _FiniteFloat(click.FloatRange):
    """A FloatRange that refuses nan and infinities."""

    def convert(self, value, param, ctx):
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number; expected a number in {self._describe_range()}",
                      param, ctx)
        return number


def memory_option(command):
    """Add --max-memory (bytes, None = the default fraction of this machine's memory)."""
    default = memory_limit()
    shown = (f"{format_size(default)}, {config.MAX_MEMORY_FRACTION:.0%} of this machine's memory" if default
             else "no limit")
    return click.option("--max-memory", type=_ByteSize(), default=None, metavar="SIZE",
                        help="Refuse inputs whose declared sizes need more memory than this "
                             f"(e.g. 4G, 512M) [default: {shown}].")(command)


def _json(value, **kwargs):
    """Standard JSON text of ``value``: NaN and infinities become null (json.dumps
    would write bare NaN, which JSON parsers reject)."""
    return json.dumps(_json_safe(value), allow_nan=False, **kwargs)


def _json_safe(value):
    """``value`` with non-finite floats replaced by None (dicts, lists, numpy scalars too)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if hasattr(value, "item") and callable(value.item):  # numpy scalars
        return _json_safe(value.item())
    return value


def _print_json_document(head, rows):
    """Print {**head, "rows": [...]} as one JSON document, a row at a time (rows may
    be a generator: the document is never held in memory)."""
    text = _json(dict(head, rows=[]), indent=1)
    cut = text.rindex("[]")
    click.echo(text[:cut] + "[", nl=False)
    count = 0
    for row in rows:
        click.echo(("\n  " if count == 0 else ",\n  ") + _json(row), nl=False)
        count += 1
    click.echo(("\n ]" if count else "]") + text[cut + 2:])


# --- commands ------------------------------------------------------------------------------

class _Group(click.Group):
    """A click group whose commands stop quietly (exit 0) when stdout's reader goes away.

    click's own handler of a closed pipe exits 1, which a pipeline would read as
    "findings" (``collide report ... | head -1``).
    """

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except BrokenPipeError:
            _silence_broken_pipe()
            sys.exit(0)


def _print_version(ctx, param, value):
    """--version: collide's version, then what it runs on (imports the engine's libraries,
    which nothing else before a command does) and where numba keeps the compiled kernels."""
    if not value or ctx.resilient_parsing:
        return
    import platform
    lines = [f"collide {collide.__version__}",
             f"Python {platform.python_version()} ({platform.python_implementation()}, {sys.executable})"]
    for name in ("numpy", "numba", "llvmlite", "trimesh", "h5py"):
        try:
            module = __import__(name)
            version = module.__version__
            if name == "h5py":
                version += f" (HDF5 {module.version.hdf5_version})"
        except Exception as exc:  # a broken install: say which, keep going
            version = f"not importable ({type(exc).__name__}: {exc})"
        lines.append(f"{name} {version}")
    try:
        from collide.jit_events import cache_folder
        folder, why = cache_folder()
        lines.append(f"numba kernel cache: {folder}" + (f" ({why})" if why else ""))
    except Exception as exc:
        lines.append(f"numba kernel cache: unknown ({type(exc).__name__}: {exc})")
    click.echo("\n".join(escape_text(line) for line in lines))
    ctx.exit()


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--version", is_flag=True, expose_value=False, is_eager=True, callback=_print_version,
              help="Show the versions of collide, Python and its libraries, and numba's kernel "
                   "cache folder, and exit.")
def cli():
    """collide: when, where and for how long do triangle meshes touch along a motion.

    \b
    collide scan MESHES TRAJECTORY -o contacts.h5   the main job
    collide validate TRAJECTORY [MESHES]            check inputs, change nothing
    collide report CONTACTS [--format csv]          results to stdout, for pipelines
    collide diff BASELINE CONTACTS                  CI regression: same contacts or not
    collide plot CONTACTS -o timeline.png           picture of the contact intervals
    collide inspect MESHES                          mesh and BVH statistics
    collide urdf ROBOT.urdf JOINTS -o traj.h5 --meshes-out DIR   robot -> meshes + trajectory
    collide warmup                                  compile the kernels for this machine now
    """
    _configure_logging()


@cli.command()
@click.argument("meshes", type=PATH)
@click.argument("trajectory", type=PATH)
@click.option("-o", "--output", default="contacts.h5", show_default=True, type=PATH,
              help="Result file (HDF5); replaced only by a complete new file, never an input file.")
@click.option("--mode", type=click.Choice(["continuous", "discrete"]), default="continuous",
              show_default=True, help="continuous: also detect contact between frames; "
                                      "discrete: frame poses only.")
@click.option("--interpolation", type=click.Choice(["screw", "linear-vertex"]), default="screw",
              show_default=True, help="Continuous mode: how objects move between frames. screw: each "
                                      "object turns and slides at a constant rate about one fixed axis "
                                      "from one pose to the next (rigid); linear-vertex: every vertex "
                                      "moves on a straight line.")
@click.option("--warn-angle", type=click.FloatRange(min=0, max=180), default=config.SCREW_WARN_DEG,
              show_default=True, metavar="DEGREES",
              help="Screw motion: warn when an object turns more than this between two frames.")
@click.option("--ignore", multiple=True, metavar="A:B",
              help="Skip the object pairs whose names match the globs A and B (either order; repeatable; "
                   "e.g. 'link_*:link_*', 'floor:*'); adds to the trajectory's filters/ignore list.")
@click.option("--only", multiple=True, metavar="A:B",
              help="Check only the object pairs matching the globs A and B (repeatable; e.g. 'gripper*:*').")
@click.option("--glob", default=None, metavar="PATTERN",
              help="Which files of MESHES are meshes (e.g. '*.stl' when each mesh comes in several formats) "
                   "[default: every file trimesh loads].")
@click.option("--split", type=click.Choice(config.SPLIT_RULES), default=config.SPLIT_RULES[0], show_default=True,
              help="BVH construction: sah (binned surface area heuristic: the best trees), median or mean "
                   "(split at the median or mean centre), lbvh (bottom-up from Morton codes, in parallel: "
                   "fastest to build, slower to query: see collide inspect's SAH cost).")
@click.option("--leaf-size", type=click.IntRange(min=1, max=config.MAX_LEAF_SIZE), default=None,
              help=f"Max triangles per BVH leaf [default: {config.DEFAULT_LEAF_SIZE}].")
@click.option("--triangle-pairs", is_flag=True, help="Also write every intersecting triangle pair "
                                                    "at every frame (/triangle_pairs).")
@click.option("--frames", default=None, metavar="START:STOP[:STEP]",
              help="Analyse a frame range (Python slice, positive step); only its frames are read.")
@click.option("--fail-on-contact", is_flag=True, help="Exit 1 if any contact is found (for CI).")
@click.option("--workers", type=click.IntRange(min=1, max=config.MAX_WORKERS), default=None,
              help="Local parallelism (threads) [default: all cores].")
@click.option("--scheduler", default=None, metavar="ADDRESS", help="Run on a Dask distributed cluster.")
@click.option("--time-tol", type=_FiniteFloat(min=0, min_open=True, max=config.MAX_TIME_TOL),
              default=config.TIME_TOL, show_default=True,
              help="Continuous mode: tolerance of contact times, in frame intervals (at most 1).")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True,
              help="Summary format on stdout.")
@click.option("--allow-external-data", is_flag=True,
              help="Follow HDF5 external links, external storage and virtual datasets of the trajectory "
                   "(they read other files; refused by default).")
@click.option("--no-cache", is_flag=True,
              help="Parse every mesh and build every BVH afresh, without reading or writing the mesh cache "
                   "(COLLIDE_CACHE_DIR; default ~/.cache/collide).")
@memory_option
@verbosity_options
def scan(meshes, trajectory, output, mode, interpolation, warn_angle, ignore, only, glob, split, leaf_size,
         triangle_pairs, frames, fail_on_contact, workers, scheduler, time_tol, fmt, allow_external_data,
         no_cache, max_memory):
    """Find when, where and for how long the meshes in MESHES touch along TRAJECTORY."""
    bar = None
    state = {"done": 0}
    live = _state["verbosity"] >= 0 and sys.stderr.isatty()

    def stage(text):
        """On a terminal, one status line that each stage overwrites (cleared by the bar)."""
        if live and bar is None:
            sys.stderr.write(f"\r\033[Kcollide: {text}...")
            sys.stderr.flush()

    def progress(done, total):
        """The scan's work so far (weighted units, see collide.scan) on a bar of 1000 steps."""
        nonlocal bar
        if bar is None:
            if live:
                sys.stderr.write("\r\033[K")
            bar = _progress_bar(_BAR_STEPS, "scanning frames and steps" if mode == "continuous" else "scanning frames")
            if bar is None:
                return
            bar.__enter__()
        position = min(_BAR_STEPS, int(_BAR_STEPS * done / total)) if total > 0 else _BAR_STEPS
        bar.update(position - state["done"])
        state["done"] = position

    run_scan = collide.scan  # imports the engine
    _engine_imported()
    from collide.jit_events import report_to
    if _state["verbosity"] >= 0:  # -q: only the log line, which -q silences
        report_to(sys.stderr, live=sys.stderr.isatty())
    try:
        result = run_scan(meshes, trajectory, mode=mode, split=split, leaf_size=leaf_size,
                          triangle_pairs=triangle_pairs, frames=frames, workers=workers,
                          scheduler=scheduler, time_tol=time_tol, interpolation=interpolation,
                          warn_angle=warn_angle, ignore=ignore, only=only, glob=glob,
                          output=output, progress=progress, stage=stage,
                          command=" ".join(["collide"] + sys.argv[1:]), max_memory=max_memory,
                          allow_external_data=allow_external_data, cache=not no_cache)
    finally:
        report_to(None)
        if bar is not None:
            bar.__exit__(None, None, None)
        elif live:
            sys.stderr.write("\r\033[K")
    _print_summary(result, output, fmt)
    if fail_on_contact and result.stats["contacts"] > 0:
        sys.exit(EXIT_FINDINGS)


def _print_summary(result, output, fmt):
    s = result.stats
    summary = {"output": str(output), "mode": result.mode, "frames": s["frames"], "objects": s["objects"],
               "contacts": s["contacts"], "pairs_in_contact": len(set(zip(result.contacts["object_a"].tolist(),
                                                                         result.contacts["object_b"].tolist()))),
               "frames_in_contact": s["frames_in_contact"], "triangle_pairs": s["triangle_pairs"],
               "static_objects": s["static_objects"], "filters": s["filters"],
               "seconds": {k[:-2]: round(v, 4) for k, v in s.items() if k.endswith("_s")}, "work": s["work"],
               "cache": s.get("cache")}
    if fmt == "json":
        click.echo(_json(summary))
        return
    click.echo(f"{summary['contacts']} contact intervals between {summary['pairs_in_contact']} object pairs "
               f"({summary['frames_in_contact']} of {s['frames']} frames in contact, {s['objects']} objects, "
               f"{result.mode}) -> {output}")
    click.echo("time: " + ", ".join(f"{k} {v:.3f} s" for k, v in summary["seconds"].items()))
    cache = s.get("cache")
    if cache is not None:
        click.echo("cache: off" if not cache["enabled"] else
                   f"cache: {cache['mesh_hits']} of {cache['mesh_hits'] + cache['mesh_misses']} meshes and "
                   f"{cache['bvh_hits']} of {cache['bvh_hits'] + cache['bvh_misses']} BVHs reused")
    logging.getLogger("collide").info("work: %s", ", ".join(f"{k} {v}" for k, v in summary["work"].items()))


@cli.command()
@click.argument("trajectory", type=PATH)
@click.argument("meshes", required=False, type=PATH)
@click.option("--allow-external-data", is_flag=True,
              help="Follow HDF5 external links, external storage and virtual datasets (refused by default).")
@memory_option
@verbosity_options
def validate(trajectory, meshes, allow_external_data, max_memory):
    """Check TRAJECTORY (and the MESHES folder, if given) as scan reads them; change nothing.

    With MESHES, the trajectory's filters/ignore patterns are matched against the objects
    too. How far objects turn between frames is checked by scan, since it depends on
    its --mode and --interpolation."""
    from collide.filters import build_filters
    from collide.load import check_trajectory, load_scene
    if meshes is None:
        traj = check_trajectory(trajectory, allow_external=allow_external_data, max_memory=max_memory)
        click.echo(f"ok: {trajectory}: {traj.time.shape[0]} frames, {len(traj.names)} objects")
        return
    scene = load_scene(meshes, trajectory, allow_external=allow_external_data, max_memory=max_memory)
    build_filters(scene.names, trajectory_ignore=scene.ignore, trajectory_path=scene.trajectory_path)
    n_static = int(scene.static.sum())
    triangles = sum(m.faces.shape[0] for m in scene.meshes)
    click.echo(f"ok: {trajectory}: {scene.time.shape[0]} frames, {len(scene.names)} objects "
               f"({n_static} static), {len(scene.meshes)} meshes, {triangles} triangles")


@cli.command()
@click.argument("meshes", type=PATH)
@click.option("--split", "splits", type=click.Choice(config.SPLIT_RULES), multiple=True,
              help=f"BVH construction rule(s) to build with (repeatable) [default: all: "
                   f"{', '.join(config.SPLIT_RULES)}].")
@click.option("--leaf-size", type=click.IntRange(min=1, max=config.MAX_LEAF_SIZE), default=None,
              help="Max triangles per BVH leaf.")
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table", show_default=True)
@verbosity_options
def inspect(meshes, splits, leaf_size, fmt):
    """Mesh and BVH statistics for every mesh in MESHES, per split rule."""
    from collide.inspect import inspect_meshes
    _engine_imported()  # inspect builds BVHs, compiling their kernels on a first run
    rows = inspect_meshes(meshes, splits or config.SPLIT_RULES, leaf_size)
    if fmt == "json":
        click.echo(_json(rows, indent=1))
        return
    header = ("mesh", "triangles", "split", "nodes", "depth", "leaf min/mean/max", "SAH cost", "build ms")
    table = [header] + [(r["mesh"], str(r["triangles"]), r["split"], str(r["nodes"]), str(r["depth"]),
                         f"{r['leaf_size_min']}/{r['leaf_size_mean']:.2f}/{r['leaf_size_max']}",
                         f"{r['sah_cost']:.2f}", f"{1000 * r['build_s']:.2f}") for r in rows]
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    for row in table:
        click.echo("  ".join(c.ljust(w) if i < 3 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths))))


@cli.command()
@click.argument("contacts", type=PATH)
@click.option("--format", "fmt", type=click.Choice(["table", "csv", "json", "jsonl"]), default="table",
              show_default=True, help="table for people; csv/jsonl stream a row per line; json is one document.")
@click.option("--what", type=click.Choice(["contacts", "pairs", "triangle-pairs"]), default="contacts",
              show_default=True, help="Contact intervals, a summary per object pair, or triangle pairs per frame.")
@memory_option
@verbosity_options
def report(contacts, fmt, what, max_memory):
    """Print the contacts of a CONTACTS file (from collide scan) to stdout."""
    from collide import report as rep
    cf = collide.read_contacts(contacts, max_memory=max_memory)
    if what == "triangle-pairs" and cf.triangle_pairs is None:
        raise collide.InputError(contacts, "has no triangle_pairs", "a file from collide scan --triangle-pairs",
                                 dataset="triangle_pairs")
    rows = {"contacts": rep.contact_rows, "pairs": rep.pair_rows, "triangle-pairs": rep.triangle_pair_rows}[what](cf)
    fields = rep.fields(what)
    if fmt == "csv":
        _print_csv(rows, fields)
    elif fmt == "jsonl":
        for row in rows:
            click.echo(_json(row))
    elif fmt == "json":
        _print_json_document({"file": contacts, "mode": cf.attrs.get("mode"), "what": what,
                              "objects": cf.objects["name"]}, rows)
    else:
        if what == "contacts":
            click.echo("contact intervals:")
        _print_table(list(rows), fields)
        if what == "contacts":
            click.echo()
            click.echo("per object pair:")
            _print_table(rep.pair_rows(cf), rep.PAIR_FIELDS)


def _print_csv(rows, fields):
    import csv
    import io
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    click.echo(buffer.getvalue(), nl=False)
    for row in rows:
        buffer.seek(0)
        buffer.truncate()
        writer.writerow(row)
        click.echo(buffer.getvalue(), nl=False)


def _format_cell(value):
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _print_table(rows, fields):
    """Aligned columns; numbers right-aligned."""
    if not rows:
        click.echo("(none)")
        return
    cells = [list(fields)] + [[_format_cell(r[f]) for f in fields] for r in rows]
    widths = [max(len(row[i]) for row in cells) for i in range(len(fields))]
    numeric = [not isinstance(rows[0][f], str) for f in fields]
    for row in cells:
        click.echo("  ".join(c.rjust(w) if num else c.ljust(w) for c, w, num in zip(row, widths, numeric)).rstrip())


@cli.command()
@click.argument("baseline", type=PATH)
@click.argument("contacts", type=PATH)
@click.option("--time-tol", type=_FiniteFloat(min=0), default=1e-9, show_default=True,
              help="Largest difference of t_begin / t_end (in time units) still counted as the same.")
@click.option("--ignore-filters", is_flag=True,
              help="Compare even when the two scans checked different object pairs (--ignore/--only/"
                   "filters/ignore); only the pairs both checked are meaningful then.")
@memory_option
@verbosity_options
def diff(baseline, contacts, time_tol, ignore_filters, max_memory):
    """Compare CONTACTS with BASELINE: exit 0 when the same, 1 (listing every difference) when not.

    Pairs are matched by object names; provenance is ignored, except that the two
    scans must have checked the same object pairs (same pair filters). For CI:
    collide scan ... -o contacts.h5 && collide diff baseline.h5 contacts.h5
    """
    from collide.report import diff_contacts, scan_filters
    before = collide.read_contacts(baseline, max_memory=max_memory)
    after = collide.read_contacts(contacts, max_memory=max_memory)
    if not ignore_filters and scan_filters(before) != scan_filters(after):
        raise collide.UsageError(f"{contacts} was scanned with pair filters {scan_filters(after)} but {baseline} "
                                 f"with {scan_filters(before)}: they checked different object pairs; expected "
                                 "files scanned with the same filters (or --ignore-filters to compare them anyway)")
    differences = diff_contacts(before, after, time_tol)
    if not differences:
        click.echo(f"same contacts ({baseline} vs {contacts}, time tolerance {time_tol:g})")
        return
    click.echo(f"{len(differences)} differences ({baseline} -> {contacts}, time tolerance {time_tol:g}):")
    for d in differences:
        click.echo("  " + d.describe())
    sys.exit(EXIT_FINDINGS)


@cli.command()
@click.argument("contacts", type=PATH)
@click.option("-o", "--output", default="timeline.png", show_default=True, type=PATH,
              help="Image file to write: .png, .pdf, .svg, .eps or .ps.")
@click.option("--title", default=None, help="Plot title.")
@click.option("--max-pairs", type=click.IntRange(min=1), default=config.PLOT_MAX_PAIRS, show_default=True,
              help="Draw at most this many object pairs (those that touch first).")
@memory_option
@verbosity_options
def plot(contacts, output, title, max_pairs, max_memory):
    """Draw the contact intervals of CONTACTS over time, one row per object pair (PNG)."""
    from collide.output import check_output_path
    from collide.plot import plot_timeline
    check_output_path(output, [contacts])  # never over the file being drawn
    plot_timeline(collide.read_contacts(contacts, max_memory=max_memory), output, title, max_pairs,
                  inputs=[contacts], source=contacts)
    click.echo(f"wrote {output}")


# --- collide urdf: robot + joint positions -> meshes folder + trajectory -----------------------

@cli.command()
@click.argument("robot", type=click.Path(path_type=str))
@click.argument("joints", type=click.Path(path_type=str))
@click.option("-o", "--output", required=True, type=click.Path(),
              help="Trajectory to write (HDF5: the links' world poses as poses/matrix, root link at "
                   "the identity; replaced only by a complete new file).")
@click.option("--meshes-out", required=True, type=click.Path(),
              help="Folder to create with one mesh per link that has geometry, in the link frame: "
                   "binary PLY with float64 vertices, named after the link.")
@click.option("--geometry", type=click.Choice(["collision", "visual"]), default="collision",
              show_default=True,
              help="Which elements make a link's mesh; a link with none of them uses the other kind.")
@click.option("--ignore-adjacent/--no-ignore-adjacent", default=True, show_default=True,
              help="Write the link pairs joined by a joint to filters/ignore (links without geometry "
                   "are skipped over).")
@click.option("--force", is_flag=True,
              help="Write into a non-empty --meshes-out (files of the same name are replaced, others kept).")
@verbosity_options
def urdf(robot, joints, output, meshes_out, geometry, ignore_adjacent, force):
    """Turn a URDF ROBOT and its JOINTS positions over time into a meshes folder and a
    trajectory for collide scan.

    \b
    JOINTS is an HDF5 file (time (T,), joints/name str (J,), joints/position (T, J))
    or a CSV file with a header: a time column and one column per joint.
    Positions are radians (revolute, continuous) or URDF lengths (prismatic); joints
    not listed stay at 0; mimic joints follow their leader. Needs pip install 'collide[urdf]'.
    """
    from collide.urdf import urdf_to_scene
    scene = urdf_to_scene(robot, joints, meshes_out, output, geometry=geometry,
                          ignore_adjacent=ignore_adjacent, force=force)
    ignored = f", {len(scene.ignore)} adjacent link pairs in filters/ignore" if ignore_adjacent else ""
    click.echo(f"robot {scene.robot!r}: {len(scene.objects)} link meshes -> {meshes_out}, "
               f"{scene.frames} frames -> {output}{ignored}")


@cli.command()
@click.option("--mode", "modes", type=click.Choice(["continuous", "discrete"]), multiple=True,
              help="Prepare the kernels of this scan mode only [default: both].")
@click.option("--split", "splits", type=click.Choice(config.SPLIT_RULES), multiple=True,
              help="Also prepare the BVH builder of this rule (sah, median and mean share one, always "
                   "prepared; lbvh has its own) [default: sah].")
@click.option("--workers", type=click.IntRange(min=1, max=config.MAX_WORKERS), default=None,
              help="Processes compiling at once [default: all cores].")
@verbosity_options
def warmup(modes, splits, workers):
    """Compile collide's numba kernels for this machine now (in parallel processes), so
    that the first scan starts at once; e.g. in a CI step or a container build. A warm
    cache makes this a fraction of a second."""
    from collide.jit import kernel_cache_dir
    from collide.warmup import warm_up
    _engine_imported()  # warmup compiles in this process too

    def progress(units, seconds):
        click.echo(f"{units}: " + ("failed (a scan compiles what it needs itself)" if seconds is None
                                   else f"{seconds:.1f} s"))
    _, seconds = warm_up(modes or ("discrete", "continuous"), workers, progress,
                         extra=("lbvh",) if "lbvh" in splits else ())
    click.echo(f"kernels ready in {seconds:.1f} s -> {kernel_cache_dir()}")


# --- entry point ------------------------------------------------------------------------------

def main(argv=None):
    """Run the CLI and exit with its code (see the module docstring).

    Ctrl-C, SIGTERM and SIGHUP unwind the command (temporary files are removed)
    and exit with 128 + the signal number (130, 143, 129), never with a traceback.
    """
    previous = _install_handlers()
    try:
        code = _run(argv)
    except Terminated as exc:  # a signal in the instant before or after the command's own handling
        code = _stopped(exc)
    finally:
        _restore_handlers(previous)
    if _AS_PROGRAM:
        _ignore_late_signals()
    sys.exit(code)


def _engine_imported():
    """As the program: the engine's modules, imported, stay for the whole run; the garbage
    collector (off while starting up, see the module top) runs again, without them
    (gc.freeze), before the scan loads its inputs (likewise before inspect and warmup,
    which may compile kernels here). The other commands are short and end with it off;
    code that calls main in its own process keeps its collector as it was."""
    if _AS_PROGRAM:
        _skip_numba_blas_probe()
        gc.freeze()
        gc.enable()


def _skip_numba_blas_probe():
    """Tell numba, before it first loads a kernel, that there is no BLAS. It probes for
    SciPy's then (importing scipy.linalg: about 0.15 s of every run where SciPy is
    installed), for np.dot and np.linalg inside compiled code, which collide's kernels do
    not use. As the program only (other code in the process may want them); left alone if
    numba has already looked or is laid out otherwise."""
    try:
        from numba.np import linalg
    except ImportError:
        return
    if "numba.np.arraymath" in sys.modules or not callable(getattr(linalg, "ensure_blas", None)):
        return

    def no_blas():
        raise ImportError("collide's kernels use no BLAS")
    linalg.ensure_blas = no_blas


def _ignore_late_signals():
    """The command has ended (its output is complete): a stop signal from now on changes
    nothing. Without this, Python's shutdown resets its signal handlers to the default,
    and a signal in that last instant would kill the finished process (exit -N)."""
    for signum in _STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)


def _install_handlers():
    """Stop signals raise Terminated; Python warnings and unraisable exceptions go to
    the debug log. Returns what was there before (for _restore_handlers)."""
    previous = {"showwarning": warnings.showwarning, "unraisablehook": sys.unraisablehook, "signals": {}}
    if threading.current_thread() is threading.main_thread():
        for signum in _STOP_SIGNALS:
            handler = signal.getsignal(signum)
            if handler is not signal.SIG_IGN and handler is not None:
                previous["signals"][signum] = signal.signal(signum, _terminate)
    warnings.showwarning = _warning_to_log
    sys.unraisablehook = _unraisable
    return previous


def _restore_handlers(previous):
    """After the command: as the program, a late stop signal just ends the process
    quietly; called from other code, the previous handlers come back.

    A stop signal that arrives while the handlers are being put back (the command has
    ended, so it is a late one) is held until they all are, then handled as one
    arriving just after: as the program by _stop_quietly, otherwise sent again to the
    restored handler."""
    late = None
    pending = list(previous["signals"].items())
    while pending:
        try:
            signum, handler = pending[0]
            signal.signal(signum, _stop_quietly if _AS_PROGRAM else handler)  # idempotent: safe to repeat
            pending.pop(0)
        except Terminated as exc:
            late = exc.signum
    if not _AS_PROGRAM:
        warnings.showwarning = previous["showwarning"]
        sys.unraisablehook = previous["unraisablehook"]
    if late is not None:
        if _AS_PROGRAM:
            _stop_quietly(late, None)
        signal.raise_signal(late)


def _error(text):
    """Print one ``collide: ...`` line on stderr (control characters escaped)."""
    click.echo(escape_text(text), err=True)


def _run(argv):
    """Run the command line; returns the exit code."""
    _state["verbosity"] = 0  # -v/-q count per run (main may be called several times)
    _configure_logging()
    if not (sys.argv[1:] if argv is None else argv) and "_COLLIDE_COMPLETE" not in os.environ:
        # no command (and not shell completion asking): say which there are, whatever click's version does
        _error(f"collide: error: no command given; expected one of {', '.join(cli.list_commands(None))} "
               "(see 'collide --help')")
        return EXIT_BAD_INPUT
    try:
        cli.main(args=argv, prog_name="collide", standalone_mode=False)
    except click.exceptions.Exit as exc:
        return exc.exit_code
    except click.UsageError as exc:  # bad command line: one line, exit 2
        command = exc.ctx.command_path if exc.ctx is not None else "collide"
        message = " ".join(exc.format_message().split()).rstrip(".")
        _error(f"collide: error: {message}; see '{command} --help'")
        return EXIT_BAD_INPUT
    except click.ClickException as exc:  # other click errors: exit 2
        _error(f"collide: error: {' '.join(exc.format_message().split()).rstrip('.')}; "
               "expected arguments as described by --help")
        return EXIT_BAD_INPUT if exc.exit_code in (1, 2) else exc.exit_code
    except (Terminated, KeyboardInterrupt, click.exceptions.Abort) as exc:
        return _stopped(exc)
    except CollideError as exc:
        _error(f"collide: error: {exc}")
        return EXIT_BAD_INPUT
    except BrokenPipeError:
        _silence_broken_pipe()
        return 0
    except SystemExit as exc:
        return exc.code
    except Exception as exc:
        if stop_request(exc) is not None:  # a signal while a kernel ran in this thread
            return _stopped(stop_request(exc))
        if _state["verbosity"] > 0:
            traceback.print_exc()
        _error(f"collide: internal error: {type(exc).__name__}: {exc} (run with -v for a traceback)")
        return EXIT_INTERNAL
    return 0


def _stopped(exc):
    """Report a stop request (Ctrl-C: KeyboardInterrupt or click's Abort; Terminated);
    returns the exit code, 128 + the signal number."""
    if isinstance(exc, Terminated) and exc.signum != signal.SIGINT:
        _error(f"collide: terminated by {signal.Signals(exc.signum).name}")
        return 128 + exc.signum
    _error("collide: interrupted")
    return EXIT_INTERRUPTED


def _silence_broken_pipe():
    """After the reader of stdout went away (``| head``), stop Python's exit-time flush error."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except OSError:
        pass


if __name__ == "__main__":
    main()
