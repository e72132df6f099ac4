"""Held-out evaluation of the residual analysis: folds within and across runs, blocks from the residual's
autocorrelation, fold fits by one Gauss-Newton step, and the analysis' sub-sampling.

The reference for the fold fits is an independent computation: scipy's least squares refitted from
scratch on each fold's training samples only. The tolerance is a fraction of the parameters' own
standard error (from the Jacobian and the residual's variance, with one independent sample per filter
window), so it holds on any machine.
"""
# covers: euc_ros/core/residual/folds.py
# covers: euc_ros/core/residual/selection.py
# covers: euc_ros/core/states/contexts.py
from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize

from euc_ros.core.model.candidate import ModelContext
from euc_ros.core.model.effects import make_candidates
from euc_ros.core.model.extended import Model
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.folds import folds_of, residual_block_length, with_blocks
from euc_ros.core.residual.selection import fit_base_h, fit_model, held_out, model_jacobian
from euc_ros.core.states.contexts import ANALYSIS_RATE_HZ, Recording, analysis_rate, decimation_step, prepare
from euc_ros.core.states.kinematics import reconstruct_states


def _fake_recs(lengths, dt=0.1, block_s=1.0):
    recs = []
    for i, n in enumerate(lengths):
        t = np.arange(n) * dt
        z = np.zeros(n)
        ctx = ModelContext(t=t, x_dot=z, x_ddot=z, gamma=z, gamma_dot=z, gamma_ddot=z, phi=z, phi_dot=z,
                           phi_ddot=z, psi=z, psi_dot=z, theta=z, params=None)
        recs.append(Recording(f"r{i}", ctx, np.floor(t / block_s).astype(int)))
    return recs


def test_every_sample_is_held_out_once_and_never_trained_on_near_its_fold():
    recs = _fake_recs([70, 55, 90])
    folds = folds_of(recs, 2, guard_s=0.45)
    assert len(folds) == 6
    for i, rec in enumerate(recs):
        count = sum(f.test[i].astype(int) for f in folds)
        assert np.all(count == 1)
    for f in folds:
        for i, rec in enumerate(recs):
            assert not np.any(f.train[i] & f.test[i])
            if f.test[i].any():
                t_test = rec.ctx.t[f.test[i]]
                d = np.min(np.abs(rec.ctx.t[f.train[i]][:, None] - t_test[None, :]), axis=1)
                assert d.min() >= 0.45 - 1e-12
                # the guard excludes exactly the samples within 0.45 s
                near = np.min(np.abs(rec.ctx.t[:, None] - t_test[None, :]), axis=1) < 0.45
                assert np.array_equal(f.train[i], ~near)
            else:
                assert f.train[i].all()
        # test segments are whole blocks
        for i, rec in enumerate(recs):
            tb = set(rec.block[f.test[i]])
            assert not (tb & set(rec.block[~f.test[i]]))


def test_block_length_follows_the_noise_not_the_signal():
    """Moving-average noise of m samples has a triangular autocorrelation that reaches 0 at lag m: the
    block is 2 m dt. A slow, large signal (an effect's signature) on top must not lengthen it."""
    rng = np.random.default_rng(3)
    dt, m, n = 0.01, 40, 6000
    recs = _fake_recs([n], dt=dt)
    e = np.convolve(rng.normal(size=n + m - 1), np.ones(m) / m, mode="valid")
    b = residual_block_length(recs, [e], min_s=0.1, trend_s=16 * m * dt)
    # the slow part is removed by a cubic Savitzky-Golay fit over trend_s (16 m samples), a high-pass that also
    # takes ~20 % of the noise's own correlation; the block may be that much shorter, never longer
    assert 0.75 * 2 * m * dt <= b <= 1.1 * 2 * m * dt
    slow = 20 * np.std(e) * np.sin(2 * np.pi * recs[0].ctx.t / 40.0)
    b2 = residual_block_length(recs, [e + slow], min_s=0.1, trend_s=16 * m * dt)
    assert b2 == pytest.approx(b, rel=0.25)
    # never shorter than the floor, never longer than a quarter of the recording
    assert residual_block_length(recs, [rng.normal(size=n)], min_s=1.2, trend_s=1.0) == pytest.approx(1.2)
    assert residual_block_length(recs, [np.cumsum(rng.normal(size=n))], min_s=0.1, trend_s=60.0) <= 0.25 * n * dt


def test_decimation_step():
    assert decimation_step(1 / 120, 10.0) == 12
    assert decimation_step(1 / 360, 10.0) == 36
    assert decimation_step(1 / 120, None) == 1
    assert decimation_step(1 / 5, 10.0) == 1


