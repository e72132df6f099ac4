"""Low-lag Kalman fixed-lag smoother: known answers, an independent Kalman recursion,
gap handling and streaming == offline."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.filters.causal import (
    DEFAULT_TOL,
    StreamingKalman,
    default_smoothing_s,
    kalman_derivatives,
    kalman_weights,
    streaming_filter,
)

DT = 1.0 / 120.0
EPS = np.finfo(float).eps


@pytest.mark.parametrize("lag", [0, 3, 12, 72])
def test_cubic_is_exact_with_analytic_derivatives(lag):
    """A constant-jerk model's smoother reproduces cubics exactly (the truncation keeps that)."""
    t = np.arange(900) * DT
    c = (0.3, -1.2, 2.5, -0.7)
    y = c[0] + c[1] * t + c[2] * t**2 + c[3] * t**3
    d = kalman_derivatives(DT, y, lag_s=lag * DT, smoothing_s=0.07)
    k = np.flatnonzero(np.isfinite(d.y))
    assert d.lag == lag and k[0] == d.window - 1 - lag and k[-1] == t.size - 1 - lag
    assert np.allclose(d.y[k], y[k], atol=1e-9)
    assert np.allclose(d.y_dot[k], c[1] + 2 * c[2] * t[k] + 3 * c[3] * t[k] ** 2, atol=1e-7)
    assert np.allclose(d.y_ddot[k], 2 * c[2] + 6 * c[3] * t[k], atol=1e-5)


def _augmented_fixed_lag(y, lag, order, tau):
    """Independent route: a time-varying Kalman filter on the state augmented with its lagged copies.

    The filtered estimate of the oldest copy is the fixed-lag smoothed estimate. Physical units, the
    covariance recursion run from a diffuse prior (no Riccati solver, no innovations form).
    """
    from math import factorial

    n = order
    A = np.array([[DT ** (j - i) / factorial(j - i) if j >= i else 0.0 for j in range(n)] for i in range(n)])
    q = DT / tau ** (2 * n)
    Q = np.array([[q * DT ** (2 * n - 1 - i - j) / (factorial(n - 1 - i) * factorial(n - 1 - j) * (2 * n - 1 - i - j))
                   for j in range(n)] for i in range(n)])
    N = n * (lag + 1)
    Aa = np.zeros((N, N))
    Aa[:n, :n] = A
    for k in range(lag):
        Aa[n * (k + 1):n * (k + 2), n * k:n * (k + 1)] = np.eye(n)
    Qa = np.zeros((N, N))
    Qa[:n, :n] = Q
    Ha = np.zeros(N)
    Ha[0] = 1.0
    x = np.zeros(N)
    P = np.eye(N) * 1e6
    out = np.full((y.size, 3), np.nan)
    for k in range(y.size):
        if k:
            x = Aa @ x
            P = Aa @ P @ Aa.T + Qa
        S = P[0, 0] + 1.0
        K = P[:, 0] / S
        x = x + K * (y[k] - x[0])
        P = P - np.outer(K, Ha @ P)
        P = 0.5 * (P + P.T)
        if k >= lag:
            out[k - lag] = x[n * lag:n * lag + 3]
    return out


@pytest.mark.parametrize("lag,order", [(0, 3), (6, 4)])
def test_weights_equal_an_independent_time_varying_kalman_smoother(lag, order):
    rng = np.random.default_rng(3)
    n = 1200
    tau = 0.06
    y = np.cumsum(np.cumsum(rng.normal(size=n), 0), 0) * 1e-4 + 0.01 * rng.normal(size=n)
    ref = _augmented_fixed_lag(y, lag, order, tau)
    d = kalman_derivatives(DT, y, lag_s=lag * DT, smoothing_s=tau, order=order)
    w = kalman_weights(DT, lag, order=order, smoothing_s=tau)
    k = np.arange(n - lag)[np.arange(n - lag) >= 2 * w.shape[1]]     # the diffuse start has converged
    for i, est in enumerate((d.y, d.y_dot, d.y_ddot)):
        # truncation leaves DEFAULT_TOL of each weight row's L1 mass; the polynomial correction moves
        # the weights by as much again: the difference is bounded by 2 tol sum|w| max|y - mean|
        bound = 2 * DEFAULT_TOL * np.abs(w[i]).sum() * np.abs(y - y.mean()).max()
        assert np.max(np.abs(est[k] - ref[k, i])) < bound, i


def test_streaming_equals_offline_to_roundoff_across_gaps():
    rng = np.random.default_rng(0)
    n = 1500
    y = np.cumsum(np.cumsum(rng.normal(size=(n, 2)), 0), 0) * 1e-4 + np.array([3.0, -20.0])
    y[300:303] = np.nan      # bridged (max_gap 5)
    y[700:720] = np.nan      # splits the signal: the streaming filter restarts
    d = kalman_derivatives(DT, y, lag_s=0.1, max_gap=5)
    f = StreamingKalman(DT, lag_s=0.1, max_gap=5)
    on = np.full((3, n, 2), np.nan)
    filled = np.zeros(n, bool)
    for i in range(n):
        for s in f.push(y[i], frame=i):
            on[:, s.frame] = (s.y, s.y_dot, s.y_ddot)
            filled[s.frame] = s.filled
    off = np.stack([d.y, d.y_dot, d.y_ddot])
    assert np.array_equal(np.isnan(on), np.isnan(off))
    assert np.array_equal(filled, d.filled) and d.filled[300:303].all()
    assert np.all(np.isnan(off[:, 700:720 + f.window - 1 - f.lag]))
    w = f._coeffs
    for i in range(3):
        # two dot products of `window` terms, each within window * eps * sum|w| max|y| of the exact one
        bound = 2 * f.window * EPS * np.abs(w[i]).sum() * np.nanmax(np.abs(y))
        assert np.nanmax(np.abs(on[i] - off[i])) <= bound, i


def test_lag_smoothing_and_settings():
    f = StreamingKalman(DT, lag_s=0.1)
    assert f.lag == 12 and f.lag_s == pytest.approx(0.1) and f.smoothing_s == default_smoothing_s(0.1)
    assert streaming_filter("kalman", DT, window_s=1.2, polyorder=6).lag == 12
    sg = streaming_filter("savgol", DT, window_s=1.2, polyorder=6, lag_s=0.2)
    assert sg.lag == 24 and sg.window == 145
    with pytest.raises(ConfigError, match="lag_s"):
        streaming_filter("savgol", DT, window_s=1.2, polyorder=6, lag_s=0.7)
    with pytest.raises(ConfigError, match="estimator"):
        streaming_filter("ekf", DT, window_s=1.2, polyorder=6)
    with pytest.raises(ConfigError, match="smoothing_s"):
        kalman_weights(DT, 3, smoothing_s=0.001)
    with pytest.raises(ConfigError, match="order"):
        kalman_weights(DT, 3, smoothing_s=0.1, order=2)


def test_white_noise_gain_is_the_weights_norm():
    """A linear filter's output noise is sigma ||w||: the lower the lag, the noisier (at equal tau)."""
    g = [np.linalg.norm(kalman_weights(DT, lag, smoothing_s=0.065)[2]) for lag in (0, 6, 12, 36)]
    assert g == sorted(g, reverse=True)
    rng = np.random.default_rng(1)
    noise = rng.normal(scale=1e-3, size=20000)
    d = kalman_derivatives(DT, noise, lag_s=0.1, smoothing_s=0.065)
    sd = np.nanstd(d.y_ddot)
    # the sample std of ~20000 correlated values (correlation over ~window samples): within 10 %
    assert sd == pytest.approx(1e-3 * g[2], rel=0.1)
