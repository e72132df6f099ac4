"""The fast median against numpy's, bit for bit, on arrays chosen to break its bracket."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core import robust
from euc_ros.core.robust import median


def _same(a, b) -> bool:
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def _arrays(rng, n):
    walk = np.cumsum(rng.standard_normal(n))
    yield rng.standard_normal(n)
    yield rng.standard_cauchy(n)                       # heavy tails
    yield np.round(rng.standard_normal(n), 1)          # many ties around the median
    yield walk                                         # a time series: the strided sample is not random
    yield np.sort(walk)
    yield np.sort(walk)[::-1].copy()
    yield np.full(n, 0.25)
    yield np.abs(rng.standard_normal(n)) ** 3          # skewed, as the absolute deviations are


@pytest.mark.parametrize("n", [1, 2, 7, robust.MIN_SIZE - 1, robust.MIN_SIZE, 10_001, 72_000, 216_001])
def test_equal_to_numpy_bit_for_bit(n):
    rng = np.random.default_rng(n)
    for x in _arrays(rng, n):
        assert _same(median(x), np.median(x))


def test_a_sample_that_misses_the_median_falls_back_to_numpy():
    """The sampled positions carry values far above the rest: the bracket lies outside the median's ranks."""
    n = 50_000
    x = np.random.default_rng(3).standard_normal(n)
    x[::max(1, n // robust.SAMPLE)] = 1e6 + np.arange(x[::max(1, n // robust.SAMPLE)].size)
    assert _same(median(x), np.median(x))
    x[::max(1, n // robust.SAMPLE)] *= -1
    assert _same(median(x), np.median(x))


def test_nan_anywhere_gives_nan_as_numpy():
    x = np.random.default_rng(4).standard_normal(20_000)
    x[12_345] = np.nan
    assert np.isnan(median(x)) and np.isnan(np.median(x))


@pytest.mark.parametrize("keepdims", [False, True])
def test_axes_and_keepdims_as_numpy(keepdims):
    rng = np.random.default_rng(5)
    a = rng.standard_normal((3, 30_001))
    for axis in (None, 0, 1, -1):
        assert _same(median(a, axis=axis, keepdims=keepdims), np.median(a, axis=axis, keepdims=keepdims))
        assert np.shape(median(a, axis=axis, keepdims=keepdims)) == \
            np.shape(np.median(a, axis=axis, keepdims=keepdims))
