"""unicycle_sim and steering_controller in process: lockstep loop, realtime mode, domain stop.

Each test runs the real nodes in its own rclpy Context with a single-threaded executor; the test's
own node plays the part of the missing peer (an observer or a controller that answers ``u = 0``).

Tolerances: the nodes run the same core code as the in-process reference on the same doubles
(messages carry float64), so they agree to the last bits: 1e-12 (1e-9 for the controller's input
over a whole run, where the order of additions of the integrated states may differ by an ulp per step).
"""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

pytestmark = pytest.mark.ros

rclpy = pytest.importorskip("rclpy")

from euc_msgs.msg import SteeringCommand, UnicycleState  # noqa: E402
from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402

from euc_ros.core.errors import ConfigError  # noqa: E402
from euc_ros.core.rotations import rotate  # noqa: E402
from euc_ros.core.unicycle.dynamics import UnicycleParams  # noqa: E402
from euc_ros.core.unicycle.linearize import straight_rolling_state  # noqa: E402
from euc_ros.core.unicycle.simulate import (  # noqa: E402
    UnicycleSimulator,
    simulate,
    wheel_pose,  # noqa: E402
)
from euc_ros.core.unicycle.steering import SteeringController, lane_change_reference, steering_gains  # noqa: E402
from euc_ros.nodes.steering_controller import SteeringControllerNode  # noqa: E402
from euc_ros.nodes.unicycle_sim import UnicycleSim  # noqa: E402
from euc_ros.ros import interfaces as itf  # noqa: E402
from euc_ros.ros.convert import msg_to_unicycle_state as msg_to_state  # noqa: E402
from euc_ros.ros.convert import unicycle_state_to_msg as state_to_msg  # noqa: E402


def _overrides(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


def _spin_until(executor, cond, timeout=20.0):
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, "condition not reached in time"
        executor.spin_once(timeout_sec=0.01)


class _Collector:
    def __init__(self, node, cls, topic, qos=itf.LOCKSTEP_QOS):
        self.msgs = []
        node.create_subscription(cls, topic, self.msgs.append, qos)


def test_lockstep_loop_in_process_equals_core_simulate(ros_context):
    """Sim + controller nodes over topics reproduce core simulate exactly (deterministic lockstep)."""
    speed, duration = 5.0, 3.0
    sim = UnicycleSim(context=ros_context, parameter_overrides=_overrides(
        speed=speed, duration=duration, exit_when_done=False, wait_observers=1, linger=0.0))
    ctrl = SteeringControllerNode(context=ros_context, parameter_overrides=_overrides(
        maneuver="lane_change", speed=speed, lane_offset=-1.0, maneuver_start=0.5, maneuver_duration=2.0,
        wait_observers=1))
    probe = rclpy.create_node("probe", context=ros_context)
    states = _Collector(probe, UnicycleState, itf.UNICYCLE_STATE)
    cmds = _Collector(probe, SteeringCommand, itf.STEERING_COMMAND)
    poses = _Collector(probe, PoseStamped, itf.UNICYCLE_POSE)
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (sim, ctrl, probe):
        ex.add_node(n)
    try:
        _spin_until(ex, lambda: sim.done and len(states.msgs) > 300 and len(poses.msgs) > 300)
        _spin_until(ex, lambda: len(states.msgs) == 301 and len(cmds.msgs) >= 300, timeout=5)
    finally:
        ex.shutdown()
        for n in (sim, ctrl, probe):
            n.destroy_node()

    p = UnicycleParams()
    core = SteeringController(p, "lane_change", speed, target=-1.0, start=0.5, duration=2.0)
    ref = simulate(p, core, straight_rolling_state(p, speed), duration, 0.01)
    x = np.array([msg_to_state(m) for m in states.msgs])
    assert [m.step for m in states.msgs] == list(range(301))            # no loss, no duplicate, in order
    assert all(m.status == "ok" for m in states.msgs)
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in states.msgs])
    np.testing.assert_array_equal(stamps, np.round(np.arange(301) * 0.01 * 1e9).astype(np.int64))  # t = k dt
    assert np.max(np.abs(x - ref.x)) < 1e-9                               # over topics == in process
    assert abs(ref.x[-1, 9] - ref.x[0, 9]) > 0.9                          # and it did change lane
    np.testing.assert_allclose([m.u for m in states.msgs[1:]], ref.u, rtol=0, atol=1e-9)
    # commands answer the state of their step, with the lane-change reference in the last output
    by_step = {c.step: c for c in cmds.msgs}
    for k in (0, 100, 150, 299):
        assert by_step[k].maneuver == "lane_change" and len(by_step[k].reference) == 6
        assert by_step[k].reference[-1] == pytest.approx(float(lane_change_reference(k * 0.01, -1.0, 0.5, 2.0)))
    assert ctrl.answered >= 300 and ctrl.duplicates == 0
    # the pose is the wheel centre at height R cos(theta)
    last = poses.msgs[-1].pose.position
    assert (last.x, last.y) == pytest.approx((x[-1, 8], x[-1, 9]), abs=1e-12)
    assert last.z == pytest.approx(p.R * math.cos(x[-1, 3]), abs=1e-12)


