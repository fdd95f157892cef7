"""The ``collide`` command line: parse, call the collide API, report (SPEC §1).

Exit codes: 0 success, 1 findings (--fail-on-contact, diff), 2 usage error or
bad input, 3 internal error, 130 interrupted. Data goes to stdout; logs,
warnings, progress and errors to stderr.
"""
import json
import logging
import sys
import traceback

import click

import collide
from collide import config
from collide.errors import CollideError
from collide.plot import MAX_PAIRS as PLOT_MAX_PAIRS

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


def _configure_logging():
    logger = logging.getLogger("collide")
    if not logger.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("collide: %(levelname)s: %(message)s"))
        logger.addHandler(handler)
        logger.propagate = False
    level = {-1: logging.ERROR, 0: logging.WARNING, 1: logging.INFO}.get(
        max(-1, min(1, _state["verbosity"])))
    logger.setLevel(logging.DEBUG if _state["verbosity"] > 1 else level)


def verbosity_options(command):
    command = click.option("-v", "--verbose", count=True, expose_value=False, callback=_set_verbosity,
                           help="More output on stderr (-vv for debug; tracebacks on errors).")(command)
    return click.option("-q", "--quiet", count=True, expose_value=False, callback=_set_verbosity,
                        help="Less output on stderr (no progress, no warnings).")(command)


def _progress_bar(total, label):
    """A click progress bar on stderr when it is a terminal and not quiet, else None."""
    if _state["verbosity"] < 0 or not sys.stderr.isatty():
        return None
    return click.progressbar(length=total, label=label, file=sys.stderr, show_eta=True)


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


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(collide.__version__, "--version", prog_name="collide")
def cli():
    """collide: when, where and for how long do triangle meshes touch along a motion.

    \b
    collide scan MESHES TRAJECTORY -o contacts.h5   the main job
    collide validate TRAJECTORY [MESHES]            check inputs, change nothing
    collide report CONTACTS [--format csv]          results to stdout, for pipelines
    collide diff BASELINE CONTACTS                  CI regression: same contacts or not
    collide plot CONTACTS -o timeline.png           picture of the contact intervals
    collide inspect MESHES                          mesh and BVH statistics
    """
    _configure_logging()


@cli.command()
@click.argument("meshes", type=click.Path(path_type=str))
@click.argument("trajectory", type=click.Path(path_type=str))
@click.option("-o", "--output", default="contacts.h5", show_default=True, type=click.Path(),
              help="Result file (HDF5, SPEC §4); replaced only by a complete new file.")
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
@click.option("--split", type=click.Choice(["sah", "median", "mean"]), default="sah", show_default=True,
              help="BVH split rule.")
@click.option("--leaf-size", type=click.IntRange(min=1), default=None,
              help=f"Max triangles per BVH leaf [default: {config.DEFAULT_LEAF_SIZE}].")
@click.option("--triangle-pairs", is_flag=True, help="Also write every intersecting triangle pair "
                                                    "at every frame (/triangle_pairs).")
@click.option("--frames", default=None, metavar="START:STOP", help="Analyse a frame range (Python slice).")
@click.option("--fail-on-contact", is_flag=True, help="Exit 1 if any contact is found (for CI).")
@click.option("--workers", type=click.IntRange(min=1), default=None, help="Local parallelism [default: all cores].")
@click.option("--scheduler", default=None, metavar="ADDRESS", help="Run on a Dask distributed cluster.")
@click.option("--time-tol", type=click.FloatRange(min=0, min_open=True), default=config.TIME_TOL,
              show_default=True, help="Continuous mode: tolerance of contact times, in frame intervals.")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True,
              help="Summary format on stdout.")
@verbosity_options
def scan(meshes, trajectory, output, mode, interpolation, warn_angle, split, leaf_size, triangle_pairs, frames,
         fail_on_contact, workers, scheduler, time_tol, fmt):
    """Find when, where and for how long the meshes in MESHES touch along TRAJECTORY."""
    bar = None
    state = {"done": 0}

    def progress(done, total):
        nonlocal bar
        if bar is None:
            bar = _progress_bar(total, "scanning frames")
            if bar is None:
                return
            bar.__enter__()
        bar.update(done - state["done"])
        state["done"] = done

    try:
        result = collide.scan(meshes, trajectory, mode=mode, split=split, leaf_size=leaf_size,
                              triangle_pairs=triangle_pairs, frames=frames, workers=workers,
                              scheduler=scheduler, time_tol=time_tol, interpolation=interpolation,
                              warn_angle=warn_angle, output=output, progress=progress,
                              command=" ".join(["collide"] + sys.argv[1:]))
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    _print_summary(result, output, fmt)
    if fail_on_contact and result.stats["contacts"] > 0:
        sys.exit(EXIT_FINDINGS)


