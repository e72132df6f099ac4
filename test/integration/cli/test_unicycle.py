"""`euc-ros unicycle` in-process: gains JSON, steady states, stability figures, simulate, errors."""
from __future__ import annotations

import json

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.unicycle import steering as sg

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("maneuver, names", [("lane_change", sg.GAIN_NAMES["lane_change"]),
                                             ("turn", sg.GAIN_NAMES["turn"])])
def test_gains_json(params, tmp_path, capsys, maneuver, names):
    out = tmp_path / "g" / "gains.json"
    assert main(["unicycle", "gains", "--maneuver", maneuver, "--speed", "5", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    ref = sg.steering_gains(params, maneuver, 5.0)
    assert [k for k in data if k in sg.GAIN_UNITS] == list(names)
    assert ("P_y" in data) == (maneuver == "lane_change")
    assert np.allclose([data[n] for n in names], ref.K, rtol=1e-12)
    roots = np.array(data["closed_loop_roots"])
    assert roots.shape == (10, 2)
    assert np.sum(np.hypot(*roots.T) < 1e-6) == 10 - len(names)
    assert "D_theta" in capsys.readouterr().out


def test_gains_other_model_and_pole(tmp_path):
    out = tmp_path / "g.json"
    assert main(["unicycle", "gains", "--maneuver", "turn", "--speed", "2", "--pole", "-4", "--point-mass", "8",
                 "--radius", "0.4", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    nonzero = [complex(*z) for z in data["closed_loop_roots"] if abs(complex(*z)) > 1e-6]
    assert len(nonzero) == 5 and max(abs(z + 4) for z in nonzero) < 0.1 and data["pole"] == -4.0


@pytest.mark.parametrize("argv, key", [
    (["--maneuver", "turn", "--speed", "0"], "speed"),
    (["--maneuver", "lane_change", "--speed", "100"], "speed"),
    (["--maneuver", "turn", "--speed", "1", "--pole", "3"], "pole"),
    (["--maneuver", "turn", "--speed", "1", "--point-mass", "0"], "m0"),
    (["--maneuver", "turn", "--speed", "1", "--radius", "-0.3"], "R"),
])
def test_gains_errors_exit_2(capsys, argv, key):
    assert main(["unicycle", "gains", *argv]) == 2
    err = capsys.readouterr().err
    assert f"key '{key}'" in err and err.count("\n") == 1


def test_steady_states_json(tmp_path, capsys):
    out = tmp_path / "s.json"
    assert main(["unicycle", "steady-states", "--json", str(out)]) == 0
    s = json.loads(out.read_text())
    assert s["unicycle_critical_speed"] == pytest.approx(1.2130539971493437)
    assert s["critical_tilt_angle_deg"] == pytest.approx(18.6236, abs=1e-3)
    assert [c["rank"] for c in s["controllability"]] == [6, 6]
    assert [c["output_rank"] for c in s["controllability"]] == [{"lane_change": 6, "turn": 5}] * 2
    assert [c["open_loop_stable"] for c in s["controllability"]] == [False, True]
    assert "1.2131 m/s" in capsys.readouterr().out


def test_stability_figures(tmp_path):
    assert main(["unicycle", "stability", "--out", str(tmp_path), "--grid", "24"]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["fig3_wheel_stability.png", "fig5_unicycle_steady_states.png", "fig6_unicycle_stability.png"]
    for p in tmp_path.iterdir():
        assert p.read_bytes()[:8] == PNG_MAGIC and p.stat().st_size > 10_000


def test_simulate_json_and_plot(tmp_path, capsys):
    out, png = tmp_path / "m.json", tmp_path / "run.png"
    assert main(["unicycle", "simulate", "--maneuver", "turn", "--speed", "5", "--json", str(out),
                 "--plot", str(png)]) == 0
    m = json.loads(out.read_text())
    assert m["status"] == "ok" and abs(m["final_yaw_error"]) < 1e-4 and m["target"] == pytest.approx(-np.pi / 2)
    assert png.read_bytes()[:8] == PNG_MAGIC
    assert "status ok" in capsys.readouterr().out


def test_simulate_domain_exit_and_infeasible_target(tmp_path, capsys):
    # a 60 deg left turn at 20 m/s needs more tilt than 5 deg: stops with a status, exit code 1
    out = tmp_path / "m.json"
    rc = main(["unicycle", "simulate", "--maneuver", "turn", "--speed", "20", "--target", "60", "--max-tilt", "5",
               "--json", str(out)])
    assert rc == 1 and json.loads(out.read_text())["status"] == "tilt_limit"
    assert main(["unicycle", "simulate", "--maneuver", "lane_change", "--speed", "1", "--target", "-10"]) == 2
    assert "key 'target'" in capsys.readouterr().err
