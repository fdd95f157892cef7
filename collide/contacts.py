"""Contact tables: column layouts of the output and kernel rows -> contact intervals.

Rows are grouped by sorting (numpy lexsort), never by scanning per object pair.
"""
from typing import NamedTuple

import numpy as np

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


def _contact_columns(a, b, t_begin, t_end, kind, tri_a, tri_b, times):
    """Contact columns (CONTACT_COLUMNS; points NaN for the caller to fill) of intervals
    given as arrays, already sorted by (a, b, t_begin)."""
    n = a.shape[0]
    frame_begin, frame_end = frame_of_time(times, np.stack([t_begin, t_end]))
    values = {"object_a": a, "object_b": b, "t_begin": t_begin, "t_end": t_end,
              "frame_begin": frame_begin, "frame_end": frame_end,
              "kind": kind, "tri_a": tri_a, "tri_b": tri_b,
              "point_x": np.full(n, np.nan), "point_y": np.full(n, np.nan), "point_z": np.full(n, np.nan)}
    return {name: np.asarray(values[name]).astype(dtype, copy=False) for name, dtype in CONTACT_COLUMNS.items()}


def _new_pair(a, b):
    """bool (n,): row k starts another object pair than row k - 1 (rows sorted by pair)."""
    starts = np.ones(a.shape[0], bool)
    starts[1:] = (a[1:] != a[:-1]) | (b[1:] != b[:-1])
    return starts


def intervals_from_hits(hits, times):
    """Discrete contact intervals from frame hits.

    hits int64 (H, HIT_WIDTH): frame hits (rows.py).
    times float64 (T,) analysed frame times.
    Returns (columns, where): contact columns sorted by (object_a, object_b, t_begin),
    one row per maximal run of consecutive frames of one object pair (points NaN, for
    the caller to fill), and a Where: the contact's first frame (u = 0), whether its
    (tri_a, tri_b) may be the first found rather than the smallest (HIT_SMALLEST).
    """
    hits = np.asarray(hits, dtype=np.int64).reshape(-1, HIT_WIDTH)
    hits = hits[np.lexsort((hits[:, HIT_FRAME], _pair_key(hits[:, HIT_A], hits[:, HIT_B])))]
    a, b, frame = hits[:, HIT_A], hits[:, HIT_B], hits[:, HIT_FRAME]
    starts = _new_pair(a, b)
    starts[1:] |= frame[1:] != frame[:-1] + 1
    first = np.flatnonzero(starts)
    last = np.append(first[1:] - 1, hits.shape[0] - 1) if first.size else first
    columns = _contact_columns(a[first], b[first], times[frame[first]], times[frame[last]],
                               np.full(first.size, KIND_FRAME), hits[first, HIT_TRI_A], hits[first, HIT_TRI_B], times)
    return columns, Where(frame[first], np.zeros(first.size), hits[first, HIT_SMALLEST] == 0)


def step_time(times, step, u, direction):
    """Absolute times (float64 arrays) of fractions u of steps (frame step -> step + 1):
    exact at u = 0 and 1, otherwise times[step] + u (times[step + 1] - times[step]) moved
    one float toward ``direction`` (-inf for a begin, inf for an end), the conservative
    side of its rounding. step, u and direction broadcast against each other."""
    step = np.asarray(step, dtype=np.int64)
    u = np.asarray(u, dtype=np.float64)
    after = times[np.minimum(step + 1, times.shape[0] - 1)]
    between = np.nextafter(times[step] + u * (after - times[step]), direction)
    return np.where(u <= 0.0, times[step], np.where(u >= 1.0, after, between))


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
    ids = np.asarray(ids, dtype=np.int64).reshape(-1, SWEPT_WIDTH)
    fractions = np.asarray(fractions, dtype=np.float64).reshape(-1, TIMES_WIDTH)
    hits = np.asarray(hits, dtype=np.int64).reshape(-1, HIT_WIDTH)
    # one row per item, swept contacts first, then frame hits (few numpy calls: a short
    # scan's post-processing is mostly their fixed cost)
    items = np.concatenate([ids[:, _SWEPT_ITEM], hits[:, _HIT_ITEM]])
    hit_time = times[hits[:, HIT_FRAME]]
    swept_time = step_time(times, ids[:, SWEPT_STEP, None], fractions[:, [T_BEGIN, T_END]], _OUTWARD)
    t0 = np.concatenate([swept_time[:, 0], hit_time])
    t1 = np.concatenate([swept_time[:, 1], hit_time])
    is_frame = np.arange(items.shape[0]) >= ids.shape[0]
    first_found = np.concatenate([np.zeros(ids.shape[0], bool), hits[:, HIT_SMALLEST] == 0])
    u = np.concatenate([fractions[:, T_BEGIN], np.zeros(hits.shape[0])])
    order = merge_order(items[:, 0], items[:, 1], t0, is_frame, items[:, 2], items[:, 3])
    items, t0, t1, is_frame, first_found, u = (x[order] for x in (items, t0, t1, is_frame, first_found, u))
    a, b, tri_a, tri_b, step = items.T
    new_pair = _new_pair(a, b)
    reach = _running_max_by_group(t1, np.flatnonzero(new_pair))   # latest end so far within each pair
    starts = new_pair.copy()
    starts[1:] |= t0[1:] > reach[:-1]
    first = np.flatnonzero(starts)  # an interval's items are contiguous: reduce each run
    t_end = np.maximum.reduceat(t1, first) if first.size else np.zeros(0)
    seen_at_frame = np.logical_or.reduceat(is_frame, first) if first.size else np.zeros(0, bool)
    kind = np.where(seen_at_frame, KIND_FRAME, KIND_SWEPT)
    columns = _contact_columns(a[first], b[first], t0[first], t_end, kind, tri_a[first], tri_b[first], times)
    return columns, Where(step[first], u[first], first_found[first])