def test_controller_answers_duplicates_with_the_cached_command_and_ignores_stale(ros_context):
    speed = 1.0
    ctrl = SteeringControllerNode(context=ros_context, parameter_overrides=_overrides(maneuver="lane_change",
                                                                                      speed=speed))
    probe = rclpy.create_node("probe", context=ros_context)
    pub = probe.create_publisher(UnicycleState, itf.UNICYCLE_STATE, itf.LOCKSTEP_QOS)
    cmds = _Collector(probe, SteeringCommand, itf.STEERING_COMMAND)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(ctrl)
    ex.add_node(probe)
    p = UnicycleParams()
    rng = np.random.default_rng(6)
    x = straight_rolling_state(p, speed) + rng.normal(0, 0.02, 10)
    try:
        _spin_until(ex, lambda: ctrl._ready)
        t5 = 4.5   # mid-maneuver (2 s + 5 s / 2): y_des = -2.5 / 2 m
        pub.publish(state_to_msg(x, 0.0, 450, int(t5 * 1e9), "ok"))
        _spin_until(ex, lambda: len(cmds.msgs) == 1)
        pub.publish(state_to_msg(x, 0.0, 450, int(t5 * 1e9), "ok"))        # resent state
        pub.publish(state_to_msg(x, 0.0, 449, int(4.49e9), "ok"))          # stale
        pub.publish(state_to_msg(x, 0.0, 451, int(4.51e9), "tilt_limit"))  # the simulation stopped
        _spin_until(ex, lambda: ctrl.duplicates == 1 and ctrl.ignored == 2)
        _spin_until(ex, lambda: len(cmds.msgs) == 2, timeout=5)
    finally:
        ex.shutdown()
        ctrl.destroy_node()
        probe.destroy_node()
    assert ctrl.answered == 1
    first, again = cmds.msgs
    assert first.step == again.step == 450 and first.u == again.u
    # u = -K (C x - y_des(t)) with y = [omega1, theta, sigma, r, psi, y_G] (eq (61)) and K from the design
    K = steering_gains(p, "lane_change", speed).K
    y = x[[0, 3, 4, 5, 6, 9]]
    y_des = np.array([0, 0, 0, 0, 0, float(lane_change_reference(t5, -2.5))])
    assert first.u == pytest.approx(-K @ (y - y_des), rel=1e-12)
    assert first.reference[-1] == pytest.approx(-1.25)


def test_realtime_mode_falls_with_a_status_and_publishes_clock(ros_context):
    """Below the critical speed, uncontrolled, the unicycle falls: the node stops with a status, no NaN."""
    sim = UnicycleSim(context=ros_context, parameter_overrides=_overrides(
        mode="realtime", speed=0.5, initial_tilt=0.01, rate_factor=200.0, duration=0.0, exit_when_done=False,
        wait_observers=1, publish_pose=False))
    probe = rclpy.create_node("probe", context=ros_context)
    states = _Collector(probe, UnicycleState, itf.UNICYCLE_STATE)
    clocks = _Collector(probe, Clock, itf.CLOCK, 100)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(probe)
    try:
        _spin_until(ex, lambda: sim.done)
        _spin_until(ex, lambda: states.msgs and states.msgs[-1].status != "ok", timeout=5)
        for _ in range(20):
            ex.spin_once(timeout_sec=0.01)
        steps_at_stop = sim.sim.steps
        for _ in range(20):             # stopped: no further steps
            ex.spin_once(timeout_sec=0.01)
    finally:
        ex.shutdown()
        sim.destroy_node()
        probe.destroy_node()
    assert sim.sim.steps == steps_at_stop
    last = states.msgs[-1]
    assert last.status == "mass_below_ground"
    x = np.array([msg_to_state(m) for m in states.msgs])
    assert np.all(np.isfinite(x))
    # the same fall, stepped by hand with u = 0 (what realtime mode applies without commands)
    p = UnicycleParams()
    x0 = straight_rolling_state(p, 0.5)
    x0[3] = 0.01
    core = UnicycleSimulator(p, x0)
    while core.status == "ok":
        core.step(0.0)
    assert last.step == core.steps and core.t == pytest.approx(1.16, abs=0.01)
    np.testing.assert_allclose(msg_to_state(last), core.x, rtol=0, atol=1e-12)
    assert p.R * math.cos(last.theta) + last.r * math.sin(last.theta) <= 0          # eq (47): mass below ground
    # /clock carries the simulated time of the states
    assert clocks.msgs, "no /clock messages"
    c = clocks.msgs[-1].clock
    assert c.sec * 10**9 + c.nanosec == last.header.stamp.sec * 10**9 + last.header.stamp.nanosec


