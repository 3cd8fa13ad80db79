"""Index helpers of tsrl.kinematics."""

import numpy as np

from tsrl.kinematics import as_slice


def test_as_slice_views_consecutive_indices_and_keeps_the_others():
    data = np.arange(10.0)
    assert as_slice([3, 4, 5]) == slice(3, 6)
    assert as_slice(np.array([0])) == slice(0, 1)
    scattered = as_slice([2, 7, 3])
    np.testing.assert_array_equal(scattered, [2, 7, 3])
    np.testing.assert_array_equal(data[as_slice([3, 4, 5])], data[[3, 4, 5]])
    assert isinstance(as_slice([5, 4, 3]), np.ndarray)  # descending is not a slice
