"""`identify_h`: h with its interval as one library call, the same numbers ``euc-ros identify`` writes."""
# covers: euc_ros/core/identify/options.py
# covers: euc_ros/core/states/load.py
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.identify.budget import parse_tolerances
from euc_ros.core.identify.cog_height import HIdentification, identify_h
from euc_ros.core.identify.fit import fit_h
from euc_ros.core.identify.options import IntervalOptions
from euc_ros.core.model.terms import EucParams
from euc_ros.core.ridesim.simulate import DEFAULT_H_M, RideConfig, simulate_ride
from euc_ros.core.ridesim.writers import write_ride
from euc_ros.core.session import load_session
from euc_ros.core.states.kinematics import reconstruct_states
from euc_ros.core.states.load import load_states
from euc_ros.core.states.settings import ReconstructionSettings


@pytest.fixture(scope="module")
def ride():
    """Three 7 s decelerations with the paper's noise (the truth: h = 0.61 m)."""
    return simulate_ride(RideConfig(runs=3, seed=4))


@pytest.fixture(scope="module")
def states(ride):
    out = []
    for r in ride.runs:
        st = reconstruct_states(r.mocap, ride.session)
        st.meta["series"] = r.mocap          # the interval's biases reconstruct the poses again
        out.append(st)
    return out


@pytest.fixture(scope="module")
def ident(ride, states) -> HIdentification:
    return identify_h(states, ride.session, uncertainty=IntervalOptions(with_budget=False))


def test_h_with_its_interval_contains_the_truth(ident):
    assert ident.identifiable is True and ident.reason == ""
    lo, hi = ident.interval
    assert lo < ident.h < hi
    assert lo <= DEFAULT_H_M <= hi
    assert abs(ident.h - DEFAULT_H_M) < 0.03


def test_the_data_h_is_the_grid_fit_of_the_3dof_model(ride, states, ident):
    params = EucParams.from_session(ride.session)
    assert ident.combined.h_data_m == fit_h(states, params).pooled["3dof"].h_m == ident.fits.pooled["3dof"].h_m
    assert ident.model == "3dof"


def test_result_is_frozen_and_serialises(ident):
    with pytest.raises(dataclasses.FrozenInstanceError):
        ident.h = 0.0
    data = json.loads(ident.to_json())
    assert data == json.loads(json.dumps(ident.to_dict()))
    assert data["model"] == "3dof" and data["identifiable"] is True
    assert data["h_ci95_m"] == [pytest.approx(v) for v in ident.interval]
    assert "uncertainty" in data and "h_std_formal_m" in data


def test_without_uncertainty_no_interval(ride, states):
    quick = identify_h(states, ride.session, uncertainty=None)
    assert quick.identifiable is None and quick.uncertainty is None
    assert all(np.isnan(v) for v in quick.interval)
    assert "h_ci95_m" not in quick.to_dict()


def test_an_extended_model_heads_the_document(ride, states):
    ext = identify_h(states, ride.session, uncertainty=None, effects={"rolling_resistance": {"c_rr": 0.0}})
    assert ext.model == "3dof+rolling_resistance"
    assert ext.to_dict()["model"] == "3dof+rolling_resistance"
    # a zero-strength effect changes nothing: the extended fit equals the paper's
    assert ext.fits.pooled["3dof+rolling_resistance"].h_m == pytest.approx(ext.h, abs=1e-6)


def test_the_command_writes_what_the_library_returns(ride, tmp_path):
    write_ride(ride, tmp_path / "ride")
    session_file = tmp_path / "ride" / "session.yaml"
    csvs = sorted(str(p) for p in (tmp_path / "ride").glob("*.csv"))
    out = tmp_path / "identify.json"
    # the library call below uses the fixed filter, so the command is given the same
    assert main(["identify", str(session_file), *csvs, "--json", str(out), "--no-progress", "--no-sliding-bias",
                 "--window-s", "1.2"]) == 0
    written = json.loads(out.read_text())
    session = load_session(session_file)
    states = load_states(session, csvs, ReconstructionSettings(window_s=1.2, polyorder=6), keep_series=True)
    lib = json.loads(json.dumps(identify_h(
        states, session, uncertainty=IntervalOptions(sliding=False, tolerances=parse_tolerances([]))).to_dict()))
    for key in ("h_m", "rmse_nm", "h_ci95_m", "identifiable", "identifiability_reason", "uncertainty", "h_std_m",
                "h_range_m", "uncertainty_budget"):
        assert written[key] == lib[key], key


def test_no_recording_is_a_clear_error_not_a_crash():
    import tempfile
    from pathlib import Path

    from euc_ros.core.errors import InputError
    from euc_ros.core.identify.pipeline import identify_recordings
    from euc_ros.core.session import default_session, save_session

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "session.yaml"
        save_session(default_session(), path)
        with pytest.raises(InputError) as e:
            identify_recordings(path, [])
    assert "no recording given" in str(e.value) and "recordings" in str(e.value)
