"""collide.contacts: merging frame hits and swept contacts into intervals."""
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from collide import rows
from collide.contacts import KIND_FRAME, KIND_SWEPT, _merge_order, intervals_from_hits, intervals_from_steps

#: rows (a, b, t0 index, is_frame, tri_a, tri_b) drawn from small ranges, so that ties of every
#: size, on every key, are common
ROWS = st.lists(st.tuples(st.integers(0, 3), st.integers(0, 3), st.integers(0, 3), st.booleans(),
                          st.integers(-1, 2), st.integers(-1, 2)), max_size=120)


@given(rows=ROWS, times=st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=4, max_size=4))
@settings(max_examples=300, deadline=None)
def test_merge_order_is_the_six_key_lexsort(rows, times):
    """The merge kernel's order against np.lexsort of (a, b, t0, frame hits first, tri_a,
    tri_b), which is stable: equal rows keep their input order."""
    table = np.array(rows, dtype=np.int64).reshape(-1, 6)
    a, b, tri_a, tri_b = table[:, 0], table[:, 1], table[:, 4], table[:, 5]
    t0 = np.array(times)[table[:, 2]]
    is_frame = table[:, 3].astype(bool)
    expected = np.lexsort((tri_b, tri_a, ~is_frame, t0, b, a))
    np.testing.assert_array_equal(_merge_order(a, b, t0, is_frame, tri_a, tri_b), expected)


#: fractions of a step, the ends and a few in between, so that items often begin where others end
FRACTIONS = st.sampled_from([0.0, 0.25, 0.5, 0.7, 1.0]) | st.floats(0.0, 1.0)
#: swept rows (step, pair, tri_a, tri_b, u, u') and frame hits (frame, pair, tri_a, tri_b, smallest)
SWEPT = st.lists(st.tuples(st.integers(0, 3), st.integers(0, 2), st.integers(-1, 2), st.integers(-1, 2), FRACTIONS,
                           FRACTIONS), max_size=40)
HITS = st.lists(st.tuples(st.integers(0, 4), st.integers(0, 2), st.integers(-1, 2), st.integers(-1, 2),
                          st.booleans()), max_size=40)
PAIRS = [(0, 1), (0, 2), (1, 2)]
#: where the drawn values go in the kernels' rows
SWEPT_COLUMNS = [rows.SWEPT_STEP, rows.SWEPT_A, rows.SWEPT_B, rows.SWEPT_TRI_A, rows.SWEPT_TRI_B]
HIT_COLUMNS = [rows.HIT_FRAME, rows.HIT_A, rows.HIT_B, rows.HIT_TRI_A, rows.HIT_TRI_B, rows.HIT_SMALLEST]


def frame_of_time(times, t):
    """k such that times[k] <= t < times[k + 1], clipped to the frames (numpy)."""
    return np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 1)


def reference_intervals(swept, hits, times):
    """The merge rule in plain Python: per object pair, items sorted by (begin, frame hits
    first, tri_a, tri_b, input order); an item begins a new interval when it begins after
    every earlier item of its pair has ended."""
    def at(step, u, direction):
        after = times[min(step + 1, len(times) - 1)]
        if u <= 0.0:
            return times[step]
        if u >= 1.0:
            return after
        return math.nextafter(times[step] + u * (after - times[step]), direction)
    items = []  # (a, b, t0, t1, is_frame, tri_a, tri_b, step, u, first_found)
    for step, pair, tri_a, tri_b, u, v in swept:
        lo, hi = min(u, v), max(u, v)
        items.append((*PAIRS[pair], at(step, lo, -math.inf), at(step, hi, math.inf), False, tri_a, tri_b, step, lo,
                      False))
    for frame, pair, tri_a, tri_b, smallest in hits:
        items.append((*PAIRS[pair], times[frame], times[frame], True, tri_a, tri_b, frame, 0.0, not smallest))
    order = sorted(range(len(items)), key=lambda i: (items[i][0], items[i][1], items[i][2], not items[i][4],
                                                     items[i][5], items[i][6], i))
    out, reach = [], None
    for i in order:
        a, b, t0, t1, is_frame, tri_a, tri_b, step, u, found = items[i]
        if out and out[-1][:2] == [a, b] and t0 <= reach:
            out[-1][3] = max(out[-1][3], t1)
            out[-1][4] = out[-1][4] or is_frame
            reach = max(reach, t1)
        else:
            out.append([a, b, t0, t1, is_frame, tri_a, tri_b, step, u, found])
            reach = t1
    return out


