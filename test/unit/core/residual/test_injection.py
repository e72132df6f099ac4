"""The residual analysis takes its selection and its discovery as objects (constructor injection).

On a ride with a hidden 3 deg slope: the default selector names ground_slope; a selector that refuses every
candidate leaves the effect ``none`` (without discovery and without a noise floor nothing else can judge the
residual); a discovery given its own basis searches that basis only, and a custom discovery object is the one
the analysis calls.
"""
from __future__ import annotations

import pytest

from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.analysis import analyze
from euc_ros.core.residual.discovery import Discovery, GroupSparseDiscovery, discover_terms
from euc_ros.core.residual.families import FAMILIES
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
