"""Contact tables: column layouts of the output and kernel rows -> contact intervals.

Rows are grouped by sorting (a stable merge sort in the kernel that merges them into
intervals, merge_contacts; numpy lexsort elsewhere), never by scanning per object pair.
"""
from typing import NamedTuple

import numpy as np

from .jit import njit, njit_entry
from .rows import (
    HIT_A,
    HIT_B,
    HIT_FRAME,
    HIT_SMALLEST,
    HIT_TRI_A,
    HIT_TRI_B,
    HIT_WIDTH,
    SWEPT_A,
    SWEPT_B,
    SWEPT_STEP,
    SWEPT_TRI_A,
    SWEPT_TRI_B,
    SWEPT_WIDTH,
    T_BEGIN,
    T_END,
    TIMES_WIDTH,
)

#: contacts/ columns, in file order: name -> dtype
CONTACT_COLUMNS = {
    "object_a": np.int32, "object_b": np.int32,
    "t_begin": np.float64, "t_end": np.float64,
    "frame_begin": np.int64, "frame_end": np.int64,
    "kind": np.uint8,
    "tri_a": np.int32, "tri_b": np.int32,
    "point_x": np.float64, "point_y": np.float64, "point_z": np.float64,
}

#: triangle_pairs/ columns
TRIANGLE_PAIR_COLUMNS = {
    "frame": np.int64, "object_a": np.int32, "object_b": np.int32,
    "tri_a": np.int32, "tri_b": np.int32,
}

#: meaning of contacts/kind (stored as the dataset's ``labels`` attribute)
KIND_LABELS = {0: "frame", 1: "swept"}
KIND_FRAME = 0
KIND_SWEPT = 1


def columns_from_rows(rows, layout):
    """Dict of 1-D columns (typed per ``layout``) from a (n, len(layout)) array."""
    rows = np.asarray(rows).reshape(-1, len(layout))
    return {name: rows[:, k].astype(dtype) for k, (name, dtype) in enumerate(layout.items())}


def sort_columns(columns, keys):
    """Sort a dict of equal-length columns by ``keys`` (first key most significant)."""
    order = np.lexsort([columns[k] for k in reversed(keys)])
    return {name: col[order] for name, col in columns.items()}


class Where(NamedTuple):
    """Each contact's first moment (for its point) and where its triangle pair came from."""
    step: np.ndarray      #: int64 (E,) frame (discrete) or step (continuous) index
    u: np.ndarray            #: float64 (E,) fraction of the step (0: the frame itself)
    first_found: np.ndarray  #: bool (E,) (tri_a, tri_b) is a frame hit's pair, maybe not the smallest


def intervals_from_hits(hits, times):
    """Discrete contact intervals from frame hits.

    hits int64 (H, HIT_WIDTH): frame hits (rows.py).
    times float64 (T,) analysed frame times.
    Returns (columns, where): contact columns sorted by (object_a, object_b, t_begin),
    one row per maximal run of consecutive frames of one object pair (points NaN, for
    the caller to fill), and a Where: the contact's first frame (u = 0), whether its
    (tri_a, tri_b) may be the first found rather than the smallest (HIT_SMALLEST).
    """
    return _merged(np.zeros((0, SWEPT_WIDTH), np.int64), np.zeros((0, TIMES_WIDTH)), hits, times, True)


def intervals_from_steps(ids, fractions, hits, times):
    """Continuous contact intervals.

    ids int64 (R, SWEPT_WIDTH), fractions float64 (R, TIMES_WIDTH): swept contacts
    (rows.py; fractions u in [0, 1] of the step from frame k to k+1), from
    swept.scan_intervals. hits int64 (H, HIT_WIDTH): exact contacts at frame poses,
    as for intervals_from_hits.
    Everything is merged per object pair into maximal intervals: sorted by begin, an
    item starts a new interval when it begins after every earlier item of its pair has
    ended. kind is 0 when a frame pose inside the interval shows the contact, 1 when
    only the swept test saw it. The triangle pair and first moment are those of the
    interval's first item (frame hits before swept items at the same time, then the
    smallest pair). Returns (columns, where) as intervals_from_hits.
    """
    return _merged(ids, fractions, hits, times, False)


