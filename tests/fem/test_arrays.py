"""The index helpers: ``stable_argsort`` is numpy's stable argsort, ties included, for every
key type it takes; ``ranges`` concatenates index ranges."""

import numpy as np
import pytest

from critfric.fem.arrays import ranges, stable_argsort


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
