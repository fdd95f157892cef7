"""Contact tables: column layouts of the output and kernel rows -> contact intervals."""
import numpy as np

from .rows import (
    HIT_A,
    HIT_B,
    HIT_FRAME,
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


def frame_runs(frames):
    """Maximal runs of consecutive frame indices: sorted int64 (n,) -> (starts, ends) row indices."""
    frames = np.asarray(frames)
    if frames.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    breaks = np.flatnonzero(np.diff(frames) != 1)
    starts = np.concatenate([[0], breaks + 1])
    ends = np.concatenate([breaks, [frames.size - 1]])
    return starts, ends


def _to_columns(rows):
    """Contact columns from tuples ordered as CONTACT_COLUMNS, sorted (SPEC §4)."""
    columns = {name: np.array([r[k] for r in rows], dtype=dtype)
               for k, (name, dtype) in enumerate(CONTACT_COLUMNS.items())}
    return columns


def _group_by_pair(rows, a_col, b_col):
    """Yield (a, b, rows of that pair) for a 2-D array sorted or not."""
    if rows.shape[0] == 0:
        return
    keys = rows[:, a_col].astype(np.int64) * (int(rows[:, b_col].max()) + 1) + rows[:, b_col].astype(np.int64)
    for key in np.unique(keys):
        group = rows[keys == key]
        yield int(group[0, a_col]), int(group[0, b_col]), group


def intervals_from_hits(hits, times):
    """Discrete contact intervals from frame hits.

    hits int64 (H, HIT_WIDTH): frame hits (rows.py).
    times float64 (T,) analysed frame times.
    Returns (columns, where): contact columns sorted per SPEC §4 with one row
    per maximal run of consecutive frames of one object pair (points NaN, for
    the caller to fill), and where = (step int64 (E,), u float64 (E,),
    from_hit bool (E,)): the contact's first moment as frame/step index and
    fraction of the step, and whether (tri_a, tri_b) came from a frame hit.
    """
    hits = np.asarray(hits, dtype=np.int64).reshape(-1, HIT_WIDTH)
    rows = []
    for a, b, group in _group_by_pair(hits, HIT_A, HIT_B):
        group = group[np.argsort(group[:, HIT_FRAME], kind="stable")]
        starts, ends = frame_runs(group[:, HIT_FRAME])
        for s, e in zip(starts, ends):
            f0, f1 = group[s, HIT_FRAME], group[e, HIT_FRAME]
            rows.append((a, b, times[f0], times[f1], f0, f1, KIND_FRAME, group[s, HIT_TRI_A],
                         group[s, HIT_TRI_B], np.nan, np.nan, np.nan, f0, 0.0, True))
    return _finish(rows)


def _finish(rows):
    """Sort rows (contact columns + step, u, from_hit) and split off the where-arrays."""
    rows.sort(key=lambda r: (r[0], r[1], r[2]))
    columns = _to_columns([r[:12] for r in rows])
    where = (np.array([r[12] for r in rows], dtype=np.int64), np.array([r[13] for r in rows], dtype=np.float64),
             np.array([r[14] for r in rows], dtype=bool))
    return columns, where


def step_time(times, step, u):
    """Absolute time of fraction u of step (frame step -> step+1); exact at u = 0 and 1."""
    if u <= 0.0:
        return times[step]
    if u >= 1.0:
        return times[step + 1]
    return times[step] + u * (times[step + 1] - times[step])


def intervals_from_steps(ids, fractions, hits, times):
    """Continuous contact intervals.

    ids int64 (R, SWEPT_WIDTH), fractions float64 (R, TIMES_WIDTH): swept contacts
    (rows.py; fractions u in [0, 1] of the step from frame k to k+1), from
    swept.scan_intervals. hits int64 (H, HIT_WIDTH): exact contacts at frame poses,
    as for intervals_from_hits.
    Everything is merged per object pair into maximal intervals; kind is 0 when
    a frame pose inside the interval shows the contact, 1 when only the swept
    test saw it. Returns (columns, where) as intervals_from_hits.
    """
    ids = np.asarray(ids, dtype=np.int64).reshape(-1, SWEPT_WIDTH)
    fractions = np.asarray(fractions, dtype=np.float64).reshape(-1, TIMES_WIDTH)
    hits = np.asarray(hits, dtype=np.int64).reshape(-1, HIT_WIDTH)
    # items: a, b, begin, end, tri_a, tri_b, is_frame_contact, step, u
    items = []
    columns = ids[:, [SWEPT_STEP, SWEPT_A, SWEPT_B, SWEPT_TRI_A, SWEPT_TRI_B]].tolist()
    spans = fractions[:, [T_BEGIN, T_END]].tolist()
    for (k, a, b, ta, tb), (u0, u1) in zip(columns, spans):
        begin = step_time(times, k, u0)
        end = step_time(times, k, u1)
        if 0.0 < u0 < 1.0:  # keep the conservative side under rounding
            begin = np.nextafter(begin, -np.inf)
        if 0.0 < u1 < 1.0:
            end = np.nextafter(end, np.inf)
        items.append((a, b, begin, end, ta, tb, False, k, u0))
    for f, a, b, ta, tb in hits[:, [HIT_FRAME, HIT_A, HIT_B, HIT_TRI_A, HIT_TRI_B]].tolist():
        items.append((a, b, times[f], times[f], ta, tb, True, f, 0.0))
    items.sort(key=lambda it: (it[0], it[1], it[2], not it[6], it[4], it[5]))
    rows = []
    current = None
    for it in items:
        if current is not None and it[:2] == current[0][:2] and it[2] <= current[1]:
            current[1] = max(current[1], it[3])
            current[2] = current[2] or it[6]
            continue
        if current is not None:
            rows.append(_interval_row(current, times))
        current = [it, it[3], it[6]]
    if current is not None:
        rows.append(_interval_row(current, times))
    return _finish(rows)


def _interval_row(current, times):
    first, end, seen_at_frame = current
    a, b, begin, _, ta, tb, _, step, u = first
    return (a, b, begin, end, frame_of_time(times, begin), frame_of_time(times, end),
            KIND_FRAME if seen_at_frame else KIND_SWEPT, ta, tb, np.nan, np.nan, np.nan, step, u, first[6])


def frame_of_time(times, t):
    """k such that times[k] <= t < times[k+1]; the last frame for t >= times[-1]."""
    k = np.searchsorted(times, t, side="right") - 1
    return np.clip(k, 0, times.shape[0] - 1).astype(np.int64)
