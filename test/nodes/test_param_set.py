"""``ros2 param`` on the nodes: every parameter readable; a set either takes effect
(the node reacts) or is refused with the reason.

ros2cli is not on PyPI; ``ros2 param get/set/describe`` are clients of the node's parameter services,
and the second test uses that client (rclpy's AsyncParameterClient) against a node in its own process.
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

import rclpy  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from euc_ros.nodes.monitor import Monitor  # noqa: E402
from euc_ros.testing import load_module  # noqa: E402

pytestmark = pytest.mark.ros


H = load_module(Path(__file__).with_name("helpers.py"), "node_helpers")


def test_a_live_threshold_is_used_at_the_next_report_and_others_are_refused_with_a_reason(ros_context):
    node = Monitor(context=ros_context)
    try:
        [ok] = node.set_parameters([Parameter("rmse_threshold_nm", value=2.5)])
        assert ok.successful and node.config["rmse_threshold_nm"] == 2.5
        [ok] = node.set_parameters([Parameter("max_phi_deg", value=12.0)])
        assert ok.successful and node.config["max_phi_deg"] == 12.0
        [no] = node.set_parameters([Parameter("period", value=0.5)])
        assert not no.successful and "read at start-up" in no.reason and "-p period:=" in no.reason
        assert node.config["period"] == 1.0
        [no] = node.set_parameters([Parameter("warn_fraction", value=1.5)])      # outside [0, 1]
        assert not no.successful and node.config["warn_fraction"] == 0.8
        # the report uses the new threshold: a residual RMSE of 3 N m is an ERROR (> 2 x 2.5 is not, > 2.5 WARN)
        from euc_ros.core.online import monitoring as mon

        h = mon.consistency_health(3.0, node.config["rmse_threshold_nm"], residual_nm=0.0, h_online_m=np.nan)
        assert h.level == mon.WARN
    finally:
        node.destroy_node()


def test_setting_h_changes_the_torques_from_the_next_state(pipes, ros_context, ride):
    series, session, path = ride
    rs = H.rider_node(ros_context, path)
    te = H.torque_node(ros_context, path, rmse_window_s=1.0, h_window_s=3.0)
    pipe = pipes([rs, te])
    frames = H.frame_msgs(series)
    half = len(frames) // 2
    pipe.feed(frames[:half])
    n_before = len(pipe.torques)
    [ok] = te.set_parameters([Parameter("h", value=0.5)])
    assert ok.successful
    pipe.feed(frames[half:])
    before, after = pipe.torques[:n_before], pipe.torques[n_before:]
    assert before and after
    assert {m.h for m in before} == {0.61} and {m.h for m in after} == {0.5}
    # M_d1 and M_d2 after the set are the core's with h = 0.5 on the same states (M_d1 depends on h
    # through the rider's moment; equal to round-off: same code, same doubles)
    want, _ = H.core_torques(pipe.states, session, h=0.5, rmse_window_s=1.0, h_window_s=3.0)
    got = {H.stamp_ns(m.header.stamp): m for m in after}
    common = sorted(set(got) & set(want))
    assert len(common) == len(after)
    np.testing.assert_allclose([got[k].m_d1 for k in common], [want[k].M_d1 for k in common], rtol=1e-12)
    np.testing.assert_allclose([got[k].m_d2 for k in common], [want[k].M_d2 for k in common], rtol=1e-12)
    [no] = te.set_parameters([Parameter("session_file", value="other.yaml")])
    assert not no.successful and "restart torque_estimator" in no.reason


def test_parameter_services_of_a_node_process_as_ros2_param_uses_them(ros_context):
    from rclpy.parameter_client import AsyncParameterClient

    proc = subprocess.Popen([str(Path(sys.executable).parent / "monitor")], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    client_node = rclpy.create_node("param_probe", context=ros_context)
    executor = rclpy.executors.SingleThreadedExecutor(context=ros_context)
    executor.add_node(client_node)

    def call(make, attempts=4, timeout=5.0):
        # a request sent before the service's reply writer has matched this client is lost (DDS discovery
        # is asymmetric): ask again, as ros2 param's own retries would
        for _ in range(attempts):
            future = make()
            executor.spin_until_future_complete(future, timeout_sec=timeout)
            if future.done():
                return future.result()
        pytest.fail(f"no answer from the parameter service after {attempts} requests")

    try:
        client = AsyncParameterClient(client_node, "monitor")
        t_end = time.monotonic() + 30
        while not client.services_are_ready() and time.monotonic() < t_end:
            executor.spin_once(timeout_sec=0.1)
        assert client.services_are_ready(), "monitor's parameter services did not appear"
        names = call(lambda: client.list_parameters([], 1)).result.names
        assert {"rmse_threshold_nm", "period", "warn_fraction"} <= set(names)         # ros2 param list
        described = call(lambda: client.describe_parameters(["rmse_threshold_nm", "period"])).descriptors
        assert "settable while running" in described[0].description                   # ros2 param describe
        assert "read at start-up" in described[1].description
        [ok] = call(lambda: client.set_parameters([Parameter("rmse_threshold_nm", value=3.0)])).results
        assert ok.successful                                                            # ros2 param set
        [value] = call(lambda: client.get_parameters(["rmse_threshold_nm"])).values             # ros2 param get
        assert value.double_value == 3.0
        [no] = call(lambda: client.set_parameters([Parameter("period", value=0.2)])).results
        assert not no.successful and "restart monitor" in no.reason
    finally:
        executor.shutdown()
        client_node.destroy_node()
        proc.send_signal(2)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, proc.stdout.read()[-2000:]
