"""The loop closed live: what ``euc-ros residual`` wrote goes into the pipeline launch file as it is.

A ride on a slope nobody declared; ``residual`` finds the slope and writes its JSON; ``pipeline.launch.xml
model:=residual.json`` streams a run through the pipeline (separate processes over DDS, a real MCAP
bag) with nothing typed by hand. The live residual must fall as it does offline: its RMS within 20 % of
the held-out RMSE after. A model made with another session file stops the launch with one line.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.io.bags import read_bag

pytestmark = [pytest.mark.ros, pytest.mark.integration, pytest.mark.slow]
LAUNCH = Path(__file__).resolve().parents[2] / "launch" / "pipeline.launch.xml"


def euc_ros(*args, timeout=240):
    return subprocess.run([sys.executable, "-m", "euc_ros.cli.main", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


@pytest.fixture(scope="module")
def found(tmp_path_factory):
    """The demo's ride (three decelerations on a 2.5 deg slope) and the residual JSON of it."""
    out = tmp_path_factory.mktemp("slope")
    r = euc_ros("simulate-ride", "--maneuver", "deceleration", "--runs", "3", "--seed", "7", "--effect",
                "ground_slope", "--param", "alpha_deg=2.5", "--out", out / "ride", "--no-progress")
    assert r.returncode == 0, r.stderr
    csvs = sorted((out / "ride").glob("deceleration_*.csv"))
    r = euc_ros("residual", out / "ride" / "session.yaml", *csvs, "--json", out / "residual.json", "--no-progress")
    assert r.returncode == 0, r.stderr
    return out, json.loads((out / "residual.json").read_text())


def test_the_residuals_json_runs_the_live_pipeline_and_the_live_residual_falls_as_offline(found, ros_domain):
    out, residual = found
    assert residual["effect"] == "ground_slope"
    bag = out / "live"
    r = euc_ros("launch", LAUNCH, f"session:={out / 'ride' / 'session.yaml'}", f"model:={out / 'residual.json'}",
                "source:=csv", f"csv_path:={out / 'ride' / 'deceleration_01.csv'}", "exit_when_done:=true",
                f"bag:={bag}", "start_delay:=6.0", "rate_factor:=2.0")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    torques = [msg for topic, _, _, msg in read_bag(bag) if topic.endswith("euc/torque") and msg.valid]
    assert len(torques) > 300
    assert {m.model for m in torques} == {"3dof+ground_slope"}
    assert torques[-1].h == pytest.approx(residual["h_after_m"], abs=1e-9)
    live = float(np.sqrt(np.mean(np.square([m.residual for m in torques]))))
    after = residual["rmse_after_nm"]
    assert abs(live - after) <= 0.2 * after, (live, after, residual["rmse_before_nm"])


def test_a_model_of_another_session_stops_the_launch_in_one_line(found, ros_domain, tmp_path):
    out, _ = found
    other = tmp_path / "session.yaml"
    other.write_text((out / "ride" / "session.yaml").read_text() + "\n# another rider's file\n")
    r = euc_ros("launch", LAUNCH, f"session:={other}", f"model:={out / 'residual.json'}", "source:=csv",
                f"csv_path:={out / 'ride' / 'deceleration_01.csv'}", "exit_when_done:=true", timeout=120)
    assert r.returncode != 0
    said = [ln for ln in (r.stdout + r.stderr).splitlines() if "it was made with the session" in ln]
    assert said and "residual.json" in said[0] and "model_force" in said[0], r.stdout[-2000:] + r.stderr[-2000:]
