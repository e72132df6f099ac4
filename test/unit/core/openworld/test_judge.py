"""Judging the open-world study: right library names, a ride's verdicts, the h interval, the per-family table."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from euc_ros.core.openworld import judge as J
from euc_ros.core.worldsim import forces as F


def _law(family: str, point: str = "contact", **params) -> F.ForceLaw:
    """A hand-made law: only the fields the judging reads."""
    return F.ForceLaw(family, F.Point(point), params=params)


# -- right names ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("law,names", [
    (_law("speed", parity="odd"), ("rolling_resistance", "viscous_friction", "aero_drag")),
    (_law("dynamic", "cog_x", input="speed", order=1), ("rolling_resistance", "viscous_friction", "aero_drag")),
    (_law("drift", "rider_x"), ("ground_slope",)),
    (_law("lab_field", "cog_x", multiplier="none"), ("ground_slope",)),
    (_law("drift", "cog_z"), ("rider_mass_error",)),
    (_law("speed", parity="even"), ()),
    (_law("dynamic", input="speed", order=2), ()),
    (_law("lab_field", multiplier="speed"), ()),
    (_law("wheel"), ()),
    (_law("drift", "pitch"), ()),
    (None, ()),
])
def test_right_library_names_by_hand(law, names):
    assert J.right_library_names(law) == names


# -- one ride ------------------------------------------------------------------------------------------------
def test_judge_reads_names_discoveries_and_families():
    law = F.draw_law(np.random.default_rng(0), "speed", R=0.21, track_m=(0.0, 8.0), duration=3.0, stature=1.75)
    law = dataclasses.replace(law, params={**law.params, "parity": "odd"})
    base = {"rmse_before_nm": 1.0, "rmse_after_nm": 0.4}
    j = J.judge({**base, "effect": "viscous_friction", "discovered": []}, "speed", law)
    assert j["right_name"] and not j["false_name"] and j["explained"]
    j = J.judge({**base, "effect": "ground_slope+discovered",
                 "discovered": [{"formula": "c x_dot", "point": "contact", "coordinate": "x"}]}, "speed", law)
    assert j["false_name"] and j["explained"] and j["family_match"] is None
    assert j["discovered"] == ["c x_dot (x at contact)"] and j["discovered_terms"] == 1
    j = J.judge({**base, "effect": "discovered", "discovered": [{"formula": "c t", "family": "time"}]}, "speed", law)
    assert j["family_match"] is False and not j["explained"] and j["discovered_families"] == ["drift"]
    j = J.judge({**base, "effect": "discovered", "discovered": [{"formula": "c v", "family": "Speed"}]}, "speed", law)
    assert j["family_match"] and j["explained"]
    j = J.judge({"rmse_before_nm": 1.0, "rmse_after_nm": 0.9, "effect": "none"}, "none", None)
    assert j["explained"] is None and not j["false_name"] and j["library_names"] == []


def test_a_right_name_that_cuts_too_little_is_not_explained():
    law = _law("drift", "cog_z")
    j = J.judge({"rmse_before_nm": 2.0, "rmse_after_nm": 1.5, "effect": "rider_mass_error"}, "drift", law)
    assert j["right_name"] and not j["false_name"] and j["ratio_measured"] == pytest.approx(0.75)
    assert j["explained"] is False
    j = J.judge({"rmse_before_nm": 2.0, "rmse_after_nm": 1.0, "effect": "rider_mass_error"}, "drift", law)
    assert j["explained"] is True
    # any name on a control ride is a false name
    j = J.judge({"rmse_before_nm": 2.0, "rmse_after_nm": 1.0, "effect": "ground_slope"}, "none", None)
    assert j["false_name"] and j["right_names"] == []


@pytest.mark.parametrize("ci,h,covered,width_mm", [
    ([0.60, 0.64], 0.61, True, 40.0),
    ([0.62, 0.64], 0.61, False, 20.0),          # misses below
    ([0.55, 0.60], 0.61, False, 50.0),          # misses above
    ([None, 0.64], 0.61, False, math.inf),      # an open end informs of nothing on its side: a miss
    ([None, 0.60], 0.61, False, math.inf),
    (None, 0.61, False, math.inf),              # no interval at all: unbounded, a miss
])
def test_judge_interval_counts_a_miss_as_a_miss(ci, h, covered, width_mm):
    v = J.judge_interval(ci, h)
    assert v["covered"] is covered
    assert v["width_mm"] == pytest.approx(width_mm)
    assert (v["h_after_lo_m"], v["h_after_hi_m"]) == tuple(ci or (None, None))


# -- the table -------------------------------------------------------------------------------------------------
def _row(task, family, *, covered=True, false_name=False, explained=True, names=(), width_mm=20.0, artefact_mm=0.5,
         status="ok"):
    return {"task": task, "family": family, "status": status, "error": None if status == "ok" else "boom",
            "artefact_mm": artefact_mm, "explained": None if family == "none" else explained,
            "false_name": false_name, "library_names": list(names), "covered": covered, "width_mm": width_mm,
            "floor_nm": 1.0, "rmse_before_nm": 2.0, "before_predicted_nm": 2.0, "ratio_design": 0.4,
            "ratio_measured": 0.5, "effect": names[0] if names else "none", "discovered_terms": 0}


def test_summarize_counts_against_the_goals():
    rows = [_row("none_0", "none"), _row("none_1", "none", covered=False, width_mm=math.inf, artefact_mm=5.0),
            _row("drift_0", "drift", names=("ground_slope",), explained=True),
            _row("drift_1", "drift", names=("aero_drag",), false_name=True, explained=False, width_mm=50.0),
            _row("drift_2", "drift", status="failed")]
    s = J.summarize(rows)
    assert list(s["families"]) == ["none", "drift"]
    assert s["failures"] == [{"task": "drift_2", "error": "boom"}]
    none, drift = s["families"]["none"], s["families"]["drift"]
    assert (none["n"], none["failed"], none["n_clean"]) == (2, 0, 1)
    assert none["coverage_pct"] == 50.0 and none["coverage_clean_pct"] == 100.0
    assert none["no_name_pct"] == 100.0 and none["explained_pct"] is None
    assert none["width_median_mm"] == math.inf                  # an unbounded interval counts as the largest
    assert none["goals_met"] == {"false_name": True, "coverage": False, "width_clean": True, "width_usual": False,
                                 "controls_no_name": True, "controls_none": True}
    assert none["none_pct"] == 100.0 and none["width_usual_median_mm"] == math.inf and none["n_usual"] == 2
    assert (drift["n"], drift["failed"]) == (2, 1)
    assert drift["false_name_pct"] == 50.0 and drift["explained_pct"] == 50.0
    assert drift["width_clean_median_mm"] == 35.0 and drift["effects"] == {"ground_slope": 1, "aero_drag": 1}
    assert drift["goals_met"] == {"false_name": False, "coverage": True, "width_clean": False, "width_usual": True,
                                  "explained": False, "explained_low_sliding": False}
    assert drift["explained_low_sliding_pct"] == 50.0 and drift["n_low_sliding"] == 2
    assert s["family_key"] is None and s["goals"] == J.GOALS


def test_median_skips_missing_values():
    assert J.median([None, float("nan"), 3.0, 1.0]) == 2.0
    assert J.median([None]) is None
