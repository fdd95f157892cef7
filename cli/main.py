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

@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(collide.__version__, "--version", prog_name="collide")
def cli():
    """collide: when, where and for how long do triangle meshes touch along a motion.

    \b
    collide scan MESHES TRAJECTORY -o contacts.h5   the main job
    collide validate TRAJECTORY [MESHES]            check inputs, change nothing
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
def scan(meshes, trajectory, output, mode, split, leaf_size, triangle_pairs, frames, fail_on_contact,
         workers, scheduler, time_tol, fmt):
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
                              scheduler=scheduler, time_tol=time_tol, output=output, progress=progress,
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


# --- entry point ------------------------------------------------------------------------------

def main(argv=None):
    """Run the CLI and map outcomes to SPEC §1 exit codes."""
    try:
        cli.main(args=argv, prog_name="collide", standalone_mode=False)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except click.ClickException as exc:  # usage errors: click's own message, exit 2
        exc.show()
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
