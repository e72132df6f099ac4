"""A library name is kept beside discovered terms only where it adds to them.

Simulated rides with a horizontal force at the rider's CoG fixed in the lab: a constant part along lab x (which a
ground slope mimics: its moment about the contact has the same signature) and a bump. Where the discovered terms
hold the constant part themselves (per-run constants, a field over lab x), the slope is not named beside them;
where they cannot (a field proportional to the speed), it stays.
"""
# covers: euc_ros/core/residual/analysis.py
from __future__ import annotations

import pytest

from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.analysis import analyze
from euc_ros.core.residual.names import library_effects
from euc_ros.core.residual.noise import make_noise_floor
from euc_ros.core.ridesim.external import ExternalForce
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.kinematics import reconstruct_states

pytestmark = pytest.mark.slow


def traced(maneuver: str, seed: int, bump_n: float, x0_m: float, width_m: float, constant_n: float) -> dict:
    external = (ExternalForce("lab_bump", {"amp_n": bump_n, "x0_m": x0_m, "width_m": width_m}),
                ExternalForce("lab_bump", {"amp_n": constant_n, "x0_m": 0.0, "width_m": 300.0}))
    res = simulate_ride(RideConfig(maneuver=maneuver, runs=3, seed=seed, external=external))
    states = [reconstruct_states(r.mocap, res.session) for r in res.runs]
    params = EucParams.from_session(res.session)
    series = [r.mocap for r in res.runs]
    return analyze(states, params, noise_floor_of=make_noise_floor(series, states, res.session, params)).to_json()


def test_a_slope_the_discovered_terms_hold_is_not_named_beside_them():
    out = traced("deceleration", 5, 20.0, 8.0, 4.0, 12.0)
    dropped = [s for s in out["selection_steps"] if s.get("dropped_beside_discovery")]
    assert dropped and dropped[0]["dropped_beside_discovery"] == "ground_slope", out["selection_steps"]
    assert library_effects(out["effect"]) == [] and out["discovered"], out["effect"]
    assert any(d["family"] == "lab field" for d in out["discovered"]), out["discovered"]
    # the terms alone still hold both forces (20 and 12 N; 0.12 of the RMSE is left on this ride)
    assert out["rmse_after_nm"] <= 0.2 * out["rmse_before_nm"], (out["rmse_after_nm"], out["rmse_before_nm"])


def test_a_slope_the_discovered_terms_cannot_hold_stays():
    out = traced("acceleration", 11, 10.0, 10.0, 2.0, 15.0)
    assert "ground_slope" in library_effects(out["effect"]) and out["discovered"], out["effect"]
    assert not any(s.get("dropped_beside_discovery") for s in out["selection_steps"])
