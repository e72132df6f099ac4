"""Frames Motive dropped (missing rows, the frame number jumping by 2) anywhere in a recording, the first
4 s included, and 2 % of them: identify and residual work from the files and find what the ride holds.
What can go wrong: the first stretch (before the first drop) setting the filter choice's spectral grid, or
stretches between drops too short for a whole Welch segment; either leaves no motion above the noise floor
and the ride refused. The rides' seeds were drawn at random, not chosen."""
from __future__ import annotations

import json

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.io.recordings import load_recording

H_TRUE = 0.61


@pytest.fixture(scope="module")
def ride(tmp_path_factory):
    d = tmp_path_factory.mktemp("dropped") / "ride"
    assert main(["simulate-ride", "--maneuver", "deceleration", "--runs", "4", "--seed", "4582", "--drop-rate", "0.002",
                 "--out", str(d), "--no-progress"]) == 0
    return d


def test_the_ride_drops_frames_inside_its_first_segment(ride):
    early = []
    for f in sorted(ride.glob("*.csv")):
        s = load_recording(str(f))
        jumps = np.flatnonzero(np.diff(s.frame) > 1)
        early.append(jumps.size > 0 and s.t[jumps[0]] - s.t[0] < 4.0)
    assert any(early)


def test_identify_and_residual_work_on_a_ride_with_dropped_frames(ride, tmp_path):
    csvs = sorted(str(p) for p in ride.glob("*.csv"))
    assert main(["identify", str(ride / "session.yaml"), *csvs, "--json", str(tmp_path / "id.json"),
                 "--no-progress"]) == 0
    assert main(["residual", str(ride / "session.yaml"), *csvs, "--json", str(tmp_path / "r.json"),
                 "--no-progress"]) == 0
    truth = json.loads((ride / "truth" / "truth.json").read_text())
    out = json.loads((tmp_path / "r.json").read_text())
    # the hidden effect (a rider inertia error) is named or left unexplained, never another library effect
    named = [n for n in out["effect"].split("+") if n not in ("none", "discovered", "unexplained")]
    assert named in ([], [truth["effect"]]), out["effect"]


def test_two_percent_of_the_frames_dropped_still_give_h(tmp_path):
    ride = tmp_path / "ride"
    assert main(["simulate-ride", "--maneuver", "deceleration", "--runs", "3", "--seed", "758", "--drop-rate", "0.02",
                 "--out", str(ride), "--no-progress"]) == 0
    s = load_recording(str(sorted(ride.glob("*.csv"))[0]))
    assert np.count_nonzero(np.diff(s.frame) > 1) > 0.01 * s.frame.size
    assert main(["identify", str(ride / "session.yaml"), *sorted(str(p) for p in ride.glob("*.csv")),
                 "--json", str(tmp_path / "id.json"), "--no-progress"]) == 0
    out = json.loads((tmp_path / "id.json").read_text())
    # 3 runs of 7 s: the per-run spread of h is ~4 mm (test_rates), so 2 cm is a 5-sigma bound
    assert out["identifiable"] and abs(out["h_m"] - H_TRUE) < 0.02, (out["h_m"], out["identifiable"])
