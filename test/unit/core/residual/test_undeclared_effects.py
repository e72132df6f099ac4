"""Recordings with an effect the analysis is not told about must be traced to that effect.

Every family at two plausible magnitudes, plus three controls (no effect over several seeds, the
undetectable wheel-body friction, two effects at once). Each must be named (or ``none``), its
parameters recovered within 25 %, and the held-out RMSE after at most 0.6 of the RMSE before or at its
noise floor.
The recordings come from the ride simulator (which shares no model code with the analysis); the
scenarios live in :mod:`studies.campaign`, which also writes the README table.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from euc_ros.core.residual.selector import DEFAULT_ALPHA

# the experiment harnesses live in studies/ at the repository root, outside the package
sys.path.insert(0, str(Path(__file__).resolve().parents[4]))
from studies.campaign import CONTROLS, SCENARIOS, run_scenario, verdict  # noqa: E402

pytestmark = pytest.mark.slow


#: Scenarios the analysis does not yet meet, with what was measured (strict: a pass is news, and fails here).
KNOWN_SHORT = {
    "wheel_radius_error-0.03": "named, but h after 0.596 m against 0.61 (the criterion: 1 cm): "
                               "the residual's fixed 1.2 s filter biases h more than the effect's h shift",
}


@pytest.mark.parametrize("scenario", [pytest.param(s, id=s.name, marks=pytest.mark.xfail(
    strict=True, reason=KNOWN_SHORT[s.name])) if s.name in KNOWN_SHORT else pytest.param(s, id=s.name)
    for s in SCENARIOS])
def test_undeclared_effect_is_found(scenario):
    out = run_scenario(scenario)
    ok, problems = verdict(scenario, out)
    assert ok, f"{problems}; top candidates: {out['candidates'][:3]}"


@pytest.mark.parametrize("seed", [11, 23, 37])
def test_no_effect_gives_none(seed):
    out = run_scenario(CONTROLS[0], seed=seed)
    assert out["effect"] == "none", out["selection_steps"]
    assert out["significance_level"] == DEFAULT_ALPHA


def test_wheel_body_friction_is_reported_undetectable():
    out = run_scenario(CONTROLS[1])
    assert verdict(CONTROLS[1], out)[0], out["effect"]
    assert "wheel_body_friction" in out["undetectable"]


def test_no_effect_in_aggressive_turns_names_no_library_effect():
    """The planar model in 29-deg turns leaves held-out structure (README limits): discovered or
    unexplained may be reported, a library effect never."""
    out = run_scenario(CONTROLS[3])
    assert set(out["effect"].split("+")) <= {"none", "discovered", "unexplained"}, out["selection_steps"]


def test_two_effects_at_once():
    out = run_scenario(CONTROLS[2])
    ok, problems = verdict(CONTROLS[2], out)
    assert ok, problems
    assert len(out["effect"].split("+")) == 2
