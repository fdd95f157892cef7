"""Contact tables: column layouts (SPEC §4) and frame hits -> contact intervals."""
import numpy as np

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


def intervals_from_hits(hits, times):
    """Discrete contact intervals from frame hits.

    hits int64 (H, 6): frame, object_a, object_b, n_pairs, tri_a, tri_b.
    times float64 (T,) analysed frame times.
    Returns the contact columns (points set to NaN: filled by the caller) with
    one row per maximal run of consecutive frames of one object pair.
    """
    hits = np.asarray(hits, dtype=np.int64).reshape(-1, 6)
    order = np.lexsort((hits[:, 0], hits[:, 2], hits[:, 1]))
    hits = hits[order]
    rows = []
    pair_keys = hits[:, 1] * (hits[:, 2].max(initial=0) + 1) + hits[:, 2]
    for key in np.unique(pair_keys):
        group = hits[pair_keys == key]
        starts, ends = frame_runs(group[:, 0])
        for s, e in zip(starts, ends):
            f0, f1 = group[s, 0], group[e, 0]
            rows.append((group[s, 1], group[s, 2], times[f0], times[f1], f0, f1,
                         KIND_FRAME, group[s, 4], group[s, 5], np.nan, np.nan, np.nan))
    columns = {name: np.array([r[k] for r in rows], dtype=dtype)
               for k, (name, dtype) in enumerate(CONTACT_COLUMNS.items())}
    return sort_columns(columns, ["object_a", "object_b", "t_begin"])


def frame_of_time(times, t):
    """k such that times[k] <= t < times[k+1]; the last frame for t >= times[-1]."""
    k = np.searchsorted(times, t, side="right") - 1
    return np.clip(k, 0, times.shape[0] - 1).astype(np.int64)
