"""The soft-tissue sliding all rider bodies share: a stated prior, propagated into h's interval.

The recordings get a common displacement of every rider body, half of its variance following the
rider's acceleration with the opposite sign (soft tissue lags), made here from the poses alone (finite
differences of the segments' mean pivot, a Butterworth band): none of the prior's own code. No link
between bodies sees it, so nothing but the prior can widen the interval for it.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.signal import butter, sosfiltfilt

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.cog_height import identify_h
from euc_ros.core.identify.interval import extend_by_prior
from euc_ros.core.identify.options import IntervalOptions
from euc_ros.core.identify.sliding_prior import SlidingPrior, prior_spread, rms_from_sliding
from euc_ros.core.model.terms import EucParams
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.kinematics import reconstruct_states

H_TRUE = 0.61


def common_slide(series, session, rms_m: float, share: float, rng):
    names, fractions, _ = session.segment_arrays()
    idx = [series.bodies.index(n) for n, f in zip(names, fractions) if f > 0]
    w = np.array([f for f in fractions if f > 0])
    centre = np.einsum("b,btk->tk", w / w.sum(), series.position[idx])
    dt = 1.0 / series.rate_hz
    sos = butter(2, [0.3 * 2 * dt, 3.0 * 2 * dt], btype="band", output="sos")
    acc = np.gradient(np.gradient(centre, dt, axis=0), dt, axis=0)
    d = np.zeros_like(centre)
    for k in (0, 2):                                   # forward and up (Z-up world, the ride along x)
        a = sosfiltfilt(sos, acc[:, k])
        white = sosfiltfilt(sos, rng.standard_normal(a.size))
        d[:, k] = rms_m * (-np.sqrt(share) * a / a.std() + np.sqrt(1 - share) * white / white.std())
    pos = series.position.copy()
    pos[[series.bodies.index(n) for n in names]] += d[None]
    return dataclasses.replace(series, position=pos)


@pytest.fixture(scope="module", params=[1, 2])
def slid(request):
    ride = simulate_ride(RideConfig(maneuver="deceleration", runs=3, seed=request.param))
    rng = np.random.default_rng(request.param)
    states = []
    for r in ride.runs:
        s = common_slide(r.mocap_clean, ride.session, 1e-3, 0.5, rng)
        st = reconstruct_states(s, ride.session)
        st.meta["series"] = s
        states.append(st)
    return ride.session, EucParams.from_session(ride.session), states


def _interval(slid, prior_m):
    session, params, states = slid
    ident = identify_h(states, session, params, models=("3dof",),
                       uncertainty=IntervalOptions(with_budget=False, sliding=False,
                                                   sliding_prior=SlidingPrior(rms_m=prior_m)))
    return ident.h, ident.uncertainty["h_ci95_m"], ident.uncertainty["uncertainty"]


def test_without_the_prior_the_interval_misses_a_shared_slide(slid):
    h, (lo, hi), u = _interval(slid, 0.0)
    assert u["sliding_prior_range_m"] == [0.0, 0.0]
    assert not lo <= H_TRUE <= hi, (h, lo, hi)         # 1 mm shared sliding biases h by several cm


def test_the_prior_of_the_slides_size_holds_the_truth(slid):
    h, (lo, hi), u = _interval(slid, 1e-3)
    assert lo <= H_TRUE <= hi, (h, lo, hi, u["sliding_prior_range_m"])
    h0, (lo0, hi0), _ = _interval(slid, 0.0)
    p_lo, p_hi = u["sliding_prior_range_m"]
    assert h == h0 and lo == pytest.approx(lo0 - p_hi, abs=1e-12) and hi == pytest.approx(hi0 - p_lo, abs=1e-12)


def test_prior_edge_cases():
    assert extend_by_prior(0.5, 0.6, (-0.01, 0.02)) == pytest.approx((0.48, 0.61))
    assert extend_by_prior(0.5, 0.6, (0.01, -0.02)) == pytest.approx((0.5, 0.6))     # never narrowed
    assert extend_by_prior(0.5, 0.6, (None, float("nan"))) == (0.5, 0.6)
    with pytest.raises(ConfigError, match="--sliding-prior-mm"):
        SlidingPrior(rms_m=0.5)
    with pytest.raises(ConfigError):
        prior_spread([object()], None, 0.6, SlidingPrior(rms_m=None))
    assert prior_spread([], None, 0.6, SlidingPrior(rms_m=0.0))["sliding_prior_range_m"] == [0.0, 0.0]


def test_default_size_is_the_mass_weighted_measured_sliding():
    from euc_ros.core.session import default_session

    session = default_session()
    names, fractions, _ = session.segment_arrays()
    sliding = {"bodies": list(names), "rms_m": [0.002] * len(names), "rms_max_m": 0.002}
    assert rms_from_sliding(sliding, session, 5e-4) == pytest.approx(0.002 * float(np.sum(fractions)))
    assert rms_from_sliding(dict(sliding, rms_max_m=1e-4), session, 5e-4) == 0.0
    assert rms_from_sliding(None, session, 5e-4) == 0.0