def _print_summary(result, output, fmt):
    s = result.stats
    summary = {"output": str(output), "mode": result.mode, "frames": s["frames"], "objects": s["objects"],
               "contacts": s["contacts"], "pairs_in_contact": len(set(zip(result.contacts["object_a"].tolist(),
                                                                         result.contacts["object_b"].tolist()))),
               "frames_in_contact": s["frames_in_contact"], "triangle_pairs": s["triangle_pairs"],
               "seconds": {k[:-2]: round(v, 4) for k, v in s.items() if k.endswith("_s")}}
    if fmt == "json":
        click.echo(json.dumps(summary))
        return
    click.echo(f"{summary['contacts']} contact intervals between {summary['pairs_in_contact']} object pairs "
               f"({summary['frames_in_contact']} of {s['frames']} frames in contact, {s['objects']} objects, "
               f"{result.mode}) -> {output}")
    click.echo("time: " + ", ".join(f"{k} {v:.3f} s" for k, v in summary["seconds"].items()))


@cli.command()
@click.argument("trajectory", type=click.Path(path_type=str))
@click.argument("meshes", required=False, type=click.Path(path_type=str))
@verbosity_options
def validate(trajectory, meshes):
    """Check TRAJECTORY (and the MESHES folder, if given) against SPEC §2; change nothing."""
    from collide.load import load_scene, load_trajectory
    if meshes is None:
        traj = load_trajectory(trajectory)
        click.echo(f"ok: {trajectory}: {traj.time.shape[0]} frames, {len(traj.names)} objects")
        return
    scene = load_scene(meshes, trajectory)
    n_static = int(scene.static.sum())
    triangles = sum(m.faces.shape[0] for m in scene.meshes)
    click.echo(f"ok: {trajectory}: {scene.time.shape[0]} frames, {len(scene.names)} objects "
               f"({n_static} static), {len(scene.meshes)} meshes, {triangles} triangles")


@cli.command()
@click.argument("meshes", type=click.Path(path_type=str))
@click.option("--split", "splits", type=click.Choice(["sah", "median", "mean"]), multiple=True,
              help="Split rule(s) to build with [default: all three].")
@click.option("--leaf-size", type=click.IntRange(min=1), default=None, help="Max triangles per BVH leaf.")
@click.option("--format", "fmt", type=click.Choice(["table", "json"]), default="table", show_default=True)
@verbosity_options
def inspect(meshes, splits, leaf_size, fmt):
    """Mesh and BVH statistics for every mesh in MESHES, per split rule."""
    from collide.inspect import inspect_meshes
    rows = inspect_meshes(meshes, splits or ("sah", "median", "mean"), leaf_size)
    if fmt == "json":
        click.echo(json.dumps(rows, indent=1))
        return
    header = ("mesh", "triangles", "split", "nodes", "depth", "leaf min/mean/max", "SAH cost", "build ms")
    table = [header] + [(r["mesh"], str(r["triangles"]), r["split"], str(r["nodes"]), str(r["depth"]),
                         f"{r['leaf_size_min']}/{r['leaf_size_mean']:.2f}/{r['leaf_size_max']}",
                         f"{r['sah_cost']:.2f}", f"{1000 * r['build_s']:.2f}") for r in rows]
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    for row in table:
        click.echo("  ".join(c.ljust(w) if i < 3 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths))))


@cli.command()
@click.argument("contacts", type=click.Path(path_type=str))
@click.option("--format", "fmt", type=click.Choice(["table", "csv", "json", "jsonl"]), default="table",
              show_default=True, help="table for people; csv/jsonl stream a row per line; json is one document.")
@click.option("--what", type=click.Choice(["contacts", "pairs", "triangle-pairs"]), default="contacts",
              show_default=True, help="Contact intervals, a summary per object pair, or triangle pairs per frame.")
