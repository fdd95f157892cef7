"""Timeline picture of a contact file (``collide plot``): one row per object pair,
contact intervals as bars over time, swept-only contacts hatched, frame ticks.

matplotlib is optional (``pip install collide[plot]``); it is imported only here.
"""
import io
from pathlib import Path

import numpy as np

from . import config
from .errors import InputError, UsageError
from .output import write_bytes_atomic
from .report import timeline

FRAME_COLOUR = "#1f77b4"
SWEPT_COLOUR = "#d62728"
#: default limit of pairs drawn (one row each): beyond it the picture stops being readable
MAX_PAIRS = config.PLOT_MAX_PAIRS


def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise UsageError("collide plot needs matplotlib; install it with: pip install 'collide[plot]'") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _check_drawable(cf, source):
    """Refuse times beyond config.PLOT_MAX_TIME in magnitude (matplotlib cannot place them)."""
    times = np.concatenate([cf.frame_time, cf.contacts["t_begin"], cf.contacts["t_end"]])
    largest = float(np.abs(times).max()) if times.size else 0.0
    if not largest <= config.PLOT_MAX_TIME:
        raise InputError(source, f"has a time of magnitude {largest:g}, too large to draw",
                         f"times within {config.PLOT_MAX_TIME:g} of 0", dataset="frames/time")


def plot_timeline(cf, output, title=None, max_pairs=MAX_PAIRS, inputs=(), source="contacts"):
    """Draw the contact intervals of a Contacts file to an image at ``output`` (atomically;
    never over one of ``inputs``, e.g. the contacts file itself), in the format its suffix
    names (IMAGE_FORMATS; PNG without a suffix). ``source`` names the contacts file in
    messages.

    One row per object pair; with more than ``max_pairs`` pairs only the
    ``max_pairs`` that touch first are drawn (the title says so).
    """
    image_format = _image_format(output)
    _check_drawable(cf, source)
    plt = _pyplot()
    from matplotlib.patches import Patch
    rows = timeline(cf)
    labels = list(rows)
    n_pairs = len(labels)
    if n_pairs > max_pairs:
        labels = sorted(labels, key=lambda label: (min(r[0] for r in rows[label]), label))[:max_pairs]
    times = cf.frame_time
    t0, t1 = (float(times[0]), float(times[-1])) if times.size else (0.0, 1.0)
    span = max(t1 - t0, 1e-12)
    min_width = span / 400  # single-frame contacts stay visible
    height = 1.6 + 0.32 * max(len(labels), 1)
    fig, ax = plt.subplots(figsize=(11, height), dpi=110)
    for row, label in enumerate(labels):
        for begin, end, kind in rows[label]:
            swept = kind == "swept"
            width = max(end - begin, min_width)
            ax.broken_barh([(begin - (width - (end - begin)) / 2, width)], (row - 0.35, 0.7),
                           facecolors=SWEPT_COLOUR if swept else FRAME_COLOUR,
                           hatch="///" if swept else None, edgecolor="black", linewidth=0.4)
    ax.set_yticks(range(len(labels)))
    ax.set_yticklabels(labels, fontsize=8 if len(labels) > 20 else 10, parse_math=False)  # names: no $math$
    ax.set_ylim(len(labels) - 0.5 if labels else 0.5, -0.5)
    ax.set_xlim(t0 - 0.01 * span, t1 + 0.01 * span)
    if 1 < times.size <= 400:
        ax.set_xticks(times, minor=True)
        ax.tick_params(axis="x", which="minor", length=3, color="grey")
    ax.grid(axis="x", linestyle=":", alpha=0.5)
    ax.set_xlabel("time (frame ticks below the axis)")
    mode = cf.attrs.get("mode", "?")
    shown = f"{n_pairs} object pairs" if n_pairs == len(labels) else \
        f"the {len(labels)} of {n_pairs} object pairs that touch first"
    ax.set_title(title or f"{shown} in contact ({mode} mode)", fontsize=11, loc="left", parse_math=False)
    if not labels:
        ax.text(0.5, 0.5, "no contacts", transform=ax.transAxes, ha="center", va="center", fontsize=14)
    ax.legend(handles=[Patch(facecolor=FRAME_COLOUR, edgecolor="black", label="contact seen at a frame"),
                       Patch(facecolor=SWEPT_COLOUR, hatch="///", edgecolor="black",
                             label="between frames only (swept test)")],
              loc="lower right", bbox_to_anchor=(1.0, 1.0), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    output = Path(output)
    image = io.BytesIO()
    fig.savefig(image, format=image_format)
    plt.close(fig)
    write_bytes_atomic(output, image.getbuffer(), inputs)
    return output


#: image formats by file suffix (what matplotlib writes without extra packages)
IMAGE_FORMATS = ("png", "pdf", "svg", "eps", "ps")


def _image_format(output):
    """The image format of ``output`` by its suffix: png when it has none; UsageError for a
    suffix of another format."""
    suffix = Path(output).suffix.lower().lstrip(".")
    if not suffix:
        return "png"
    if suffix not in IMAGE_FORMATS:
        raise UsageError(f"-o {output}: .{suffix} is not an image format written here; expected a file name "
                         f"ending in {', '.join('.' + f for f in IMAGE_FORMATS)}")
    return suffix
