"""The index helpers: ``stable_argsort`` is numpy's stable argsort, ties included, for every
key type it takes; ``ranges`` concatenates index ranges; ``distinct`` is ``np.unique``;
``unused_nodes`` the nodes no cell names."""

import numpy as np
import pytest

from critfric.fem.arrays import distinct, ranges, stable_argsort, unused_nodes


@pytest.mark.parametrize("dtype", [np.int32, np.int64, np.uint64, np.float64])
@pytest.mark.parametrize("high", [3, 1000, 10**6])
def test_stable_argsort_is_numpys_stable_sort(dtype, high):
    keys = np.random.default_rng(high).integers(0, high, 20000).astype(dtype)
    np.testing.assert_array_equal(stable_argsort(keys), np.argsort(keys, kind="stable"))


@pytest.mark.parametrize("keys", [[-1, 5, -1, 2], [2**61, 1, 2**61], [7], []])
def test_stable_argsort_outside_the_keyed_range(keys):
    keys = np.array(keys, dtype=np.int64)
    np.testing.assert_array_equal(stable_argsort(keys), np.argsort(keys, kind="stable"))


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
