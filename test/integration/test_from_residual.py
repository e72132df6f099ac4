"""``identify --from-residual`` applies a residual result only to the data it was made from, and says when
the extended model fits worse than the model it extends.

The residual JSONs here are written by hand in the recording format (the contract), with ``inputs`` from
the files; what they claim is known: a 2.5 deg ground slope, on a ride that has it and on one that has not.
"""
from __future__ import annotations

import json
import warnings

import pytest

import euc_ros
from euc_ros.api import ModelFitWarning
from euc_ros.cli.main import main
from euc_ros.core.io.provenance import inputs_record


@pytest.fixture(scope="module")
def rides(tmp_path_factory):
    """A flat ride and a ride on a 2.5 deg slope (one 7 s deceleration each, the same rider)."""
    from euc_ros.core.ridesim.effects import EffectSet
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    out = {}
    for name, effects in (("flat", EffectSet()), ("slope", EffectSet({"ground_slope": {"alpha_deg": 2.5}}))):
        folder = tmp_path_factory.mktemp(name)
        write_ride(simulate_ride(RideConfig(runs=1, seed=5, effects=effects)), folder)
        out[name] = folder
    return out


def _residual_json(path, session, recordings, alpha_deg=2.5):
    data = {"h_m": 0.3, "rmse_before_nm": 7.0, "effect": "ground_slope", "effect_parameters": {"alpha_deg": alpha_deg},
            "rmse_after_nm": 0.3, "h_after_m": 0.6, "candidates": [], "inputs": inputs_record(session, recordings)}
    path.write_text(json.dumps(data))
    return path


def _identify(ride, residual, *extra):
    return main(["identify", str(ride / "session.yaml"), str(ride / "deceleration_01.csv"), "--from-residual",
                 str(residual), "--no-uncertainty", "--no-progress", *extra])


def test_a_residual_of_other_recordings_is_refused_in_one_line(rides, tmp_path, capsys):
    slope = rides["slope"]
    residual = _residual_json(tmp_path / "r.json", slope / "session.yaml", [slope / "deceleration_01.csv"])
    other = rides["flat"]
    code = main(["identify", str(slope / "session.yaml"), str(other / "deceleration_01.csv"), "--from-residual",
                 str(residual), "--no-uncertainty", "--no-progress"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "r.json" in err[0] and "deceleration_01.csv is not among the recordings" in err[0] and "--force" in err[0]


def test_a_residual_of_another_session_is_refused(rides, tmp_path, capsys):
    slope = rides["slope"]
    session = tmp_path / "session.yaml"
    session.write_text((slope / "session.yaml").read_text().replace("mass: ", "mass: 1", 1))
    residual = _residual_json(tmp_path / "r.json", session, [slope / "deceleration_01.csv"])
    assert _identify(slope, residual) == 2
    assert "it was made with the session" in capsys.readouterr().err


def test_force_applies_it_with_a_warning(rides, tmp_path, capsys):
    slope = rides["slope"]
    residual = _residual_json(tmp_path / "r.json", slope / "session.yaml", [rides["flat"] / "deceleration_01.csv"])
    assert _identify(slope, residual, "--force") == 0
    assert "applied anyway: --force" in capsys.readouterr().err


def test_the_extended_model_that_fits_worse_is_said(rides, tmp_path, capsys):
    flat = rides["flat"]
    residual = _residual_json(tmp_path / "r.json", flat / "session.yaml", [flat / "deceleration_01.csv"])
    out = tmp_path / "h.json"
    assert _identify(flat, residual, "--json", str(out)) == 0
    data = json.loads(out.read_text())
    ext, base = data["models"]["3dof+ground_slope"]["rmse_nm"], data["models"]["3dof"]["rmse_nm"]
    assert ext > base
    said = [w for w in data["warnings"] if "fits these recordings worse" in w]
    assert said and "3dof+ground_slope" in said[0]
    assert "fits these recordings worse" in capsys.readouterr().err
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        euc_ros.identify(flat / "session.yaml", flat / "deceleration_01.csv", from_residual=residual, uncertainty=False)
    assert any(w.category is ModelFitWarning for w in caught)


def test_the_extended_model_that_belongs_is_not_warned_about(rides, tmp_path):
    slope = rides["slope"]
    residual = _residual_json(tmp_path / "r.json", slope / "session.yaml", [slope / "deceleration_01.csv"])
    out = tmp_path / "h.json"
    assert _identify(slope, residual, "--json", str(out)) == 0
    data = json.loads(out.read_text())
    assert data["models"]["3dof+ground_slope"]["rmse_nm"] < data["models"]["3dof"]["rmse_nm"]
    assert not [w for w in data["warnings"] if "fits these recordings worse" in w]
    assert data["inputs"]["recordings"][0]["path"].endswith("deceleration_01.csv")
