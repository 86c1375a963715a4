"""core.memo: a result is made once per input, a changed input (bytes, dtype or shape) is a new result, arrays come
back read-only and the least recently used results go first."""
import numpy as np
import pytest

from addon.core.memo import Memo, digest


def test_a_result_is_made_once_per_input_and_again_for_any_change():
    made = []

    def area(tri, side):
        made.append(side)
        return np.full(3, tri.sum() * side)

    memo = Memo()
    tri = np.arange(6, dtype=np.float32).reshape(3, 2)
    first = memo.call(area, tri, 4)
    assert memo.call(area, tri.copy(), 4) is first and made == [4]
    with pytest.raises(ValueError):
        first[0] = 1.0
    memo.call(area, tri, 8)
    memo.call(area, tri.astype(np.float64), 4)
    memo.call(area, tri.reshape(2, 3), 4)
    changed = tri.copy()
    changed[0, 0] = np.nextafter(np.float32(0), np.float32(1))
    memo.call(area, changed, 4)
    assert made == [4, 8, 4, 4, 4]
    assert digest(tri, 4) != digest(tri, 4.0) and digest(tri, 4) == digest(tri.copy(), 4)


def test_the_least_recently_used_results_are_dropped_first():
    memo = Memo(kept=2, max_bytes=1 << 20)
    memo.get(b"a", lambda: 1)
    memo.get(b"b", lambda: 2)
    memo.get(b"a", lambda: 0)          # used again: b is now the oldest
    memo.get(b"c", lambda: 3)
    assert list(memo.items) == [b"a", b"c"]
    memo = Memo(kept=10, max_bytes=1000)
    memo.get(b"x", lambda: np.zeros(100))
    memo.get(b"y", lambda: np.zeros(100))
    assert list(memo.items) == [b"y"] and memo.bytes == 800
