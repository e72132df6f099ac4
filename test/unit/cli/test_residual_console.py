"""What ``euc-ros residual`` prints last and once: each warning one time, a refusal only in the verdict, and
the h to use (the final model's) with its verdict at the end, never the base model's."""
from __future__ import annotations

from euc_ros.cli.residual_report import base_status_text, console_warnings, headline_text

REFUSAL = "rolling_resistance not named: c_rr = 0.09 outside its plausible range [0, 0.05]"


def _data(**over):
    data = {"h_m": 0.3, "h_ci95_m": [None, None], "identifiable": False,
            "identifiability_reason": "too little excitation", "effect": "ground_slope", "h_after_m": 0.6,
            "h_after_ci95_m": [0.58, 0.62], "h_after_identifiable": True, "h_after_identifiability_reason": None,
            "refused": [{"text": REFUSAL, "rmse_after_nm": 1.0}],
            "warnings": ["run_01: only 40 % of the frames give usable states", "run_01: only 40 % of the frames "
                         "give usable states"],
            "analysis_warnings": [f"{REFUSAL} (it would cut the held-out RMSE 2.0 -> 1.0 N m)",
                                  "tied models imply h from 0.59 to 0.61 m"]}
    data.update(over)
    return data


def test_each_warning_once_and_a_refusal_only_in_the_verdict():
    assert console_warnings(_data()) == ["run_01: only 40 % of the frames give usable states",
                                         "tied models imply h from 0.59 to 0.61 m"]


def test_the_headline_is_the_final_models_h_and_says_how_to_run_it_live():
    text = headline_text(_data(), "residual.json", "session.yaml")
    assert text.startswith("h to use: 0.600 m, 95 % interval [0.58, 0.62] m (final model: ground_slope)")
    assert "model:=residual.json" in text and "0.300" not in text


def test_a_final_h_the_data_do_not_bound_is_not_offered_for_use():
    text = headline_text(_data(h_after_ci95_m=[0.58, None], h_after_identifiable=False,
                               h_after_identifiability_reason="its 95 % interval is not bounded"))
    assert "NOT identifiable" in text and "do not use it as h" in text and "h to use" not in text


def test_without_a_final_model_the_base_models_verdict_is_the_headline():
    text = headline_text(_data(h_after_ci95_m=None, effect="none", h_after_m=0.3, identifiable=True,
                               h_ci95_m=[0.28, 0.32], h_after_identifiable=True))
    assert text.startswith("h to use: 0.300 m") and "3-DoF, no effect" in text


def test_the_base_models_verdict_stands_beside_its_h():
    assert "base model: h NOT identifiable" in base_status_text(_data())
    assert "[0.28, 0.32]" in base_status_text(_data(identifiable=True, h_ci95_m=[0.28, 0.32]))


def test_a_held_h_is_the_one_to_use_and_says_so_once_with_its_number():
    from euc_ros.cli.residual_report import format_summary

    held = {"held": True, "h_m": 0.712, "std_m": 0.0065, "ci95_m": [0.699, 0.725],
            "reason": "the data do not bound h: its 95 % interval from the data is [unbounded, 0.300] m"}
    data = _data(h_m=0.712, h_after_m=0.712, h_ci95_m=[0.699, 0.725], h_after_ci95_m=[0.699, 0.725],
                 effect="none", effect_parameters={}, h_after_identifiable=False, h_held=held,
                 h_after_identifiability_reason="h is held: " + held["reason"], rmse_before_nm=0.3,
                 rmse_after_nm=0.3, held_out={"kind": "segments", "folds": 6}, candidates=[], h_range_m=[0.712, 0.712])
    text = headline_text(data)
    assert text.startswith("h to use: 0.712 m (held at the segments' geometric h") and "NOT identifiable" not in text
    lines = [line for line in format_summary(data).splitlines() if "held at the segments' geometric h" in line]
    assert len(lines) == 1 and "use h = 0.712 m" in lines[0] and "do not bound h" in lines[0]


def test_a_combined_final_h_is_the_one_to_use_and_says_what_it_rests_on():
    comb = {"h_m": 0.61, "ci95_m": [0.59, 0.63], "h_from_data_m": 0.55, "h_from_data_ci95_m": [0.3, None],
            "h_geometric_m": 0.612, "u_geometric_m": 0.008, "weight_data": 0.0}
    data = _data(h_after_m=0.61, h_after_ci95_m=[0.59, 0.63], h_after_identifiable=False,
                 h_after_identifiability_reason="its 95 % interval is not bounded",
                 diagnostics={"h_after_combined": comb})
    text = headline_text(data)
    assert text.startswith("h to use: 0.610 m (the final model's h from the data, 0.550 m, with the segments' "
                           "geometric h 0.612 m; the data carry 0 %; the data alone do not identify it: its 95 %")
    assert "[0.59, 0.63]" in text and "NOT identifiable" not in text