#: columns of swept rows and of frame hits that make an item: a, b, tri_a, tri_b, step (frame)
_SWEPT_ITEM = [SWEPT_A, SWEPT_B, SWEPT_TRI_A, SWEPT_TRI_B, SWEPT_STEP]
_HIT_ITEM = [HIT_A, HIT_B, HIT_TRI_A, HIT_TRI_B, HIT_FRAME]
#: step_time's direction for (begin, end): each rounded outward
_OUTWARD = np.array([-np.inf, np.inf])


def merge_order(a, b, t0, is_frame, tri_a, tri_b):
    """int64 indices sorting rows by (a, b, t0, frame hits first, tri_a, tri_b): the order of
    np.lexsort of the six keys (stable), found by sorting on (a, b, t0) alone and then
    ordering only the rows that tie there by the rest. Ties are common (a frame hit and
    the swept contact that starts at its frame: nearly every row at 1000 bodies) but
    almost all come in twos, which are put in order by one vectorised comparison;
    sorting every row by every key took three times as long."""
    pair = _pair_key(a, b)
    order = np.lexsort((t0, pair))
    p_s, t_s = pair[order], t0[order]
    tied = (p_s[1:] == p_s[:-1]) & (t_s[1:] == t_s[:-1])  # row k + 1 ties with row k
    if not tied.any():
        return order
    starts = np.flatnonzero(tied & np.append(True, ~tied[:-1]))  # first row of each run of ties
    ends = np.flatnonzero(tied & np.append(~tied[1:], True)) + 1  # and its last row
    two = ends - starts == 1
    first, second = order[starts[two]], order[ends[two]]
    swap = _after(first, second, is_frame, tri_a, tri_b)
    order[starts[two][swap]], order[ends[two][swap]] = second[swap], first[swap]
    if (~two).any():  # rare: three or more rows at one moment, sorted together, run by run
        lo, hi = starts[~two], ends[~two] + 1
        at = _concatenated_ranges(lo, hi)
        run = np.repeat(np.arange(lo.size), hi - lo)
        rows = order[at]
        order[at] = rows[np.lexsort((tri_b[rows], tri_a[rows], ~is_frame[rows], run))]
    return order


def _concatenated_ranges(lo, hi):
    """int64: lo[0], ..., hi[0] - 1, then lo[1], ..., hi[1] - 1, and so on."""
    sizes = hi - lo
    return np.repeat(lo - np.cumsum(sizes) + sizes, sizes) + np.arange(sizes.sum())


def _pair_key(a, b):
    """int64 keys ordered as the object pairs (a, b) (ids in [0, 2**31)): a * n + b, n one
    more than the largest id. Sorting on one key instead of two is about 4x faster."""
    n = max(int(a.max()), int(b.max())) + 1 if a.size else 1
    return a.astype(np.int64) * n + b


def _after(i, j, is_frame, tri_a, tri_b):
    """bool: row i comes after row j by (frame hits first, tri_a, tri_b)."""
    fi, fj = is_frame[i], is_frame[j]
    same_kind = fi == fj
    return ((fj & ~fi) | (same_kind & (tri_a[i] > tri_a[j]))
            | (same_kind & (tri_a[i] == tri_a[j]) & (tri_b[i] > tri_b[j])))


def _running_max_by_group(values, group_starts):
    """Running maximum of float64 values (n,), restarting at each index of group_starts
    (sorted, starting with 0): one numpy call per group (per object pair in contact)."""
    out = np.empty_like(values)
    bounds = np.append(group_starts, values.shape[0])
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        out[lo:hi] = np.maximum.accumulate(values[lo:hi])
    return out


def frame_of_time(times, t):
    """k such that times[k] <= t < times[k+1]; the last frame for t >= times[-1]."""
    k = np.searchsorted(times, t, side="right") - 1
    return np.minimum(np.maximum(k, 0), times.shape[0] - 1).astype(np.int64)  # np.clip: 4x the time on small arrays
