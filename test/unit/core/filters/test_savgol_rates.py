"""The Savitzky-Golay coefficients are numerically sound at every frame rate and window.

Known solutions: a least-squares polynomial fit of order p reproduces every polynomial of degree
<= p exactly, so the value/derivative coefficients applied to t**k give k t**(k-1) etc. at any
rate; the derivative coefficients of a constant sum to zero. The reference implementation
(scipy.signal.savgol_coeffs, sample-unit Vandermonde) is only used where it is well conditioned.

Tolerances: the fit is solved in u in [-1, 1] with a Legendre basis whose conditioning does not
depend on the rate, so the round-off of the d-th derivative of a signal of scale Y is
~ eps * sum|h_d| * Y with sum|h_d| the coefficients' 1-norm (computed here, not guessed); we allow
1e3 of that for the QR's growth with the window length (sqrt(window) <= 35 for 1201 samples).
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.filters.derivatives import (
    StreamingSavgol,
    savgol_coefficients,
    savgol_derivatives,
    window_samples,
)

EPS = np.finfo(float).eps
RATES = (30, 60, 100, 120, 180, 240, 360, 500, 1000)


@pytest.mark.parametrize("rate", RATES)
@pytest.mark.parametrize("window_s,polyorder", [(0.9, 3), (1.2, 6), (0.3, 2)])
def test_coefficients_reproduce_polynomials_at_any_rate(rate, window_s, polyorder):
    dt = 1.0 / rate
    w = window_samples(dt, window_s=window_s, polyorder=polyorder)
    half = (w - 1) // 2
    positions = [0, half // 2, half, w - 1]
    h = savgol_coefficients(w, polyorder, dt, positions)
    tj = (np.arange(w) - half) * dt                      # sample times, centre at 0 [s]
    x0 = 37.0                                           # a position far from the origin [m]
    for i, pos in enumerate(positions):
        tp = (pos - half) * dt
        for k in range(polyorder + 1):
            y = x0 + tj**k
            want = (x0 + tp**k, k * tp ** (k - 1) if k >= 1 else 0.0,
                    k * (k - 1) * tp ** (k - 2) if k >= 2 else 0.0)
            for d in range(3):
                tol = 1e3 * EPS * np.abs(h[d, i]).sum() * np.abs(y).max()
                assert h[d, i] @ y == pytest.approx(want[d], abs=tol), (rate, w, pos, k, d)
        # a constant has no rate and no acceleration
        for d in (1, 2):
            assert abs(h[d, i].sum()) <= 1e3 * EPS * np.abs(h[d, i]).sum()


def test_the_issue_case_360hz_433_samples_order_6():
    """scipy's sample-unit coefficients sum to ~50 here (the cause of h = 1.2 at 360 Hz)."""
    h = savgol_coefficients(433, 6, 1 / 360, [216])
    assert abs(h[2, 0].sum()) < 1e3 * EPS * np.abs(h[2, 0]).sum()
    scipy_signal = pytest.importorskip("scipy.signal")
    bad = scipy_signal.savgol_coeffs(433, 6, deriv=2, delta=1 / 360, use="dot")
    assert abs(bad.sum()) > 1.0   # documents why we do not use it (if scipy fixes it, drop this line)


@pytest.mark.parametrize("window,polyorder", [(25, 3), (9, 2), (61, 4)])
def test_matches_scipy_where_scipy_is_well_conditioned(window, polyorder):
    scipy_signal = pytest.importorskip("scipy.signal")
    dt = 1 / 120
    rng = np.random.default_rng(3)
    y = np.cumsum(rng.normal(size=(400, 2)), axis=0)
    d = savgol_derivatives(dt, y, window=window, polyorder=polyorder)
    for k, ours in enumerate(d):
        ref = scipy_signal.savgol_filter(y, window, polyorder, deriv=k, delta=dt, axis=0, mode="interp")
        h = savgol_coefficients(window, polyorder, dt, [(window - 1) // 2])[k, 0]
        # scipy solves in sample units: its round-off grows with that Vandermonde's condition number
        cond = np.linalg.cond(np.vander(np.arange(window) - (window - 1) / 2, polyorder + 1))
        tol = 10 * EPS * cond * np.abs(h).sum() * np.abs(y).max()
        assert np.max(np.abs(ours - ref)) < tol


@pytest.mark.parametrize("rate", (60, 360, 1000))
def test_offline_and_streaming_agree_at_high_rates(rate):
    dt = 1.0 / rate
    t = np.arange(int(3.0 * rate)) * dt
    y = np.column_stack([12.0 + 2.0 * t + 0.3 * np.sin(2.0 * t), np.cos(1.3 * t)])
    w = window_samples(dt, window_s=1.2, polyorder=6)
    off = savgol_derivatives(dt, y, window=w, polyorder=6)
    f = StreamingSavgol(w, 6, dt)
    got = {s.frame: s for k in range(t.size) for s in f.push(y[k], frame=k)}
    frames = np.array(sorted(got))
    live_ddot = np.array([got[k].y_ddot for k in frames])
    h2 = savgol_coefficients(w, 6, dt, [(w - 1) // 2])[2, 0]
    tol = 1e3 * EPS * np.abs(h2).sum() * np.abs(y).max()
    assert np.max(np.abs(live_ddot - off.y_ddot[frames])) < tol
    # and both are right: the true second derivative within the fit's truncation error
    truth = np.column_stack([-0.3 * 4.0 * np.sin(2.0 * t), -1.69 * np.cos(1.3 * t)])
    assert np.max(np.abs(off.y_ddot[frames] - truth[frames])) < 0.02
