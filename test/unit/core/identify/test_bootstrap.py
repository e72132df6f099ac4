"""The block bootstrap's replicates of two coefficient sets of the same samples are paired when given the
same block counts and seed: the random error of a combination of the two (the corrected h) is then that
of the combination, not of two independent estimates."""
from __future__ import annotations

import numpy as np

from euc_ros.core.identify.bootstrap import block_bootstrap, block_counts, block_length


def _coefs(rng, n: int, h0: float, common: np.ndarray, own: float) -> np.ndarray:
    """Coefficients of the residual ``e(h) = a0 + a1 h`` (c = 1, a2 = 0, d = 1) of one recording whose
    least-squares h is near ``h0``: ``a0 = -a1 h0 + noise``, the noise ``common`` (shared by both sets)
    plus independent noise of standard deviation ``own``."""
    a1 = 1.0 + 0.3 * np.sin(np.linspace(0.0, 40.0, n))
    a0 = -a1 * h0 + common + own * rng.standard_normal(n)
    return np.vstack([np.ones(n), a0, a1, np.zeros(n), np.ones(n), np.zeros(n)])


def test_same_counts_and_seed_pair_the_replicates():
    rng = np.random.default_rng(11)
    n, window = 4000, 25
    # correlated noise (the filter's): a moving average over a window of white noise
    common = np.convolve(rng.standard_normal(n + window - 1), np.ones(window) / np.sqrt(window), "valid")
    # b: the same noise smoothed further (as by a longer filter), so its residual's own block length is longer
    a = [_coefs(rng, n, 0.80, 0.05 * common, 0.005)]
    b = [_coefs(rng, n, 0.79, 0.05 * np.convolve(common, np.ones(31) / 31, "same"), 0.005)]
    assert block_length(b, 0.79, window) != block_length(a, 0.80, window)
    ha, hb = (-np.sum(c[1] * c[2]) / np.sum(c[2] ** 2) for c in (a[0], b[0]))    # the least-squares optima
    hb_a, length, nb, _ = block_bootstrap(a, ha, window, 0.01, n_boot=400, seed=3)
    counts = block_counts(a, length)
    assert counts == [n // length]
    paired, _, nb_p, _ = block_bootstrap(b, hb, window, 0.01, n_boot=400, seed=3, counts=counts)
    unpaired, _, _, _ = block_bootstrap(b, hb, window, 0.01, n_boot=400, seed=4, counts=counts)
    assert nb_p == nb
    # both sets share the noise that moves h, so paired replicates move together: their difference
    # scatters by what differs only, far less than each; unpaired, their variances add (about sqrt(2) times each)
    d_paired, d_unpaired = np.std(hb_a - paired), np.std(hb_a - unpaired)
    assert d_paired < 0.4 * np.std(hb_a), (d_paired, np.std(hb_a))
    assert d_unpaired > 1.0 * np.std(hb_a), (d_unpaired, np.std(hb_a))


def test_counts_default_to_the_block_length():
    rng = np.random.default_rng(5)
    a = [_coefs(rng, 3000, 0.7, 0.0, 0.01), _coefs(rng, 1200, 0.7, 0.0, 0.01)]
    length = block_length(a, 0.7, 25)
    one = block_bootstrap(a, 0.7, 25, 0.01, n_boot=200, seed=1)[0]
    two = block_bootstrap(a, 0.7, 25, 0.01, n_boot=200, seed=1, counts=block_counts(a, length))[0]
    np.testing.assert_array_equal(one, two)
