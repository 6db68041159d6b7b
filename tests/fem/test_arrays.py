"""The index helpers: ``ranges`` concatenates index ranges; ``distinct`` is ``np.unique``;
``unused_nodes`` the nodes no cell names."""

import numpy as np
import pytest

from critfric.fem.arrays import distinct, ranges, unused_nodes


def test_ranges():
    np.testing.assert_array_equal(ranges(np.array([5, 0, 9]), np.array([2, 0, 3])),
                                  [5, 6, 9, 10, 11])
    assert ranges(np.array([], dtype=np.int32), np.array([], dtype=np.int32)).size == 0


@pytest.mark.parametrize("values", [np.random.default_rng(3).integers(0, 50, (400, 3)),
                                    np.array([[2**62, -5], [7, 2**62]]), np.zeros((0, 3), int),
                                    np.array([0.5, -0.0, 0.0, 0.5, -2.0])])
def test_distinct_is_numpys_unique(values):
    out = distinct(values)
    np.testing.assert_array_equal(out, np.unique(values))
    assert out.dtype == np.asarray(values).dtype


def test_unused_nodes():
    cells = np.array([[0, 2, 3], [3, 2, 6]])
    np.testing.assert_array_equal(unused_nodes(cells, 8), [1, 4, 5, 7])
    assert unused_nodes(np.zeros((0, 3), int), 2).tolist() == [0, 1]
