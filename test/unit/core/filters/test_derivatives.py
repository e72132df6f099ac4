"""Savitzky-Golay derivatives: known answers, gap handling, and online == offline."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.derivatives import (
    StreamingSavgol,
    gap_stretches,
    savgol_derivatives,
    window_samples,
)
from euc_ros.testing import savgol_roundoff

DT = 1.0 / 120.0


def test_cubic_is_reproduced_exactly_with_analytic_derivatives_including_edges():
    t = np.arange(200) * DT
    c = (0.3, -1.2, 2.5, -0.7)
    y = c[0] + c[1] * t + c[2] * t**2 + c[3] * t**3
    d = savgol_derivatives(DT, y, window=21, polyorder=3)
    assert np.allclose(d.y, y, atol=1e-11)
    assert np.allclose(d.y_dot, c[1] + 2 * c[2] * t + 3 * c[3] * t**2, atol=1e-9)
    assert np.allclose(d.y_ddot, 2 * c[2] + 6 * c[3] * t, atol=1e-6)
    assert not d.filled.any()


def test_sine_derivatives_match_the_analytic_ones():
    t = np.arange(600) * DT
    f = 1.0  # Hz: a 0.2 s cubic window attenuates the second derivative by about 3 % here
    y = np.sin(2 * np.pi * f * t)
    y_s, y_d, y_dd = savgol_derivatives(t, y, window_s=0.2, polyorder=3)
    w = 2 * np.pi * f
    inner = slice(12, -12)
    assert np.max(np.abs(y_d[inner] - w * np.cos(w * t[inner]))) < 0.02 * w
    assert np.max(np.abs(y_dd[inner] + w**2 * np.sin(w * t[inner]))) < 0.04 * w**2


def test_window_from_seconds_is_odd_and_validated():
    assert window_samples(DT, window_s=0.2) == 25
    assert window_samples(DT, window_s=0.19) == 23
    with pytest.raises(ConfigError, match="window"):
        window_samples(DT, window=20)
    with pytest.raises(ConfigError, match="polyorder"):
        window_samples(DT, window=3, polyorder=3)
    with pytest.raises(ConfigError, match="exactly one"):
        window_samples(DT, window_s=0.2, window=25)


def test_short_gap_is_filled_and_flagged_long_gap_splits():
    t = np.arange(400) * DT
    y = np.cos(3 * t)
    y[100:102] = np.nan  # 2 missing: bridged (max_gap 2)
    y[250:260] = np.nan  # 10 missing: split
    d = savgol_derivatives(DT, y, window=15, polyorder=3, max_gap=2)
    assert d.filled[100:102].all() and d.filled.sum() == 2
    assert np.allclose(d.y[100:102], np.cos(3 * t[100:102]), atol=1e-3)
    assert np.all(np.isnan(d.y[250:260])) and np.all(np.isnan(d.y_ddot[250:260]))
    # No leakage across the long gap: the second stretch alone gives the same numbers.
    alone = savgol_derivatives(DT, y[260:], window=15, polyorder=3)
    assert np.array_equal(alone.y_ddot, d.y_ddot[260:])
    # The first stretch's last samples are edge fits of that stretch only.
    alone1 = savgol_derivatives(DT, y[102:250], window=15, polyorder=3)
    assert np.allclose(alone1.y_dot[-7:], d.y_dot[243:250], atol=1e-12)


def test_stretch_shorter_than_window_gives_nan_not_garbage():
    y = np.linspace(0, 1, 60)
    y[10:20] = np.nan
    d = savgol_derivatives(DT, y, window=15, polyorder=3, max_gap=2)
    assert np.all(np.isnan(d.y[:10]))  # 10 samples < 15
    assert np.all(np.isfinite(d.y[20:]))


def test_frame_numbers_that_skip_are_gaps():
    n = 300
    frame = np.arange(n, dtype=np.int64)
    keep = np.ones(n, bool)
    keep[150] = False  # one dropped frame: bridged
    keep[200:210] = False  # ten dropped frames: split
    t = frame * DT
    y = t**2
    d_frame = savgol_derivatives(DT, y[keep], window=11, polyorder=3, frame=frame[keep])
    d_time = savgol_derivatives(t[keep], y[keep], window=11, polyorder=3)
    assert np.array_equal(np.isnan(d_frame.y_ddot), np.isnan(d_time.y_ddot))
    far = np.isfinite(d_frame.y_ddot) & (np.abs(np.flatnonzero(keep) - 150) > 6)
    assert np.allclose(d_frame.y_ddot[far], 2.0, atol=1e-7)
    assert np.allclose(d_time.y_dot[far], 2 * t[keep][far], atol=1e-9)
    # The dropped frame is absent from the output (nothing to flag); the signal was bridged:
    assert np.isfinite(d_frame.y[149]) and np.isfinite(d_frame.y[150])
    assert gap_stretches(frame[keep] , np.ones(keep.sum(), bool), 2) == [(0, 198), (199, keep.sum() - 1)]


def test_vector_signal_missing_when_any_component_is_nan():
    y = np.random.default_rng(0).normal(size=(100, 3)).cumsum(axis=0)
    y[40, 1] = np.nan
    d = savgol_derivatives(DT, y, window=9, polyorder=3, max_gap=0)
    assert np.all(np.isnan(d.y[40])) and np.isfinite(d.y[39]).all() and np.isfinite(d.y[41]).all()
    assert d.y_dot.shape == (100, 3)


def test_non_increasing_time_is_an_input_error():
    with pytest.raises(InputError, match="increasing"):
        savgol_derivatives(np.array([0.0, 0.01, 0.005, 0.02]), np.zeros(4), window=3, polyorder=2)


def _run_online(f: StreamingSavgol, frames, values):
    got = {}
    for fr, v in zip(frames, values):
        for s in f.push(v, frame=int(fr)):
            got[s.frame] = s
    return got


@pytest.mark.parametrize("window, polyorder", [(25, 3), (11, 2), (31, 4)])
def test_online_equals_offline_once_lag_is_aligned(window, polyorder):
    rng = np.random.default_rng(3)
    n = 1500
    frame = np.arange(n, dtype=np.int64)
    t = frame * DT
    y = np.column_stack([np.sin(1.3 * t), 0.2 * t**2]) + rng.normal(0, 1e-3, (n, 2))
    y[300:302] = np.nan  # bridged gap (NaN samples)
    y[700:720] = np.nan  # long gap: reset
    keep = np.ones(n, bool)
    keep[900] = keep[1100:1140] = False  # dropped frames: one bridged, one long
    fr, yy = frame[keep], y[keep]
    off = savgol_derivatives(DT, yy, window=window, polyorder=polyorder, max_gap=2, frame=fr)
    f = StreamingSavgol(window, polyorder, DT, max_gap=2)
    assert f.lag == (window - 1) // 2 and f.lag_s == pytest.approx(f.lag * DT)
    got = _run_online(f, fr, yy)
    assert len(got) > 0.8 * n
    pos = {int(v): i for i, v in enumerate(fr)}
    # The same fit on the same samples (bridged ones interpolated alike): the two differ by round-off,
    # each within savgol_roundoff of the exact output, for samples up to max|y| (0.2 t^2 reaches 3).
    scale = float(np.nanmax(np.abs(yy)))
    tol = [2 * savgol_roundoff(window, polyorder, d, DT, scale) for d in range(3)]
    compared = 0
    for frm, s in got.items():
        if frm not in pos:
            continue
        i = pos[frm]
        assert s.filled == bool(off.filled[i])
        np.testing.assert_allclose(s.y, off.y[i], rtol=0, atol=tol[0])
        np.testing.assert_allclose(s.y_dot, off.y_dot[i], rtol=0, atol=tol[1])
        np.testing.assert_allclose(s.y_ddot, off.y_ddot[i], rtol=0, atol=tol[2])
        compared += 1
    assert compared > 0.8 * n
    # The online filter never emits samples inside a long gap.
    assert not any(700 <= k < 720 or 1100 <= k < 1140 for k in got)


def test_causal_lag_zero_is_exact_on_a_polynomial_and_scalar_in_scalar_out():
    f = StreamingSavgol(9, 3, DT, lag=0)
    t = np.arange(30) * DT
    outs = _run_online(f, range(30), 1 + 2 * t - t**3)
    s = outs[29]
    assert isinstance(s.y, float)
    # a cubic is reproduced exactly: round-off only, of the fit evaluated at the window's last sample
    tol = [savgol_roundoff(9, 3, d, DT, 1.5, pos=8) for d in range(3)]   # |y| <= 1.5 over the window
    assert s.y == pytest.approx(1 + 2 * t[29] - t[29] ** 3, rel=0, abs=tol[0])
    assert s.y_dot == pytest.approx(2 - 3 * t[29] ** 2, rel=0, abs=tol[1])
    assert s.y_ddot == pytest.approx(-6 * t[29], rel=0, abs=tol[2])
    with pytest.raises(ConfigError, match="lag"):
        StreamingSavgol(9, 3, DT, lag=5)


def test_online_resets_after_long_nan_run():
    f = StreamingSavgol(5, 2, DT, max_gap=1)
    for i in range(10):
        f.push(float(i), frame=i)
    assert f.push(float("nan"), frame=10) == []
    assert f.push(float("nan"), frame=11) == []  # run of 2 > max_gap: reset
    assert f.push(12.0, frame=12) == []  # buffer restarted
    assert len(f.push(13.0, frame=13)) == 0


def test_trim_edges_in_frames_and_stretches():
    from euc_ros.core.filters.derivatives import trim_edges

    mask = np.array([True] * 10 + [False] + [True] * 10)
    out = trim_edges(mask, 2)
    assert out.tolist() == [False] * 2 + [True] * 6 + [False] * 2 + [False] + [False] * 2 + [True] * 6 + [False] * 2
    # rows skip a dropped frame (bridged) and a long gap (a new stretch)
    frames = np.array([0, 1, 2, 4, 5, 6, 20, 21, 22, 23, 24])
    out = trim_edges(np.ones(11, bool), 2, frames, max_gap=2)
    assert out.tolist() == [False, False, True, True, False, False, False, False, True, False, False]


@pytest.mark.parametrize("window,polyorder,columns", [(145, 3, 3), (31, 2, 1), (9, 3, None)])
def test_fft_filtering_of_long_stretches_equals_the_direct_correlation(monkeypatch, window, polyorder, columns):
    # a random walk far from the origin (lab coordinates) with a fast component; the direct correlation is the
    # reference. Round-off bound: each output sums `window` products of the offset-free signal (scale `span`)
    # with the weights, so both paths are exact to a few eps * sum|weights| * span.
    from euc_ros.core.filters import derivatives as dv

    rng = np.random.default_rng(window)
    n = 40 * window + 7
    shape = (n,) if columns is None else (n, columns)
    y = 12.0 + np.cumsum(rng.standard_normal(shape), axis=0) * 1e-3 + 0.01 * rng.standard_normal(shape)
    dt = 1.0 / 120.0
    calls = []
    real = dv.oaconvolve_many
    monkeypatch.setattr(dv, "oaconvolve_many", lambda *a, **k: calls.append(1) or real(*a, **k))
    fast = dv._filter_stretch(y, window, polyorder, dt)
    assert calls, "a stretch of 40 windows is filtered by FFT"
    monkeypatch.setattr(dv, "FFT_MIN_WINDOWS", 10 ** 9)
    direct = dv._filter_stretch(y, window, polyorder, dt)
    coeffs = dv._stretch_coefficients(window, polyorder, dt)[:, 0]
    span = float(np.max(np.abs(y - y[n // 2])))
    for d in range(3):
        eps = np.finfo(float).eps
        bound = 64 * eps * np.sum(np.abs(coeffs[d])) * span + (4 * eps * 12.0 if d == 0 else 0.0)
        np.testing.assert_allclose(fast[d], direct[d], rtol=0, atol=bound)

