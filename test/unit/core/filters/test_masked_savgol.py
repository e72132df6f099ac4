"""Least-squares polynomial fits through the recorded samples of every window (masked Savitzky-Golay).

Checked against Savitzky-Golay itself where no sample is missing, against the analytic derivatives of a
polynomial of the fit's order where samples are missing (the fit is exact for it, whatever the pattern), and
for the variance inflation its normal equations predict: 1 with the full window, the measured scatter of the
second derivative on white noise next to a gap.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.derivatives import savgol_derivatives
from euc_ros.core.filters.masked_savgol import masked_savgol

DT = 1.0 / 120.0


def test_without_missing_samples_the_fits_are_savitzky_golay():
    rng = np.random.default_rng(1)
    t = np.arange(2400) * DT
    y = np.column_stack([np.sin(2 * np.pi * 0.7 * t) + 0.3 * np.sin(2 * np.pi * 2.1 * t), np.cos(1.3 * t)]) + 4.0
    y += rng.normal(0.0, 1e-3, y.shape)
    ref = savgol_derivatives(DT, y, window=145, polyorder=8)
    out = masked_savgol(y, 145, 8, DT)
    inner = slice(72, t.size - 72)
    for a, b in zip(ref, (out.y, out.y_dot, out.y_ddot)):
        np.testing.assert_allclose(b[inner], a[inner], rtol=0, atol=1e-10 * np.max(np.abs(a[inner])))
    np.testing.assert_allclose(out.inflation[inner], 1.0, rtol=1e-9)
    assert out.usable[inner].all() and out.recorded.all()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_polynomial_of_the_fits_order_is_exact_through_any_gaps(seed):
    rng = np.random.default_rng(seed)
    n, p = 1200, 6
    t = np.arange(n) * DT
    c = rng.normal(0.0, 1.0, p + 1)
    poly = np.polynomial.Polynomial(c, domain=[0, t[-1]], window=[-1, 1])
    y = poly(t)
    keep = rng.uniform(size=n) > 0.05                        # 5 % dropped frames
    for start in rng.integers(100, n - 120, 4):               # and four occlusions of 4-20 frames
        keep[start:start + rng.integers(4, 21)] = False
    out = masked_savgol(np.where(keep, y, np.nan), 121, p, DT)
    u = out.usable
    assert u.mean() > 0.9
    for est, exact in ((out.y, y), (out.y_dot, poly.deriv(1)(t)), (out.y_ddot, poly.deriv(2)(t))):
        scale = np.max(np.abs(exact))
        np.testing.assert_allclose(est[u], exact[u], rtol=0, atol=1e-8 * scale)


def test_the_inflation_is_the_scatter_of_the_second_derivative_next_to_a_gap():
    """On white noise the second derivative's variance next to a gap over its variance far from it is the
    predicted inflation (500 noise draws: the ratio's relative standard error is about 9 %)."""
    rng = np.random.default_rng(3)
    n, w, p = 600, 61, 4
    keep = np.ones(n, bool)
    keep[300:320] = False
    near, far = 325, 150
    draws = rng.normal(0.0, 1.0, (n, 500))
    out = masked_savgol(np.where(keep[:, None], draws, np.nan), w, p, DT)
    ratio = np.var(out.y_ddot[near]) / np.var(out.y_ddot[far])
    assert out.inflation[far] == pytest.approx(1.0)
    assert out.inflation[near] > 1.5
    assert ratio == pytest.approx(out.inflation[near], rel=4 * 0.09)


def test_a_gap_longer_than_the_window_is_not_bridged():
    y = np.arange(600, dtype=float)
    y[200:330] = np.nan                                      # 130 samples > the 61-sample window
    out = masked_savgol(y, 61, 4, DT)
    assert not out.usable[230:300].any() and np.isnan(out.y_ddot[265])
    assert out.usable[100] and out.usable[400]


def test_bad_arguments_name_the_key():
    with pytest.raises(ConfigError, match="window"):
        masked_savgol(np.zeros(50), 10, 4, DT)
    with pytest.raises(ConfigError, match="dt"):
        masked_savgol(np.zeros(50), 11, 4, 0.0)
    with pytest.raises(InputError, match="y"):
        masked_savgol(np.zeros((5, 5, 5)), 11, 4, DT)
