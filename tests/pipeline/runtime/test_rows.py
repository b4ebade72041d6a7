import numpy as np
import pytest

from skinsynth.pipeline.runtime.rows import unique_rows


@pytest.mark.parametrize("dtype", [np.int64, np.int32, np.bool_, np.float64])
def test_unique_rows_is_numpys_unique_along_rows(dtype):
    rows = np.random.default_rng(3).integers(-2, 3, (500, 4)).astype(dtype)
    rows = np.asfortranarray(rows)  # not C-contiguous, as a transposed view is
    unique, first, inverse = unique_rows(rows, return_index=True, return_inverse=True)
    want, want_first, want_inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    np.testing.assert_array_equal(unique, want)
    np.testing.assert_array_equal(first, want_first)
    np.testing.assert_array_equal(inverse, want_inverse.reshape(-1))
    np.testing.assert_array_equal(unique[inverse], rows)


def test_unique_rows_edges():
    assert unique_rows(np.zeros((0, 3), np.int64)).shape == (0, 3)
    np.testing.assert_array_equal(unique_rows(np.array([[2, 1], [1, 5], [2, 1]])), [[1, 5], [2, 1]])
    np.testing.assert_array_equal(unique_rows(np.array([[1.0, 0.0], [1.0, -0.0]])), [[1.0, 0.0]])
    assert unique_rows(np.ones((4, 2)), return_inverse=True)[1].tolist() == [0, 0, 0, 0]
    with pytest.raises(ValueError, match="2-D"):
        unique_rows(np.zeros(3))