def _merged(ids, fractions, hits, times, frame_runs):
    """(columns, where) of merge_contacts' intervals; points NaN, for the caller to fill."""
    ids = np.ascontiguousarray(ids, dtype=np.int64).reshape(-1, SWEPT_WIDTH)
    fractions = np.ascontiguousarray(fractions, dtype=np.float64).reshape(-1, TIMES_WIDTH)
    hits = np.ascontiguousarray(hits, dtype=np.int64).reshape(-1, HIT_WIDTH)
    times = np.ascontiguousarray(times, dtype=np.float64)
    a, b, t_begin, t_end, frame_begin, frame_end, kind, tri_a, tri_b, step, u, first_found = merge_contacts(
        ids, fractions, hits, times, frame_runs)
    values = {"object_a": a, "object_b": b, "t_begin": t_begin, "t_end": t_end, "frame_begin": frame_begin,
              "frame_end": frame_end, "kind": kind, "tri_a": tri_a, "tri_b": tri_b}
    columns = {name: values[name].astype(dtype, copy=False) if name in values else np.full(a.shape[0], np.nan)
               for name, dtype in CONTACT_COLUMNS.items()}
    return columns, Where(step, u, first_found)


@njit_entry
def merge_contacts(ids, fractions, hits, times, frame_runs):
    """intervals_from_steps' (frame_runs False) and intervals_from_hits' (frame_runs True,
    no swept rows) merge in one kernel (a short scan's post-processing was mostly the
    fixed cost of some fifty numpy calls): the items (swept rows, then frame hits) in the
    order of _merge_order, each object pair's run cut where an item begins after every
    earlier one has ended (frame_runs: where a frame is not the one after the last).
    Returns, per interval (E,): object_a, object_b int64, t_begin, t_end float64,
    frame_begin, frame_end int64, kind uint8, tri_a, tri_b, step int64, u float64
    (fraction of the step of the first item), first_found bool."""
    a, b, t0, t1, is_frame, tri_a, tri_b, step, u, first_found = _merge_items(ids, fractions, hits, times)
    order = _merge_order(a, b, t0, is_frame, tri_a, tri_b)
    starts = _interval_starts(order, a, b, t0, t1, step, frame_runs)
    first = order[starts]  # each interval's first item
    t_end, kind = _interval_ends(order, starts, t1, is_frame)
    t_begin = t0[first]
    return (a[first], b[first], t_begin, t_end, _frames_of_times(times, t_begin), _frames_of_times(times, t_end),
            kind, tri_a[first], tri_b[first], step[first], u[first], first_found[first])


@njit(cache=True)
def _merge_items(ids, fractions, hits, times):
    """The items to merge, swept rows then frame hits, as arrays (n,): a, b, t0, t1 (their
    begin and end times, float64), is_frame, tri_a, tri_b, step (frame for a hit), u
    (fraction of the step at t0), first_found (a hit's pair may be the first found)."""
    n_swept = ids.shape[0]
    n = n_swept + hits.shape[0]
    a = np.empty(n, np.int64)
    b = np.empty(n, np.int64)
    tri_a = np.empty(n, np.int64)
    tri_b = np.empty(n, np.int64)
    step = np.empty(n, np.int64)
    t0 = np.empty(n)
    t1 = np.empty(n)
    u = np.empty(n)
    is_frame = np.empty(n, np.bool_)
    first_found = np.empty(n, np.bool_)
    for r in range(n_swept):
        a[r], b[r], step[r] = ids[r, SWEPT_A], ids[r, SWEPT_B], ids[r, SWEPT_STEP]
        tri_a[r], tri_b[r] = ids[r, SWEPT_TRI_A], ids[r, SWEPT_TRI_B]
        u[r] = fractions[r, T_BEGIN]
        t0[r] = _step_time(times, step[r], fractions[r, T_BEGIN], -np.inf)
        t1[r] = _step_time(times, step[r], fractions[r, T_END], np.inf)
        is_frame[r] = False
        first_found[r] = False
    for h in range(hits.shape[0]):
        r = n_swept + h
        a[r], b[r], step[r] = hits[h, HIT_A], hits[h, HIT_B], hits[h, HIT_FRAME]
        tri_a[r], tri_b[r] = hits[h, HIT_TRI_A], hits[h, HIT_TRI_B]
        u[r] = 0.0
        t0[r] = t1[r] = times[step[r]]
        is_frame[r] = True
        first_found[r] = hits[h, HIT_SMALLEST] == 0
    return a, b, t0, t1, is_frame, tri_a, tri_b, step, u, first_found