def test_lockstep_resends_unanswered_state_and_exits_with_status(ros_context):
    """No answer: step 0 is resent; wrong-step commands are ignored; a domain stop exits with code 1."""
    sim = UnicycleSim(context=ros_context, parameter_overrides=_overrides(
        speed=0.5, initial_tilt=0.01, resend_period=0.05, wait_observers=0, linger=0.0, publish_pose=False))
    probe = rclpy.create_node("probe", context=ros_context)
    states = _Collector(probe, UnicycleState, itf.UNICYCLE_STATE)
    pub = probe.create_publisher(SteeringCommand, itf.STEERING_COMMAND, itf.LOCKSTEP_QOS)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(probe)
    answered = set()

    def answer_zero():      # a controller that answers u = 0 once per step (after the resend test)
        for m in states.msgs:
            if m.step not in answered and m.status == "ok":
                answered.add(m.step)
                pub.publish(SteeringCommand(u=0.0, step=m.step))

    try:
        _spin_until(ex, lambda: len(states.msgs) >= 3)
        assert {m.step for m in states.msgs} == {0} and sim.resent >= 2
        pub.publish(SteeringCommand(u=0.0, step=7))          # not the step the simulator waits for
        pub.publish(SteeringCommand(u=float("nan"), step=0))  # non-finite: dropped
        _spin_until(ex, lambda: sim.ignored == 2)
        assert sim.sim.steps == 0
        with pytest.raises(SystemExit) as exc:
            _spin_until(ex, lambda: answer_zero() or False)
        assert exc.value.code == 1
    finally:
        ex.shutdown()
        sim.destroy_node()
        probe.destroy_node()
    assert sim.done and sim.sim.status == "mass_below_ground"
    assert np.all(np.isfinite(sim.sim.x))


def test_initial_state_outside_the_domain_is_published_with_its_status(ros_context):
    sim = UnicycleSim(context=ros_context, parameter_overrides=_overrides(
        mode="realtime", initial_tilt=1.45, wait_observers=1, exit_when_done=False, publish_pose=False))  # 83 > 80 deg
    probe = rclpy.create_node("probe", context=ros_context)
    states = _Collector(probe, UnicycleState, itf.UNICYCLE_STATE)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(probe)
    try:
        _spin_until(ex, lambda: len(states.msgs) == 1)
    finally:
        ex.shutdown()
        sim.destroy_node()
        probe.destroy_node()
    assert sim.done and sim.sim.steps == 0
    assert states.msgs[0].status == "tilt_limit" and states.msgs[0].theta == 1.45


def test_wheel_pose_axle_and_height():
    """Orientation Rz(psi) Rx(theta) Ry(phi): the axle y2 = (-sin psi cos theta, cos psi cos theta, sin theta)."""
    p = UnicycleParams()
    rng = np.random.default_rng(2)
    for _ in range(20):
        x = rng.normal(0, 1, 10)
        x[3] = rng.uniform(-1.2, 1.2)
        pos, q = wheel_pose(x, p)
        psi, th = x[6], x[3]
        axle = rotate(q, np.array([0.0, 1.0, 0.0]))
        np.testing.assert_allclose(axle, [-math.sin(psi) * math.cos(th), math.cos(psi) * math.cos(th), math.sin(th)],
                                   atol=1e-12)
        # the wheel's rolling direction: for phi = 0 body x is the forward axis x1 = (cos psi, sin psi, 0)
        _, q0 = wheel_pose(np.where(np.arange(10) == 7, 0.0, x), p)
        np.testing.assert_allclose(rotate(q0, np.array([1.0, 0.0, 0.0])), [math.cos(psi), math.sin(psi), 0.0],
                                   atol=1e-12)
        np.testing.assert_allclose(pos, [x[8], x[9], p.R * math.cos(th)], atol=0)
    # a positive tilt leans the top of the wheel to the right (-y1), as in the model (eq (73))
    _, q = wheel_pose(np.array([0, 0, 0, 0.3, 0, 0, 0, 0, 0, 0.0]), p)
    assert rotate(q, np.array([0.0, 0.0, 1.0]))[1] < 0


@pytest.mark.parametrize("override, key", [
    ({"speed": 100.0}, "steering_controller.ros__parameters.speed"),
    ({"speed": -1.0}, "steering_controller.ros__parameters.speed"),
    ({"pole": 2.0}, "steering_controller.ros__parameters.pole"),
    ({"lane_offset": -40.0}, "steering_controller.ros__parameters.lane_offset"),
    ({"maneuver": "slalom"}, "steering_controller.ros__parameters.maneuver"),
])
def test_controller_bad_design_names_the_parameter(ros_context, override, key):
    with pytest.raises(ConfigError) as exc:
        SteeringControllerNode(context=ros_context, parameter_overrides=_overrides(**override))
    assert exc.value.key == key


def test_state_fields_follow_the_state_of_eq_37():
    from euc_ros.core.unicycle.dynamics import STATE_NAMES
    from euc_ros.ros.convert import UNICYCLE_STATE_FIELDS

    assert tuple(n.lower() for n in STATE_NAMES) == UNICYCLE_STATE_FIELDS
    x = np.arange(10.0) + 0.5
    assert np.array_equal(msg_to_state(state_to_msg(x, 1.5, 3, 10**9, "ok")), x)
