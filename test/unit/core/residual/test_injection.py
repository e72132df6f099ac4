"""The residual analysis takes its selection and its discovery as objects (constructor injection).

On a ride with a hidden 3 deg slope: the default selector names ground_slope; a selector that refuses every
candidate leaves the effect ``none`` (without discovery and without a noise floor nothing else can judge the
residual); a discovery given its own basis searches that basis only, and a custom discovery object is the one
the analysis calls.
"""
# covers: euc_ros/core/residual/analysis.py
# covers: euc_ros/core/residual/discovery.py
# covers: euc_ros/core/residual/records.py
# covers: euc_ros/core/residual/result.py
# covers: euc_ros/core/residual/selector.py
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.analysis import analyze
from euc_ros.core.residual.discovery import Discovery, GroupSparseDiscovery, discover_terms
from euc_ros.core.residual.families import FAMILIES, Family
from euc_ros.core.residual.records import Selection
from euc_ros.core.residual.search import GroupSearch
from euc_ros.core.residual.selector import ForwardSelector, Selector
from euc_ros.core.ridesim.effects import EffectSet
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.kinematics import reconstruct_states

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def slope_ride():
    res = simulate_ride(RideConfig(maneuver="deceleration", runs=3, seed=5,
                                   effects=EffectSet({"ground_slope": {"alpha_deg": 3.0}})))
    states = [reconstruct_states(r.mocap, res.session) for r in res.runs]
    return states, EucParams.from_session(res.session)


class RefuseAll(Selector):
    """A selection that names nothing."""

    def select(self, setup, stage, remaining, screening, journal, say):
        return Selection(stage, None)


class Recorded(Discovery):
    """The default discovery, recording each call."""

    def __init__(self):
        self.calls = 0

    def discover(self, current, current_x, recs, folds, h0, current_ho, h_geometric=float("nan")):
        self.calls += 1
        return discover_terms(current, current_x, recs, folds, h0, current_ho, h_geometric)


def test_the_default_selector_object_names_the_slope(slope_ride):
    states, params = slope_ride
    out = analyze(states, params, selector=ForwardSelector(alpha=0.01, min_gain=0.1, max_effects=3),
                  discovery=False).to_json()
    assert out["effect"] == "ground_slope", out["selection_steps"]


def test_a_selector_that_refuses_everything_names_nothing(slope_ride):
    states, params = slope_ride
    out = analyze(states, params, selector=RefuseAll(), discovery=None).to_json()
    assert out["effect"] == "none" and out["selection_steps"] == [], out["effect"]
    assert out["discovery"] == {"run": False}
    # the slope is still there: the base model's held-out RMSE is what is left
    assert out["rmse_after_nm"] == out["rmse_before_nm"]


def test_the_discovery_searches_the_basis_it_is_given_and_the_object_passed_is_called(slope_ride):
    states, params = slope_ride
    speed = tuple(f for f in FAMILIES if f.kind == "speed")
    out = analyze(states, params, selector=RefuseAll(),
                  discovery=GroupSparseDiscovery(families=speed, search=GroupSearch(max_groups=1))).to_json()
    assert out["discovery"]["run"] and set(out["discovery"]["families"]) <= {f.key for f in speed}
    assert len(out["discovery"]["heldout_rmse_by_terms"]) <= 2       # no groups, and at most one
    recorded = Recorded()
    out = analyze(states, params, selector=RefuseAll(), discovery=recorded).to_json()
    assert recorded.calls == 1 and out["discovery"]["run"]


@pytest.fixture(scope="module")
def drag_ride():
    """A quadratic drag at the rider's CoG (C_d A = 2 m^2: 1.2 N per (m/s)^2, 16 N at the ride's 3.7 m/s)."""
    res = simulate_ride(RideConfig(maneuver="deceleration", runs=3, seed=5,
                                   effects=EffectSet({"aero_drag": {"cda_m2": 2.0}})))
    states = [reconstruct_states(r.mocap, res.session) for r in res.runs]
    return states, EucParams.from_session(res.session)


def test_a_family_of_the_users_functions_finds_a_hidden_force(drag_ride):
    """Only the user's family is searched (a custom selector names nothing): its x_dot |x_dot| columns explain
    the hidden drag (held-out error cut by more than 3/4, with the drag's sign), and a family of the wrong shape
    (a lab-fixed ripple) is not adopted and leaves the error as it was."""
    states, params = drag_ride
    quadratic = Family.custom("velocity squared", "x_dot",
                              lambda v, level: np.stack([v * np.abs(v), v][:level + 1], axis=1), levels=2)
    ripple = Family.custom("lab ripple", "lab_x",
                           lambda x, level: np.stack([np.sin(2 * np.pi * x / 0.37), np.cos(2 * np.pi * x / 0.37)], 1))
    found = analyze(states, params, selector=RefuseAll(),
                    discovery=GroupSparseDiscovery(families=(quadratic,), search=GroupSearch(max_groups=1))).to_json()
    assert found["effect"] == "discovered" and found["discovery"]["families"] == [quadratic.key]
    assert found["rmse_after_nm"] < 0.25 * found["rmse_before_nm"], (found["rmse_before_nm"], found["rmse_after_nm"])
    term, = found["discovered"]
    assert term["family"] == "velocity squared" and term["argument_unit"] == "m/s"
    values = np.asarray(term["values"], float).ravel()
    grid = np.asarray(term["grid"], float)
    assert grid.min() > 0 and np.all(values < 0), "drag opposes the (forward) motion at every speed"
    assert abs(values[-1]) > abs(values[0]), "and grows with speed"
    wrong = analyze(states, params, selector=RefuseAll(),
                    discovery=GroupSparseDiscovery(families=(ripple,), search=GroupSearch(max_groups=1))).to_json()
    assert wrong["effect"] == "none" and not wrong["discovered"]
    assert wrong["rmse_after_nm"] == wrong["rmse_before_nm"]


def test_a_users_family_is_checked_when_it_is_made():
    with pytest.raises(ConfigError, match="argument"):
        Family.custom("f", "speed", lambda x, level: x[:, None])
    with pytest.raises(ConfigError, match="basis"):
        Family.custom("f", "x_dot", lambda x, level: x)                  # one-dimensional columns
    with pytest.raises(ConfigError, match="basis"):
        Family.custom("f", "x_dot", lambda x, level: 1.0 / x[:, None])   # not finite where x = 0
