"""`euc-ros steer` (simulator, controller, recorder as processes).

The lockstep run read back from the bag must end where the in-process simulation ends (< 1 mm).

Tolerances: the bag holds the float64 states and inputs of the lockstep run; the in-process
reference integrates the same equations with the same steps, but the report's numbers pass through
JSON and the input is recomputed from messages: 1e-6 (m, rad, N m) is far above their round-off
(~1e-12) and far below any real difference; times 1e-12 s.
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.core.unicycle.dynamics import UnicycleParams
from euc_ros.core.unicycle.linearize import straight_rolling_state
from euc_ros.core.unicycle.simulate import maneuver_metrics, simulate
from euc_ros.core.unicycle.steering import SteeringController

pytestmark = [pytest.mark.ros, pytest.mark.integration]

REPORT_KEYS = {"maneuver", "speed_m_per_s", "final_lateral_error_m", "final_yaw_error_rad", "max_abs_u_n",
               "max_tilt_rad", "max_tilt_deg", "status", "gains", "closed_loop_roots", "sim_time_s", "wall_time_s"}


@pytest.mark.timeout(90)
@pytest.mark.parametrize("maneuver, speed", [("lane_change", 1.0), ("turn", 5.0)])
def test_steer_over_topics_matches_in_process_simulation(ros_domain, tmp_path, capsys, maneuver, speed):
    from euc_ros.cli.main import main

    out = tmp_path / "run"
    report_path = tmp_path / "report.json"
    extra = []
    if maneuver == "turn":           # a bag left by an earlier run is replaced with --overwrite
        (out / "bag").mkdir(parents=True)
        (out / "bag" / "metadata.yaml").write_text("stale")
        (out / "bag" / "bag_0.mcap").write_bytes(b"stale")
        extra = ["--overwrite"]
    code = main(["steer", "--maneuver", maneuver, "--speed", str(speed), "--out", str(out),
                 "--json", str(report_path), *extra])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "final lateral error" in printed and "max |u|" in printed

    # the bag, read back independently of the command's own parser
    bag = out / "bag"
    assert check_bag(bag) == []
    states = {}
    commands = {}
    for topic, _, _, msg in read_bag(bag):
        if topic == "/unicycle/state":
            states.setdefault(msg.step, msg)
        elif topic == "/unicycle/command":
            commands.setdefault(msg.step, msg)
    assert sorted(states) == list(range(1001)), "states lost over topics"
    assert set(range(1000)) <= set(commands)
    final = states[1000]
    assert final.status == "ok"
    assert final.header.stamp.sec == 10 and final.header.stamp.nanosec == 0

    # the same maneuver in process (core simulate, same dt)
    p = UnicycleParams()
    ctrl = SteeringController(p, maneuver, speed)
    ref = simulate(p, ctrl, straight_rolling_state(p, speed), 10.0, 0.01)
    gap = float(np.hypot(final.x_g - ref.x[-1, 8], final.y_g - ref.x[-1, 9]))
    assert gap < 1e-3, f"over topics ends {gap:.3e} m from the in-process run"
    travelled = float(np.hypot(ref.x[-1, 8], ref.x[-1, 9]))
    assert travelled > 7.0 * speed          # it actually drove (10 s at speed; the turn cuts a corner)
    u_bag = np.array([commands[k].u for k in range(1000)])
    np.testing.assert_allclose(u_bag, ref.u, rtol=0, atol=1e-6)

    # the report
    report = json.loads(report_path.read_text())
    assert REPORT_KEYS <= set(report)
    met = maneuver_metrics(ref, ctrl)
    assert report["maneuver"] == maneuver and report["speed_m_per_s"] == speed
    assert report["status"] == "ok" and report["sim_time_s"] == pytest.approx(10.0)
    assert report["final_lateral_error_m"] == pytest.approx(met.final_lateral_error, abs=1e-6)
    assert report["final_yaw_error_rad"] == pytest.approx(met.final_yaw_error, abs=1e-6)
    assert report["max_abs_u_n"] == pytest.approx(met.max_abs_u, rel=1e-6)
    assert report["max_tilt_rad"] == pytest.approx(met.max_abs_tilt, rel=1e-6)
    assert report["max_tilt_deg"] == pytest.approx(np.degrees(met.max_abs_tilt), rel=1e-6)
    assert list(report["gains"]) == list(ctrl.gains.names)
    assert report["gains"]["P_psi"] == pytest.approx(float(ctrl.gains.K[4]))
    assert len(report["closed_loop_roots"]) == 10
    assert report["wall_time_s"] > 0 and report["real_time_factor"] > 0
    if maneuver == "lane_change":
        assert abs(report["final_lateral_error_m"]) < 1e-3
    png = Path(report["png"])
    assert png == out / f"steer_{maneuver}_{speed:g}.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000


def test_steer_rejects_ill_conditioned_speed_before_starting_anything(tmp_path, capsys):
    from euc_ros.cli.main import main

    code = main(["steer", "--maneuver", "turn", "--speed", "100", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "key 'speed'" in err[0] and "well conditioned" in err[0]
    assert not (tmp_path / "o").exists()


def test_steer_refuses_an_existing_bag(tmp_path, capsys):
    from euc_ros.cli.main import main

    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "notes.txt").write_text("mine")
    assert main(["steer", "--maneuver", "turn", "--speed", "1", "--out", str(tmp_path)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert main(["steer", "--maneuver", "turn", "--speed", "1", "--out", str(tmp_path), "--overwrite"]) == 2
    assert "not a bag directory" in capsys.readouterr().err
    assert (tmp_path / "bag" / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("speed", ["100.0", "0.0"])
def test_controller_process_exits_with_one_line_and_code_2(ros_domain, tmp_path, speed):
    exe = Path(sys.executable).parent / "steering_controller"
    r = subprocess.run([str(exe), "--ros-args", "-p", f"speed:={speed}"], capture_output=True, text=True,
                       timeout=60, cwd=tmp_path)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("steering_controller: error: key 'steering_controller.ros__parameters.speed'")


def test_bag_reader_dedupes_resent_states_and_rejects_lost_steps(tmp_path):
    from rclpy.serialization import serialize_message

    from euc_ros.core.errors import InputError
    from euc_ros.core.io.bags import BagWriter
    from euc_ros.lockstep import steer_result_from_bag
    from euc_ros.ros.convert import unicycle_state_to_msg as state_to_msg

    def write(path, steps):
        with BagWriter(path) as w:
            for i, k in enumerate(steps):
                x = np.arange(10.0) + k
                msg = state_to_msg(x, 0.5 * k, k, int(k * 0.01 * 1e9), "ok")
                w.write_raw("/unicycle/state", "euc_msgs/msg/UnicycleState", serialize_message(msg), 1000 + i)

    write(tmp_path / "good", [0, 0, 1, 2, 2, 3])        # resent states 0 and 2
    result, log_ns = steer_result_from_bag(tmp_path / "good", 0.01)
    np.testing.assert_array_equal(result.x[:, 0], [0, 1, 2, 3])
    np.testing.assert_array_equal(result.u, [0.5, 1.0, 1.5])    # u of state k+1 is the input of step k
    np.testing.assert_allclose(result.t, [0, 0.01, 0.02, 0.03], atol=1e-12)
    assert list(log_ns) == [1000, 1002, 1003, 1005]        # first copy of each step
    write(tmp_path / "gap", [0, 1, 3])
    with pytest.raises(InputError, match="not contiguous"):
        steer_result_from_bag(tmp_path / "gap", 0.01)
