"""Monitor threshold from a calibration ride: the false-alarm rate it states is the one it gives."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view

from euc_ros.core.errors import ConfigError
from euc_ros.core.online.alarm import integrated_autocorrelation, rmse_threshold


def _ar1(n, a, rng):
    from scipy.signal import lfilter

    return lfilter([np.sqrt(1 - a * a)], [1.0, -a], rng.normal(size=n))   # unit variance


def test_ar1_correlation_time_is_the_known_one():
    a = 0.8
    tau = integrated_autocorrelation(_ar1(200_000, a, np.random.default_rng(0)))
    assert tau == pytest.approx((1 + a) / (1 - a), rel=0.05)


@pytest.mark.parametrize("alpha", [1e-2, 1e-3])
def test_exceedance_rate_matches_alpha_on_correlated_gaussian_noise(alpha):
    rng = np.random.default_rng(1)
    window = 60
    calib = 3.0 * _ar1(20_000, 0.8, rng)
    thr = rmse_threshold(calib, window, alpha)
    test = 3.0 * _ar1(400_000, 0.8, rng)
    rms = np.sqrt(np.mean(sliding_window_view(test, window) ** 2, axis=1))
    # one independent window per window / tau_int samples; the chi-square with n_eff degrees of
    # freedom is an approximation: the rate must be the stated one within a factor 3
    rate = np.mean(rms > thr)
    assert alpha / 3 < rate < 3 * alpha, rate


def test_settings_are_checked():
    with pytest.raises(ConfigError, match="alpha"):
        rmse_threshold(np.ones(10), 5, 0.0)
    with pytest.raises(ConfigError, match="window"):
        rmse_threshold(np.ones(10), 0)
