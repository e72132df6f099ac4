"""The model an analysis JSON holds: h and effects split from the flat parameters, what cannot go live."""
from __future__ import annotations

import json

import pytest

from euc_ros.core.errors import InputError
from euc_ros.core.identify.model_file import effects_of, model_from_json, read_model_file


def test_each_effect_takes_its_own_parameters():
    flat = {"alpha_deg": 2.0, "c_rr": 0.01}
    assert effects_of("ground_slope+rolling_resistance+unexplained", flat) == {
        "ground_slope": {"alpha_deg": 2.0}, "rolling_resistance": {"c_rr": 0.01}}
    assert effects_of("none", {}) == {}


def test_a_missing_parameter_names_its_key():
    with pytest.raises(InputError, match="key 'effect_parameters.c_rr'"):
        effects_of("rolling_resistance", {"alpha_deg": 1.0}, path="r.json")


def test_a_residual_result_gives_the_final_models_h_and_what_cannot_go_live():
    data = {"effect": "ground_slope+discovered", "effect_parameters": {"alpha_deg": 1.5}, "h_m": 0.3,
            "h_after_m": 0.6, "rmse_before_nm": 5.0, "discovered": [{"name": "discovered_1", "formula": "-3 x_dot N"}],
            "geometry": {"floor": {"flat": False}}}
    model = model_from_json(data, "r.json")
    assert (model.h_m, model.base_h_m, model.name) == (0.6, 0.3, "3dof+ground_slope")
    assert model.assignments() == ["ground_slope.alpha_deg=1.5"]
    assert len(model.left_out) == 2 and "discovered_1" in model.left_out[0] and "floor" in model.left_out[1]


def test_an_identify_result_gives_its_h_and_its_effects(tmp_path):
    path = tmp_path / "h.json"
    path.write_text(json.dumps({"model": "3dof+rolling_resistance", "h_m": 0.58,
                                "settings": {"effects": {"rolling_resistance": {"c_rr": 0.02}}}}))
    model = read_model_file(path)
    assert (model.kind, model.h_m, model.effects) == ("identify", 0.58, {"rolling_resistance": {"c_rr": 0.02}})


def test_bad_files_name_the_file_and_where(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"effect": "ground_slope",\n "h_m": }')
    with pytest.raises(InputError, match=r"bad.json, line 2, column"):
        read_model_file(bad)
    bad.write_text('{"effect": "ground_slope", "effect_parameters": {"alpha_deg": 1}, "h_m": "tall"}')
    with pytest.raises(InputError, match="key 'h_m'"):
        read_model_file(bad)
    bad.write_text('{"rows": []}')
    with pytest.raises(InputError, match="euc-ros residual"):
        read_model_file(bad)
