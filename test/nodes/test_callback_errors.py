"""The callback boundary of a live node (:class:`euc_ros.ros.runtime.CallbackErrors`), in-process.

An input that raises the project's own error (:class:`~euc_ros.core.errors.EucError`) is dropped with a
warning and counted (``errors``); any other exception is a bug: logged at ERROR with its traceback and
counted apart (``unexpected_errors``). Either way the node keeps running and publishes on the next good
input. The log records are read back from ``/rosout``.
"""
from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("rclpy")

from euc_msgs.msg import RiderState  # noqa: E402
from rcl_interfaces.msg import Log  # noqa: E402

from euc_ros.core.errors import InputError  # noqa: E402
from euc_ros.core.online.estimators import TorqueEstimator  # noqa: E402
from euc_ros.core.session import default_session, save_session  # noqa: E402
from euc_ros.ros import convert  # noqa: E402
from euc_ros.testing import load_module  # noqa: E402

pytestmark = pytest.mark.ros

H = load_module(Path(__file__).with_name("helpers.py"), "node_helpers")
T = load_module(Path(__file__).with_name("test_torque_estimator.py"), "callback_errors_torque_helpers")

BASE = dict(x=0.0, x_dot=3.0, x_ddot=-1.0, gamma=0.02, gamma_dot=0.0, gamma_ddot=0.1, phi=-0.1, phi_dot=0.05,
            phi_ddot=0.2, phi_eq3=-0.12, phi_hinge=-0.1, psi=0.0, theta=0.0, filter_lag=0.45)


@pytest.fixture
def session_file(tmp_path):
    path = tmp_path / "session.yaml"
    save_session(default_session(), path)
    return path


def state_msgs(n: int) -> list[RiderState]:
    """``n`` usable RiderState messages at 120 Hz."""
    out = []
    for k in range(n):
        m = RiderState(has_rider=True, phi_definition="hinge", **BASE)
        m.header.stamp.sec, m.header.stamp.nanosec = 1000, k * 8_333_333
        out.append(m)
    return out


def rosout(pipe, node_name: str) -> list[Log]:
    """Subscribe the pipe's probe to ``/rosout``; the records of ``node_name`` collect in the returned list."""
    logs: list[Log] = []
    pipe.probe.create_subscription(Log, "/rosout", lambda m: logs.append(m) if m.name == node_name else None, 100)
    return logs


def diag_values(pipe, name: str) -> dict[str, str]:
    return {kv.key: kv.value for a in pipe.diag for st in a.status if st.name == name for kv in st.values}


def test_bad_input_is_warned_a_bug_is_logged_with_its_traceback_and_the_node_runs_on(
        pipes, ros_context, session_file, monkeypatch):
    # the core raises the project's error on the 7th state and an unexpected RuntimeError on the 9th
    real_update, calls = TorqueEstimator.update, []

    def update(self, state):
        calls.append(state.t)
        if len(calls) == 7:
            raise InputError("state out of the model's domain", key="gamma")
        if len(calls) == 9:
            raise RuntimeError("a bug in the estimator")
        return real_update(self, state)

    monkeypatch.setattr(TorqueEstimator, "update", update)
    te = T.torque_node(ros_context, session_file, diagnostics_period=0.05)
    pipe = pipes([te])
    logs = rosout(pipe, te.get_logger().name)
    msgs = state_msgs(12)
    pipe.feed_states(msgs)

    # both states dropped, each counted where it belongs; every other state gave its torque
    assert te.drops.errors == 1 and te.drops.unexpected == 1 and te.errors == 1
    published = {T.stamp_ns(m.header.stamp) for m in pipe.torques}
    stamps = [T.stamp_ns(m.header.stamp) for m in msgs]
    assert published == set(stamps) - {stamps[6], stamps[8]}
    assert stamps[7] in published and stamps[9] in published         # the next good state after each
    T.assert_all_finite(pipe.torques)

    pipe.spin_until(lambda: any(m.level == Log.ERROR for m in logs) and any(m.level == Log.WARN for m in logs),
                    what="the warning and the error on /rosout")
    warning = next(m.msg for m in logs if m.level == Log.WARN and "state dropped" in m.msg)
    assert "InputError" in warning and "key 'gamma'" in warning and "Traceback" not in warning
    error = next(m.msg for m in logs if m.level == Log.ERROR)
    assert error.startswith("state dropped: unexpected error")
    assert "Traceback (most recent call last)" in error and "RuntimeError: a bug in the estimator" in error

    # a diagnostics message from before the last state may arrive first: wait for one that counts everything
    pipe.spin_until(lambda: (diag_values(pipe, "torque_estimator: torques").get("unexpected_errors"),
                             diag_values(pipe, "torque_estimator: torques").get("published")) == ("1", "10"),
                    what="diagnostics counting the unexpected error and every published torque")
    vals = diag_values(pipe, "torque_estimator: torques")
    assert vals["errors"] == "1" and vals["published"] == "10"


def test_bytes_that_are_no_mocap_frame_are_bad_input_not_a_bug(pipes, ros_context, session_file):
    rs = H.rider_node(ros_context, session_file)
    pipe = pipes([rs])
    logs = rosout(pipe, rs.get_logger().name)
    pipe.wait_matched()
    pipe.frame_pub.publish(b"\x00\x01\x00\x00" + b"\xff" * 8)        # little-endian CDR, truncated
    pipe.spin_until(lambda: rs.counts["errors"] == 1, what="the frame to be dropped")
    assert rs.counts["unexpected_errors"] == 0 and rs.counts["frames"] == 1
    pipe.spin_until(lambda: any(m.level == Log.WARN and "frame dropped" in m.msg for m in logs),
                    what="the warning on /rosout")
    assert not any(m.level >= Log.ERROR for m in logs)


def test_bytes_no_reader_can_read_are_an_input_error():
    bad = b"\x00\x01\x00\x00" + b"\xff" * 8
    with pytest.raises(InputError, match="12 bytes that are not a MocapFrame"):
        convert.raw_to_frame(bad)
    with pytest.raises(InputError, match="12 bytes that are not a RiderState"):
        convert.deserialize(bad, RiderState)
