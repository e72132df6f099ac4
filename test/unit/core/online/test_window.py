"""Online estimator and sliding RMSE: agreement with the offline identification.

Tolerances: the sliding RMSE keeps a running sum of squares, recomputed every window length of
pushes; against a direct mean over the same samples it differs by that sum's round-off, <= 2 w eps
max(r^2) / mean(r^2) relative with w = 37 and max/mean ~4 for the normal samples here: ~7e-14
(half that after the square root); rel 1e-12 leaves >= 10x, rel 1e-10 far more.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.fit import fit_h
from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torques
from euc_ros.core.online.window import OnlineHEstimator, SlidingRmse
from euc_ros.core.session import default_session
from euc_ros.core.states.kinematics import RiderStates

P = EucParams.from_session(default_session(), 0.61)


def _states(ride, rng=None, sigma=0.0):
    n = ride["t"].size
    nan = np.full(n, np.nan)
    xdd = ride["x_ddot"] + (rng.normal(0, sigma, n) if rng is not None else 0.0)
    return RiderStates(name="r", t=ride["t"], frame=np.arange(n), x=ride["x"], x_dot=ride["x_dot"], x_ddot=xdd,
                       gamma=ride["gamma"], gamma_dot=ride["gamma_dot"], gamma_ddot=ride["gamma_ddot"],
                       phi=ride["phi"], phi_dot=ride["phi_dot"], phi_ddot=ride["phi_ddot"], phi_eq3=nan,
                       phi_hinge=ride["phi"], psi=np.zeros(n), theta=np.zeros(n), C=np.full((n, 3), np.nan),
                       G=np.full((n, 3), np.nan), has_euc=np.ones(n, bool), has_rider=np.ones(n, bool),
                       valid=np.ones(n, bool))


@pytest.fixture(scope="module")
def noisy_ride(symbolic, synth):
    ride = synth.planar_ride(symbolic, P, duration=10.0, seed=3, decel=0.05)
    return _states(ride, np.random.default_rng(2), sigma=0.3)


def test_sliding_rmse_matches_numpy_over_the_window():
    rng = np.random.default_rng(0)
    vals = rng.normal(0, 5, 500)
    vals[rng.random(500) < 0.1] = np.nan
    r = SlidingRmse(37)
    for i, v in enumerate(vals):
        got = r.push(v)
        win = vals[max(0, i - 36):i + 1]
        win = win[np.isfinite(win)]
        assert got == pytest.approx(np.sqrt(np.mean(win**2)) if win.size else np.nan, rel=1e-12, nan_ok=True)
    with pytest.raises(ConfigError):
        SlidingRmse(0)


def test_online_estimate_over_the_whole_ride_equals_the_offline_one(noisy_ride):
    st = noisy_ride
    est = OnlineHEstimator(P, window=st.n, update_every=st.n)
    for args in zip(*st.torque_args()):
        out = est.update(*args)
    off = fit_h([st], P).pooled["3dof"]
    assert out.n_samples == st.n
    assert out.h_m == pytest.approx(off.h_m, abs=1e-5)
    assert out.rmse_nm == pytest.approx(off.rmse_nm, rel=1e-6)
    assert out.h_std_m > 0 and abs(out.h_m - 0.61) < 5 * out.h_std_m + 0.01
    # The formal std agrees with the offline curvature-based one.
    assert out.h_std_m == pytest.approx(off.h_std_m, rel=1e-2)


def test_sliding_window_estimate_converges_to_the_truth_and_is_nan_before(noisy_ride):
    st = noisy_ride
    est = OnlineHEstimator(P, window=480, min_samples=240, update_every=10, correlation_samples=1.0)
    hs, sd = [], []
    for k, args in enumerate(zip(*st.torque_args())):
        out = est.update(*args)
        if k < 239:
            assert np.isnan(out.h_m)
        hs.append(out.h_m)
        sd.append(out.h_std_m)
    hs, sd = np.array(hs[600:]), np.array(sd[600:])
    assert np.all(np.isfinite(hs))
    # White noise on x_ddot here, so the formal std is honest: every estimate within 3 sigma of the truth.
    assert np.all(np.abs(hs - 0.61) < 3 * sd)
    assert np.all(sd < 0.05) and np.max(np.abs(hs - 0.61)) < 0.08


def test_no_excitation_gives_nan_and_invalid_samples_are_skipped():
    est = OnlineHEstimator(P, window=100, min_samples=10)
    # Standing still upright: nothing depends on h.
    for _ in range(100):
        out = est.update(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert np.isnan(out.h_m) and out.n_samples == 100 and out.sensitivity_nm_per_m == pytest.approx(0.0, abs=1e-9)
    est.reset()
    for _ in range(20):
        out = est.update(np.nan, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert out.n_samples == 0 and np.isnan(out.h_m)


def test_online_residual_rmse_uses_the_same_torques(noisy_ride):
    st = noisy_ride
    d1, d2 = torques(*st.torque_args(), P)
    r = SlidingRmse(st.n)
    for e in d1 - d2:
        v = r.push(e)
    assert v == pytest.approx(np.sqrt(np.mean((d1 - d2) ** 2)), rel=1e-10)