@given(swept=SWEPT, hits=HITS, gaps=st.lists(st.floats(0.01, 10.0), min_size=4, max_size=4))
@settings(max_examples=300, deadline=None)
def test_intervals_from_steps_against_the_merge_rule_in_plain_python(swept, hits, gaps):
    times = np.concatenate([[0.0], np.cumsum(gaps)])
    ids = np.zeros((len(swept), rows.SWEPT_WIDTH), np.int64)
    fractions = np.zeros((len(swept), rows.TIMES_WIDTH))
    for k, (step, pair, tri_a, tri_b, u, v) in enumerate(swept):
        ids[k, SWEPT_COLUMNS] = step, *PAIRS[pair], tri_a, tri_b
        fractions[k, [rows.T_BEGIN, rows.T_END]] = min(u, v), max(u, v)
    hit_rows = np.zeros((len(hits), rows.HIT_WIDTH), np.int64)
    for k, (frame, pair, tri_a, tri_b, smallest) in enumerate(hits):
        hit_rows[k, HIT_COLUMNS] = frame, *PAIRS[pair], tri_a, tri_b, smallest
    columns, where = intervals_from_steps(ids, fractions, hit_rows, times)
    expected = reference_intervals(swept, hits, times)
    got = list(zip(columns["object_a"], columns["object_b"], columns["t_begin"], columns["t_end"],
                   columns["kind"] == KIND_FRAME, columns["tri_a"], columns["tri_b"], where.step, where.u,
                   where.first_found))
    assert [[int(v) if i in (0, 1, 5, 6, 7) else v for i, v in enumerate(row)] for row in got] == \
        [[a, b, t0, t1, seen, tri_a, tri_b, step, u, found] for a, b, t0, t1, seen, tri_a, tri_b, step, u, found
         in expected]
    assert set(columns["kind"]) <= {KIND_FRAME, KIND_SWEPT}
    np.testing.assert_array_equal(columns["frame_begin"], frame_of_time(times, columns["t_begin"]))
    np.testing.assert_array_equal(columns["frame_end"], frame_of_time(times, columns["t_end"]))
    assert np.isnan(columns["point_x"]).all() and columns["point_x"].shape == columns["t_begin"].shape


@given(hits=HITS, gaps=st.lists(st.floats(0.01, 10.0), min_size=4, max_size=4))
@settings(max_examples=300, deadline=None)
def test_intervals_from_hits_are_runs_of_consecutive_frames(hits, gaps):
    """Discrete intervals against plain Python: per object pair, its frames sorted, one
    interval per run of consecutive frames, with the pair and flag of the run's first hit."""
    times = np.concatenate([[0.0], np.cumsum(gaps)])
    hits = list({(frame, pair): (frame, pair, tri_a, tri_b, smallest)  # one hit per pair and frame
                 for frame, pair, tri_a, tri_b, smallest in hits}.values())
    hit_rows = np.zeros((len(hits), rows.HIT_WIDTH), np.int64)
    for k, (frame, pair, tri_a, tri_b, smallest) in enumerate(hits):
        hit_rows[k, HIT_COLUMNS] = frame, *PAIRS[pair], tri_a, tri_b, smallest
    expected = []
    for frame, pair, tri_a, tri_b, smallest in sorted(hits, key=lambda h: (PAIRS[h[1]], h[0])):
        if expected and expected[-1][:2] == list(PAIRS[pair]) and expected[-1][3] == frame - 1:
            expected[-1][3] = frame
        else:
            expected.append([*PAIRS[pair], frame, frame, tri_a, tri_b, not smallest])
    columns, where = intervals_from_hits(hit_rows, times)
    got = [[int(a), int(b), int(f0), int(f1), int(ta), int(tb), bool(found)] for a, b, f0, f1, ta, tb, found in zip(
        columns["object_a"], columns["object_b"], columns["frame_begin"], columns["frame_end"], columns["tri_a"],
        columns["tri_b"], where.first_found)]
    assert got == expected
    np.testing.assert_array_equal(columns["t_begin"], times[columns["frame_begin"]])
    np.testing.assert_array_equal(columns["t_end"], times[columns["frame_end"]])
    np.testing.assert_array_equal(where.step, columns["frame_begin"])
    assert (where.u == 0.0).all() and (columns["kind"] == KIND_FRAME).all()
