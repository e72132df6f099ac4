"""The session's Type B terms inside h's interval: combination, the mass-fraction direction, the JSON.

The combination is checked against a Monte Carlo of its own assumptions (a normal data error and a
rectangular error of a nominal value), not against its formula; the mass-fraction sensitivity against a
second identification with a session whose legs are lighter.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.stats import binom

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.budget import (
    K95,
    LOWER_LIMBS,
    budget,
    parse_tolerances,
    standard_uncertainty,
    widened,
    with_session,
)
from euc_ros.core.identify.fit import fit_h
from euc_ros.core.model.terms import EucParams
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.kinematics import reconstruct_states


@pytest.mark.parametrize("ratio", [0.0, 0.5, 1.0, 2.0, 5.0])
def test_the_combined_interval_holds_a_normal_plus_a_rectangular_error(ratio):
    """Coverage of h +- sqrt(d^2 + (1.96 u)^2) by draws of N(0, (d/1.96)^2) + U(-a, a), u = a / sqrt 3."""
    rng = np.random.default_rng(11)
    d, a, n = 0.02, 0.02 * ratio, 40_000
    err = rng.normal(0.0, d / K95, n) + rng.uniform(-a, a, n)
    lo, hi = widened((0.6, 0.6 - d, 0.6 + d), standard_uncertainty(1.0, a))
    covered = int(np.sum((0.6 + err >= lo) & (0.6 + err <= hi)))
    # at least 95 % within the binomial scatter of n draws (the normal approximation of a sum with a
    # rectangular part is conservative: a rectangle's 95 % point, 0.95 a, is below 1.96 a / sqrt 3 = 1.13 a)
    assert covered >= binom.ppf(1e-4, n, 0.95)
    # narrower than stacking the two 95 % half-widths linearly, where both are there
    u = standard_uncertainty(1.0, a)
    assert hi - 0.6 <= d + K95 * u + 1e-12 and (ratio == 0 or hi - 0.6 < d + K95 * u - 1e-6)


def test_an_unbounded_end_stays_unbounded_and_the_interval_stays_admissible():
    assert widened((0.6, None, 0.62), 0.01)[0] is None
    assert widened((0.6, 0.58, float("inf")), 0.01)[1] is None
    out = {"h_ci95_m": [0.15, 0.7], "uncertainty": {}}
    b = {"sensitivity": {"x": {"u_m": 0.05}}}
    with_session(out, b, 0.2, (0.1, 1.2))
    assert out["h_ci95_m"][0] == 0.1 and out["uncertainty"]["h_ci95_data_m"] == [0.15, 0.7]


def test_the_largest_term_is_named_and_the_shares_sum_to_one():
    out = {"h_ci95_m": [0.58, 0.62], "uncertainty": {}}
    b = {"sensitivity": {"rider.mass": {"u_m": 0.002}, "euc.l0": {"u_m": 0.03}, "euc.h0": {"u_m": None}}}
    with_session(out, b, 0.6, (0.1, 1.2))
    assert b["dominant"] == "euc.l0"
    shares = [v["share"] for v in b["sensitivity"].values()]
    assert abs(sum(shares) + (0.02 / K95) ** 2 / ((0.02 / K95) ** 2 + 0.002 ** 2 + 0.03 ** 2) - 1.0) < 1e-12
    lo, hi = out["h_ci95_m"]
    assert lo < 0.58 and hi > 0.62 and abs((0.6 - lo) - (hi - 0.6)) < 1e-12   # symmetric stays symmetric
    assert b["u_session_m"] == pytest.approx(np.hypot(0.002, 0.03))


def test_segment_tolerances_are_absolute():
    assert parse_tolerances(["rider.segments.mass_fraction=0.03"])["rider.segments.mass_fraction"] == 0.03
    with pytest.raises(ConfigError) as e:
        parse_tolerances(["rider.segments.com_offset=5%"])
    assert "rider.segments.com_offset" in str(e.value) and "--tolerance" in str(e.value)


def test_the_mass_fraction_sensitivity_predicts_a_session_with_lighter_legs():
    """dh/d(share moved from the legs) against identifying the same ride with 3 % of the mass moved up."""
    ride = simulate_ride(RideConfig(runs=3, seed=7))
    session = ride.session
    params = EucParams.from_session(session)
    series = [r.mocap for r in ride.runs]

    def h_with(sess):
        states = [reconstruct_states(s, sess) for s in series]
        return states, fit_h(states, params, models=("3dof",)).pooled["3dof"].h_m

    states, h0 = h_with(session)
    b = budget(series, states, session, params, h0)
    d = b["sensitivity"]["rider.segments.mass_fraction"]["dh_dp"]
    segs = session.rider.segments
    lower = sum(s.mass_fraction for k, s in segs.items() if k in LOWER_LIMBS)
    delta = 0.03
    moved = {k: dataclasses.replace(s, mass_fraction=s.mass_fraction * (
        1 - delta / lower if k in LOWER_LIMBS else 1 + delta / (1 - lower))) for k, s in segs.items()}
    assert abs(sum(s.mass_fraction for s in moved.values()) - 1.0) < 1e-12
    _, h1 = h_with(dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments=moved)))
    actual = h1 - h0
    # a central difference at 1 % predicts a 3 % move to the curvature's share (measured small) and the
    # grid's 1 mm resolution of each fit
    assert abs(d * delta - actual) <= 0.25 * abs(actual) + 2e-3, (d * delta, actual)
    assert b["sensitivity"]["rider.segments.mass_fraction"]["u_m"] == pytest.approx(
        abs(d) * 0.02 / np.sqrt(3.0), rel=1e-9)
