"""collide.contacts: merging frame hits and swept contacts into intervals."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from collide.contacts import merge_order

#: rows (a, b, t0 index, is_frame, tri_a, tri_b) drawn from small ranges, so that ties of every
#: size, on every key, are common
ROWS = st.lists(st.tuples(st.integers(0, 3), st.integers(0, 3), st.integers(0, 3), st.booleans(),
                          st.integers(-1, 2), st.integers(-1, 2)), max_size=120)


@given(rows=ROWS, times=st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=4, max_size=4))
@settings(max_examples=300, deadline=None)
def test_merge_order_is_the_six_key_lexsort(rows, times):
    """merge_order against np.lexsort of (a, b, t0, frame hits first, tri_a, tri_b), which is
    stable: equal rows keep their input order."""
    table = np.array(rows, dtype=np.int64).reshape(-1, 6)
    a, b, tri_a, tri_b = table[:, 0], table[:, 1], table[:, 4], table[:, 5]
    t0 = np.array(times)[table[:, 2]]
    is_frame = table[:, 3].astype(bool)
    expected = np.lexsort((tri_b, tri_a, ~is_frame, t0, b, a))
    np.testing.assert_array_equal(merge_order(a, b, t0, is_frame, tri_a, tri_b), expected)