@pytest.mark.parametrize("window_s", [0.3, 0.525, 0.6, 0.9, 1.2, 2.0])
@pytest.mark.parametrize("polyorder", [2, 4, 6, 8])
def test_analysis_rate_samples_beyond_the_filters_main_lobe(window_s, polyorder):
    # the smoothing response of the states' filter, computed from its own coefficients: its main lobe (response
    # above 1 % of the peak) must end below 0.6 of the sub-sample's Nyquist frequency (the default filter,
    # 1.2 s / order 6 at 10 Hz: 2.6 Hz against 5 Hz), so what the filter passes is not folded by the sub-sampling
    from euc_ros.core.filters.auto_window import savgol_response

    dt = 1 / 120
    window = int(round(window_s / dt)) // 2 * 2 + 1
    f = np.linspace(0.005, 60.0, 12000)
    r = np.abs(savgol_response(window, polyorder, 0, dt, f))
    lobe_end = f[np.argmax(r < 0.01)]
    rate = analysis_rate(window * dt, polyorder)
    assert rate >= ANALYSIS_RATE_HZ
    assert lobe_end <= 0.6 * rate / 2
    # and never much faster than needed: within a factor 2.5 of the lobe's own Nyquist rate where the rate is
    # above the default's floor
    if rate > ANALYSIS_RATE_HZ:
        assert rate <= 2.5 * 2 * lobe_end / 0.6


def test_analysis_rate_of_the_default_filter_is_the_default_rate():
    assert analysis_rate(1.2, 6) == ANALYSIS_RATE_HZ


@pytest.fixture(scope="module")
def rolling_ride():
    from euc_ros.core.ridesim.effects import make_effects
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    eff = make_effects(["rolling_resistance"], {"c_rr": 0.01})
    res = simulate_ride(RideConfig(maneuver="deceleration", runs=2, seed=31, effects=eff))
    states = [reconstruct_states(r.mocap, res.session) for r in res.runs]
    return states, EucParams.from_session(res.session)


def _standard_errors(model, recs, x, window_samples):
    r, m, J = model_jacobian(model, recs, x)
    rr = np.concatenate([a[k] for a, k in zip(r, m)])
    JJ = np.concatenate([a[k] for a, k in zip(J, m)])
    s2 = np.mean(rr ** 2) * window_samples       # one independent sample per filter window
    return np.sqrt(np.diag(s2 * np.linalg.inv(JJ.T @ JJ)))


def test_gauss_newton_fold_fits_match_refits_from_scratch(rolling_ride):
    states, params = rolling_ride
    recs = with_blocks(prepare(states, params, analysis_rate_hz=10.0), 1.2)
    cand = next(c for c in make_candidates() if c.name == "rolling_resistance")
    model = Model([cand])
    h0 = fit_base_h(recs)
    full = fit_model(model, recs, h0)
    folds = folds_of(recs, 2, guard_s=1.2)
    ho = held_out(model, recs, h0, folds, start=full.x)
    dt = float(np.median(np.diff(recs[0].ctx.t)))
    se = _standard_errors(model, recs, full.x, window_samples=max(1.0, states[0].window * states[0].dt / dt))
    lo, hi = model.bounds()
    for fold, x_gn in zip(folds, ho.params):
        def train_residual(x):
            return np.concatenate([np.where(tr, model.residual(r, x)[0], 0.0) for r, tr in zip(recs, fold.train)])

        exact = optimize.least_squares(train_residual, full.x, bounds=(lo, hi), x_scale=model.scales(),
                                       ftol=1e-12, xtol=1e-12, gtol=1e-12).x
        # one step from the full optimum: the difference is second order, far below the statistical error
        assert np.all(np.abs(x_gn - exact) < 0.05 * se), (x_gn, exact, se)
    assert ho.residual.size == sum(int(m.sum()) for m in (model.residual(r, full.x)[1] for r in recs))


def test_subsampling_keeps_the_fit(rolling_ride):
    """The analysis' 10 Hz sub-sample of a 120 Hz recording: h and c_rr within a fifth of their standard
    error of the fit on every sample (the states are low-pass filtered; the sub-sample keeps the signal)."""
    states, params = rolling_ride
    cand = next(c for c in make_candidates() if c.name == "rolling_resistance")
    model = Model([cand])
    fits, ses = [], None
    for rate in (None, 10.0):
        recs = with_blocks(prepare(states, params, analysis_rate_hz=rate), 1.2)
        f = fit_model(model, recs, fit_base_h(recs))
        fits.append(f.x)
        if rate is None:
            ses = _standard_errors(model, recs, f.x, window_samples=states[0].window)
    assert np.all(np.abs(fits[0] - fits[1]) < 0.2 * ses), (fits, ses)
