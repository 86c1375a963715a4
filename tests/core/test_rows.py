"""core.rows.unique_rows against np.unique(axis=0): the same row numbers and first occurrences."""
import numpy as np
import pytest

from addon.core.rows import unique_rows


@pytest.mark.parametrize("seed", range(6))
def test_rows_are_numbered_as_numpy_unique_numbers_them(seed):
    """Random integer rows (1 to 4 columns, negative values and many repeats, up to 5,000 rows): the inverse and the
    first occurrences equal np.unique's, element for element."""
    rng = np.random.default_rng(seed)
    n, c = int(rng.integers(1, 5000)), int(rng.integers(1, 5))
    key = rng.integers(-3, 4, (n, c)).astype(np.int64) * rng.choice([1, 1 << 40], (n, c))
    first, inverse = unique_rows(key, return_index=True)
    _, want_first, want_inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    assert np.array_equal(inverse, want_inverse.ravel()) and np.array_equal(first, want_first)
    assert np.array_equal(unique_rows(key), inverse)
    assert np.array_equal(key[first][inverse], key)


def test_no_rows_and_one_row():
    assert unique_rows(np.zeros((0, 2), np.int64)).shape == (0,)
    first, inverse = unique_rows(np.zeros((0, 3), np.int64), return_index=True)
    assert first.shape == inverse.shape == (0,)
    assert unique_rows(np.array([[5, -1]])).tolist() == [0]
