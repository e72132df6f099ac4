"""The residual pipeline's pure steps: the final model's h combined with the segments' geometric h, and the
final model's identifiability verdict (the whole pipeline runs in test_held_h, test_session_reference and the
CLI tests)."""
from __future__ import annotations

import pytest

from euc_ros.core.identify.session_prior import Z95, combine
from euc_ros.core.residual.pipeline import final_identifiability, with_geometric_after

#: identify's combination on a ride: the data's h 0.80 m [0.70, 0.90], the geometric h 0.812 m, u 12 mm.
GEO = combine(0.80, (0.70, 0.90), 0.812, 0.012)


def _data(**over):
    data = {"h_after_m": 0.78, "h_after_ci95_m": [0.60, None], "effect": "ground_slope", "warnings": ["w0"],
            "diagnostics": {"other": 1}}
    data.update(over)
    return data


def test_the_final_h_joins_the_geometric_h_and_the_datas_own_goes_under_diagnostics():
    data = _data()
    out = with_geometric_after(data, GEO)
    comb = out["diagnostics"]["h_after_combined"]
    # the data's own final h and interval are kept, the geometric h is identify's
    assert comb["h_from_data_m"] == 0.78 and comb["h_from_data_ci95_m"] == [0.60, None]
    assert comb["h_geometric_m"] == 0.812 and comb["u_geometric_m"] == 0.012
    assert out["diagnostics"]["other"] == 1 and data["diagnostics"] == {"other": 1}    # the input is not changed
    # the data bound h below only, far from it: the upper end is the geometric h's, the lower end too (the data's
    # lower end lies below it); h is the geometric h's side of a flat likelihood, within a tenth of u
    lo, hi = out["h_after_ci95_m"]
    assert lo > 0.60 and hi < 0.812 + 3.1 * 0.012 and lo < 0.812 < hi
    assert out["h_after_m"] == pytest.approx(0.812, abs=0.1 * 0.012)
    assert lo <= out["h_after_m"] <= hi
    assert "warnings" not in out                     # they agree


def test_disagreement_keeps_both_in_the_interval_and_warns():
    out = with_geometric_after(_data(h_after_m=0.55, h_after_ci95_m=[0.53, 0.57]), GEO)
    lo, hi = out["h_after_ci95_m"]
    assert lo == pytest.approx(0.53) and hi == pytest.approx(0.812 + Z95 * 0.012)
    assert out["warnings"][0] == "w0" and out["warnings"][1].startswith("final model: the data's h (0.550 m)")


@pytest.mark.parametrize("data", [_data(h_held={"held": True}), _data(h_after_ci95_m=None), _data(h_after_m=None)])
def test_nothing_to_combine_changes_nothing(data):
    assert with_geometric_after(data, GEO) == {}
    assert with_geometric_after(_data(), None) == {}


def test_the_admissible_range_cuts_the_interval():
    out = with_geometric_after(_data(), GEO, admissible=[0.70, 0.82])
    lo, hi = out["h_after_ci95_m"]
    assert hi <= 0.82 + 1e-12 and lo >= 0.70


def test_final_identifiability_reads_the_datas_interval():
    assert final_identifiability({"h_after_ci95_m": [0.6, 0.7]})["h_after_identifiable"] is True
    v = final_identifiability({"h_after_ci95_m": [0.6, None]})
    assert v["h_after_identifiable"] is False and "not bounded" in v["h_after_identifiability_reason"]
    v = final_identifiability({"h_after_ci95_m": [0.1, 0.9]})
    assert v["h_after_identifiable"] is False and "cm wide" in v["h_after_identifiability_reason"]
    v = final_identifiability({"h_after_ci95_m": None, "identifiable": True, "identifiability_reason": None})
    assert v["h_after_identifiable"] is True
