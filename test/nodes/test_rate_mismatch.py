"""A 240 Hz stream analysed with a 120 Hz session: the nodes measure the rate, use it and say so.

Before, the live residual was 7 N m and h_online ran to its bound with nothing in the
logs. Now rider_state and torque_estimator measure the frame rate from the first frames, publish a
diagnostics ERROR naming both rates, and run their filters at the measured rate, so the states
equal the core's at 240 Hz and the residual is back at its noise floor.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

from euc_ros.core.session import save_session  # noqa: E402
from euc_ros.ros.convert import ERROR  # noqa: E402
from euc_ros.testing import load_module  # noqa: E402

pytestmark = pytest.mark.ros


H = load_module(Path(__file__).with_name("helpers.py"), "node_helpers")


@pytest.fixture(scope="module")
def ride240(tmp_path_factory):
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.session import default_session

    session = dataclasses.replace(default_session("z"), rate_hz=240.0)
    result = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=3, duration_s=3.0, session=session))
    d = tmp_path_factory.mktemp("rate")
    wrong = dataclasses.replace(result.session, rate_hz=120.0)
    save_session(wrong, d / "session_120.yaml")
    return result.runs[0].mocap, result.session, d / "session_120.yaml"


def _statuses(pipe, name):
    return [st for a in pipe.diag for st in a.status if st.name == name]


def test_rate_mismatch_is_an_error_naming_both_rates_and_the_measured_rate_is_used(pipes, ros_context, ride240):
    series, session240, wrong_file = ride240
    rs = H.rider_node(ros_context, wrong_file, diagnostics_period=0.1)
    te = H.torque_node(ros_context, wrong_file, diagnostics_period=0.1, rmse_window_s=1.0)
    pipe = pipes([rs, te])
    pipe.feed(H.frame_msgs(series))
    assert rs.rate_gate.meter.rate_hz == pytest.approx(240.0, rel=1e-6)
    # the states are the core's at the true rate
    want = H.core_states(series, session240)
    got = {H.stamp_ns(m.header.stamp): m for m in pipe.states}
    assert set(got) == set(want) and len(got) > 100
    for stamp, m in got.items():
        assert m.x_ddot == pytest.approx(want[stamp].x_ddot, rel=1e-9, abs=1e-9)
    # the live residual is at its noise floor (it was 7 N m with the 120 Hz time step)
    r = np.array([m.residual for m in pipe.torques])
    assert r.size > 100 and np.sqrt(np.mean(r**2)) < 1.0
    for name in ("rider_state: states", "torque_estimator: torques"):
        pipe.spin_until(lambda n=name: any(st.level == ERROR for st in _statuses(pipe, n)),
                        what=f"an ERROR from {name}")
        msg = next(st.message for st in _statuses(pipe, name) if st.level == ERROR)
        assert "240" in msg and "120" in msg and "rate_hz" in msg, msg


def test_a_matching_rate_is_no_error(pipes, ros_context, ride240, tmp_path):
    series, session240, _ = ride240
    save_session(session240, tmp_path / "s.yaml")
    rs = H.rider_node(ros_context, tmp_path / "s.yaml", diagnostics_period=0.1)
    pipe = pipes([rs])
    pipe.feed(H.frame_msgs(series, frames=range(200)))
    pipe.settle(0.3)
    assert rs.rate_gate.meter.error is None and rs.rate_gate.meter.rate_hz == 240.0
    assert all(st.level != ERROR for st in _statuses(pipe, "rider_state: states"))


def test_a_stream_shorter_than_the_measurement_is_not_lost(pipes, ros_context, ride240, tmp_path):
    """Frames held for the rate are released by a timer when the stream stops early."""
    series, session240, _ = ride240
    save_session(session240, tmp_path / "s.yaml")
    rs = H.rider_node(ros_context, tmp_path / "s.yaml", rate_measure_s=5.0, window_s=0.1, polyorder=2)
    pipe = pipes([rs])
    n = 60
    for m in H.frame_msgs(series, frames=range(n)):
        pipe.frame_pub.publish(m)
    pipe.spin_until(lambda: len(pipe.states) > 0, timeout_s=10.0, what="held frames released")
    want = H.core_states(series, session240, frames=range(n), window_s=0.1, polyorder=2)
    pipe.spin_until(lambda: len(pipe.states) >= len(want), what="all states")
    assert {H.stamp_ns(m.header.stamp) for m in pipe.states} == set(want)