@verbosity_options
def report(contacts, fmt, what):
    """Print the contacts of a CONTACTS file (from collide scan) to stdout."""
    from collide import report as rep
    cf = collide.read_contacts(contacts)
    if what == "triangle-pairs" and cf.triangle_pairs is None:
        raise collide.InputError(contacts, "has no triangle_pairs", "a file from collide scan --triangle-pairs",
                                 dataset="triangle_pairs")
    rows = {"contacts": rep.contact_rows, "pairs": rep.pair_rows, "triangle-pairs": rep.triangle_pair_rows}[what](cf)
    fields = rep.fields(what)
    if fmt == "csv":
        _print_csv(rows, fields)
    elif fmt == "jsonl":
        for row in rows:
            click.echo(json.dumps(row))
    elif fmt == "json":
        click.echo(json.dumps({"file": contacts, "mode": cf.attrs.get("mode"), "what": what,
                               "objects": cf.objects["name"], "rows": list(rows)}, indent=1))
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
@click.argument("baseline", type=click.Path(path_type=str))
@click.argument("contacts", type=click.Path(path_type=str))
@click.option("--time-tol", type=click.FloatRange(min=0), default=1e-9, show_default=True,
              help="Largest difference of t_begin / t_end (in time units) still counted as the same.")
@verbosity_options
def diff(baseline, contacts, time_tol):
    """Compare CONTACTS with BASELINE: exit 0 when the same, 1 (listing every difference) when not.

    Pairs are matched by object names; provenance is ignored. For CI:
    collide scan ... -o contacts.h5 && collide diff baseline.h5 contacts.h5
    """
    from collide.report import diff_contacts
    differences = diff_contacts(collide.read_contacts(baseline), collide.read_contacts(contacts), time_tol)
    if not differences:
        click.echo(f"same contacts ({baseline} vs {contacts}, time tolerance {time_tol:g})")
        return
    click.echo(f"{len(differences)} differences ({baseline} -> {contacts}, time tolerance {time_tol:g}):")
    for d in differences:
        click.echo("  " + d.describe())
    sys.exit(EXIT_FINDINGS)


@cli.command()
@click.argument("contacts", type=click.Path(path_type=str))
@click.option("-o", "--output", default="timeline.png", show_default=True, type=click.Path(),
              help="PNG file to write.")
@click.option("--title", default=None, help="Plot title.")
@click.option("--max-pairs", type=click.IntRange(min=1), default=PLOT_MAX_PAIRS, show_default=True,
              help="Draw at most this many object pairs (those that touch first).")
@verbosity_options
def plot(contacts, output, title, max_pairs):
    """Draw the contact intervals of CONTACTS over time, one row per object pair (PNG)."""
    from collide.plot import plot_timeline
    plot_timeline(collide.read_contacts(contacts), output, title, max_pairs)
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


# --- entry point ------------------------------------------------------------------------------

def main(argv=None):
    """Run the CLI and map outcomes to SPEC §1 exit codes."""
    try:
        cli.main(args=argv, prog_name="collide", standalone_mode=False)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except click.UsageError as exc:  # bad command line: one line, exit 2
        command = exc.ctx.command_path if exc.ctx is not None else "collide"
        message = " ".join(exc.format_message().split()).rstrip(".")
        click.echo(f"collide: error: {message}; see '{command} --help'", err=True)
        sys.exit(EXIT_BAD_INPUT)
    except click.ClickException as exc:  # other click errors (file arguments): exit 2
        click.echo(f"collide: error: {' '.join(exc.format_message().split())}", err=True)
        sys.exit(EXIT_BAD_INPUT if exc.exit_code in (1, 2) else exc.exit_code)
    except (KeyboardInterrupt, click.exceptions.Abort):
        click.echo("collide: interrupted", err=True)
        sys.exit(EXIT_INTERRUPTED)
    except CollideError as exc:
        click.echo(f"collide: error: {exc}", err=True)
        sys.exit(EXIT_BAD_INPUT)
    except BrokenPipeError:
        _silence_broken_pipe()
        sys.exit(0)
    except SystemExit:
        raise
    except Exception as exc:
        if _state["verbosity"] > 0:
            traceback.print_exc()
        click.echo(f"collide: internal error: {type(exc).__name__}: {exc} (run with -v for a traceback)",
                   err=True)
        sys.exit(EXIT_INTERNAL)
    sys.exit(0)


def _silence_broken_pipe():
    """After the reader of stdout went away (``| head``), stop Python's exit-time flush error."""
    import os
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except OSError:
        pass


if __name__ == "__main__":
    main()