@njit(cache=True)
def _interval_starts(order, a, b, t0, t1, step, frame_runs):
    """bool (n,): item order[k] begins an interval, being the first of its object pair or
    beginning after every earlier item of the pair has ended (frame_runs: at a frame that
    is not the one after the last item's)."""
    n = order.shape[0]
    starts = np.empty(n, np.bool_)
    reach = -np.inf  # the latest end so far within the pair
    for k in range(n):
        r = order[k]
        if k == 0 or a[r] != a[order[k - 1]] or b[r] != b[order[k - 1]]:
            starts[k] = True
        elif frame_runs:
            starts[k] = step[r] != step[order[k - 1]] + 1
        else:
            starts[k] = t0[r] > reach
        reach = t1[r] if starts[k] else max(reach, t1[r])
    return starts


@njit(cache=True)
def _interval_ends(order, starts, t1, is_frame):
    """Each interval's end (the latest t1 of its items) and kind (KIND_FRAME when one of
    them is a frame hit, else KIND_SWEPT): float64 (E,), uint8 (E,)."""
    t_end = np.empty(np.count_nonzero(starts))
    kind = np.empty(t_end.shape[0], np.uint8)
    e = -1
    for k in range(order.shape[0]):
        r = order[k]
        if starts[k]:
            e += 1
            t_end[e] = t1[r]
            kind[e] = KIND_FRAME if is_frame[r] else KIND_SWEPT
        else:
            t_end[e] = max(t_end[e], t1[r])
            if is_frame[r]:
                kind[e] = KIND_FRAME
    return t_end, kind


@njit(cache=True)
def _step_time(times, step, u, direction):
    """Absolute time of fraction u of step ``step`` (frame step -> step + 1): exact at u = 0
    and 1, otherwise times[step] + u (times[step + 1] - times[step]) moved one float toward
    ``direction`` (-inf for a begin, inf for an end), the conservative side of its rounding."""
    after = times[min(step + 1, times.shape[0] - 1)]
    if u <= 0.0:
        return times[step]
    if u >= 1.0:
        return after
    return np.nextafter(times[step] + u * (after - times[step]), direction)


@njit(cache=True)
def _frames_of_times(times, t):
    """int64 (E,): for each float64 t[e], the k with times[k] <= t[e] < times[k + 1] (times
    sorted), the first frame before times[0], the last from times[-1] on; by bisection."""
    out = np.empty(t.shape[0], np.int64)
    for e in range(t.shape[0]):
        lo, hi = 0, times.shape[0]  # the first index whose time is after t[e] lies in [lo, hi]
        while lo < hi:
            mid = (lo + hi) // 2
            if times[mid] <= t[e]:
                lo = mid + 1
            else:
                hi = mid
        out[e] = min(max(lo - 1, 0), times.shape[0] - 1)
    return out


@njit(cache=True)
def _merge_order(a, b, t0, is_frame, tri_a, tri_b):
    """int64 indices sorting rows by (a, b, t0, frame hits first, tri_a, tri_b): the order
    of np.lexsort of the six keys (stable: equal rows keep their input order). A
    bottom-up merge sort of its own (numba's sorts took seconds to compile)."""
    n = a.shape[0]
    order = np.arange(n)
    spare = np.empty(n, np.int64)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j = lo, mid
            for k in range(lo, hi):  # the left row first unless the right one comes strictly before it
                if j < hi and (i >= mid or _comes_before(order[j], order[i], a, b, t0, is_frame, tri_a, tri_b)):
                    spare[k] = order[j]
                    j += 1
                else:
                    spare[k] = order[i]
                    i += 1
        order, spare = spare, order
        width *= 2
    return order


@njit(cache=True, inline="always")
def _comes_before(i, j, a, b, t0, is_frame, tri_a, tri_b):
    """Row i comes strictly before row j by (a, b, t0, frame hits first, tri_a, tri_b)."""
    if a[i] != a[j]:
        return a[i] < a[j]
    if b[i] != b[j]:
        return b[i] < b[j]
    if t0[i] != t0[j]:
        return t0[i] < t0[j]
    if is_frame[i] != is_frame[j]:
        return is_frame[i]
    if tri_a[i] != tri_a[j]:
        return tri_a[i] < tri_a[j]
    return tri_b[i] < tri_b[j]
