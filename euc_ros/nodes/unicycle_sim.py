"""Node ``unicycle_sim``: the autonomous unicycle (steering paper, eq (36)) integrated step by step.

The physics is :class:`euc_ros.core.unicycle.simulate.UnicycleSimulator` (zero-order hold on ``u``,
``substeps`` RK4 steps per control period ``dt``); this module only wires ROS. Two modes:

* ``lockstep`` (deterministic): the node publishes state ``k`` (``step = k``, stamped with the
  simulated time ``k dt``), waits for the ``SteeringCommand`` whose ``step`` is ``k``, applies its
  ``u`` for one period and publishes state ``k + 1``. Wall-clock timing cannot change the result:
  with the same ``dt`` and ``substeps`` the run equals the in-process
  :func:`~euc_ros.core.unicycle.simulate.simulate`. Before step 0 the node waits until the
  controller (and ``wait_observers`` recorders) have subscribed; a state left unanswered for
  ``resend_period`` is published again (the controller answers duplicates with its cached command).
* ``realtime``: a wall timer of period ``dt / rate_factor`` steps with the latest command (``u = 0``
  before the first) and publishes ``/clock`` (``rosgraph_msgs/Clock``) with the simulated time, so
  other nodes may run with ``use_sim_time``.

A step that leaves the model's domain stops the simulation: the state carrying the status
(``tilt_limit``, ``mass_below_ground`` or ``non_finite``, never a NaN state) is published and no
further steps are taken. After ``duration`` simulated seconds, or such a stop, the node waits until
its reliable messages are acknowledged, lingers ``linger`` seconds (so a recorder takes the last
messages) and, with ``exit_when_done``, exits: code 0 after the full duration, 1 after a domain stop.
"""
from __future__ import annotations

import math
import time

from euc_msgs.msg import SteeringCommand, UnicycleState
from geometry_msgs.msg import PoseStamped
from rclpy.duration import Duration
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from tf2_msgs.msg import TFMessage

from euc_ros.core.errors import ConfigError
from euc_ros.core.unicycle.dynamics import UnicycleParams
from euc_ros.core.unicycle.linearize import straight_rolling_state
from euc_ros.core.unicycle.simulate import STATUS_OK, UnicycleSimulator, wheel_pose
from euc_ros.ros import convert
from euc_ros.ros import interfaces as itf
from euc_ros.ros.matching import MatchGate
from euc_ros.ros.params import ParamSpec, declare_params
from euc_ros.ros.runtime import main_for

_DEFAULTS = UnicycleParams()

SPECS = (
    ParamSpec("mode", "lockstep", "lockstep: each step waits for the command of that step (deterministic); "
              "realtime: a wall timer steps with the latest command and publishes /clock",
              choices=("lockstep", "realtime")),
    ParamSpec("dt", 0.01, "control period: one step, input held constant over it", "s", 1e-4, 1.0),
    ParamSpec("substeps", 5, "RK4 steps per control period", "", 1, 1000),
    ParamSpec("duration", 10.0, "simulated time after which the simulation ends (0: never)", "s", 0.0, 1e6),
    ParamSpec("speed", 1.0, "initial straight-rolling speed v = R phi_dot* of the wheel centre", "m/s", 1e-6, 100.0),
    ParamSpec("initial_tilt", 0.0, "initial tilt theta added to straight rolling", "rad", -1.5, 1.5),
    ParamSpec("max_tilt", math.radians(80.0), "the simulation stops with status tilt_limit at this |theta|", "rad",
              1e-3, 1.57),
    ParamSpec("wheel_mass", _DEFAULTS.m, "wheel mass m (Table I)", "kg", 1e-6, 1e6),
    ParamSpec("point_mass", _DEFAULTS.m0, "point mass m0 sliding on the axle (Table I)", "kg", 1e-6, 1e6),
    ParamSpec("radius", _DEFAULTS.R, "wheel radius R (Table I)", "m", 1e-6, 100.0),
    ParamSpec("gravity", _DEFAULTS.g, "gravitational acceleration g", "m/s^2", 0.0, 1000.0),
    ParamSpec("rate_factor", 1.0, "realtime mode: simulated seconds per wall second", "", 0.01, 1000.0),
    ParamSpec("wait_observers", 0, "subscribers besides the controller (e.g. a recorder) whose subscriptions to "
              "unicycle/state and unicycle/pose must have matched before step 0", "", 0, 100),
    ParamSpec("resend_period", 0.5, "lockstep: publish the current state again after this long without an "
              "answer", "s", 0.01, 60.0),
    ParamSpec("linger", 0.5, "time to keep running after the end so subscribers take the last messages", "s",
              0.0, 3600.0),
    ParamSpec("exit_when_done", True, "exit after the end (code 0; 1 if the state left the model's domain)"),
    ParamSpec("publish_pose", True, "publish the wheel pose on unicycle/pose"),
    ParamSpec("publish_tf", True, "publish frame_id -> child_frame_id on /tf"),
    ParamSpec("frame_id", "world", "world frame of the pose and TF (REP-103/105)"),
    ParamSpec("child_frame_id", "unicycle", "TF frame of the wheel body"),
)

#: Period of the start-up, resend and end checks [s].
CHECK_PERIOD_S = 0.05
#: Longest wait for the acknowledgement of the last messages [s].
ACK_TIMEOUT_S = 2.0


class UnicycleSim(Node):
    """Simulate the autonomous unicycle, in lockstep with the controller or in real time.

    ===========  ======================  ===============================  =================================
    direction    topic                   type                             QoS / when
    ===========  ======================  ===============================  =================================
    Subscribes   ``unicycle/command``    euc_msgs/SteeringCommand         LOCKSTEP_QOS
    Publishes    ``unicycle/state``      euc_msgs/UnicycleState           LOCKSTEP_QOS, every step
    Publishes    ``unicycle/pose``       geometry_msgs/PoseStamped        LOCKSTEP_QOS (``publish_pose``): G
                                                                      and the wheel body (``wheel_pose``)
    Publishes    ``/tf``                 frame_id -> child_frame_id       as the pose (``publish_tf``)
    Publishes    ``/clock``              rosgraph_msgs/Clock              realtime mode only
    ===========  ======================  ===============================  =================================

    Parameters: :data:`SPECS` (mode, step, duration, initial state, the model's Table I, start-up and end).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ``namespace``...).

    Attributes
    ----------
    sim : UnicycleSimulator
        The integrator (``sim.x``, ``sim.t``, ``sim.steps``, ``sim.status``).
    n_steps : int or None
        Steps until the end (``round(duration / dt)``; None with ``duration`` 0).
    done : bool
        True once the simulation has ended (duration reached or domain left).
    resent, ignored : int
        States published again because no answer came (lockstep); commands ignored (wrong step, non-finite).
    """

    NAME = "unicycle_sim"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = cfg = declare_params(self, SPECS)
        self.params = UnicycleParams(m=cfg["wheel_mass"], m0=cfg["point_mass"], R=cfg["radius"], g=cfg["gravity"])
        x0 = straight_rolling_state(self.params, cfg["speed"])
        x0[3] = cfg["initial_tilt"]
        try:
            self.sim = UnicycleSimulator(self.params, x0, cfg["dt"], max_tilt=cfg["max_tilt"],
                                         substeps=cfg["substeps"])
        except ConfigError as exc:
            raise ConfigError(exc.detail, key=f"{self.NAME}.ros__parameters.{exc.key}") from None
        self.lockstep = cfg["mode"] == "lockstep"
        self.n_steps = max(1, int(round(cfg["duration"] / cfg["dt"]))) if cfg["duration"] > 0 else None
        self.done = self.sim.status != STATUS_OK
        self.resent = self.ignored = 0
        self._u = 0.0                       # input of the last step (published with the state)
        self._u_latest = 0.0                # realtime: latest command
        self._started = False
        self.start_gate = MatchGate(self._wanted_matches)
        self._sent_at = 0.0
        self._done_at: float | None = None
        self._last_msg: UnicycleState | None = None
        self.state_pub = self.create_publisher(UnicycleState, itf.UNICYCLE_STATE, itf.LOCKSTEP_QOS)
        self.pose_pub = (self.create_publisher(PoseStamped, itf.UNICYCLE_POSE, itf.LOCKSTEP_QOS)
                         if cfg["publish_pose"] else None)
        self.tf_pub = self.create_publisher(TFMessage, itf.TF, itf.RELIABLE_QOS) if cfg["publish_tf"] else None
        self.clock_pub = None if self.lockstep else self.create_publisher(Clock, itf.CLOCK, itf.CLOCK_QOS)
        self.command_sub = self.create_subscription(SteeringCommand, itf.STEERING_COMMAND, self._on_command,
                                                    itf.LOCKSTEP_QOS)
        self.create_timer(CHECK_PERIOD_S, self._check)
        if not self.lockstep:
            self._step_timer = self.create_timer(cfg["dt"] / cfg["rate_factor"], self._realtime_tick)
        self.get_logger().info(
            f"{cfg['mode']} simulation, dt {cfg['dt']:g} s x {cfg['substeps']} RK4 substeps, "
            f"{'until stopped' if self.n_steps is None else f'{self.n_steps} steps'}, start at "
            f"{cfg['speed']:g} m/s, tilt {cfg['initial_tilt']:g} rad")

    # -- start-up --------------------------------------------------------------------------------
    def _wanted_matches(self) -> list[tuple[str, int, int]]:
        """Before step 0: the controller (lockstep) and ``wait_observers`` observers, as DDS matches."""
        obs = self.config["wait_observers"]
        want = [(itf.UNICYCLE_STATE + " subscriptions", self.state_pub.get_subscription_count(),
                 obs + (1 if self.lockstep else 0))]
        if self.lockstep:   # our reader must have matched the controller's writer (the answers must get through)
            want.append((itf.STEERING_COMMAND + " publishers", self.command_sub.get_publisher_count(), 1))
        if self.pose_pub is not None:
            want.append((itf.UNICYCLE_POSE + " subscriptions", self.pose_pub.get_subscription_count(), obs))
        return want

    def _waiting(self, missing: list[str]) -> None:
        self.get_logger().info("waiting for matches: " + ", ".join(missing), throttle_duration_sec=5.0)

    # -- stepping --------------------------------------------------------------------------------
    def _publish_state(self) -> None:
        sim = self.sim
        stamp_ns = int(round(sim.t * 1e9))
        x = sim.x
        self._last_msg = convert.unicycle_state_to_msg(x, self._u, sim.steps, stamp_ns, sim.status,
                                                       self.config["frame_id"])
        self.state_pub.publish(self._last_msg)
        self._sent_at = time.monotonic()
        if self.pose_pub is not None or self.tf_pub is not None:
            pos, quat = wheel_pose(x, self.params)
            if self.pose_pub is not None:
                self.pose_pub.publish(convert.pose_stamped(stamp_ns, self.config["frame_id"], pos, quat))
            if self.tf_pub is not None:
                self.tf_pub.publish(TFMessage(transforms=[convert.transform_stamped(
                    stamp_ns, self.config["frame_id"], self.config["child_frame_id"], pos, quat)]))
        if self.clock_pub is not None:
            self.clock_pub.publish(Clock(clock=convert.ns_to_stamp(stamp_ns)))

    def _advance(self, u: float) -> None:
        """Apply ``u`` for one period, publish the new state, and end when done or out of the domain."""
        _, status = self.sim.step(u)
        self._u = float(u)
        self._publish_state()
        if status != STATUS_OK or (self.n_steps is not None and self.sim.steps >= self.n_steps):
            self._finish()

    def _finish(self) -> None:
        self.done = True
        self._done_at = time.monotonic()
        st = self.sim.status
        self.get_logger().info(f"simulation ended at t = {self.sim.t:.3f} s after {self.sim.steps} steps: {st}"
                               + (f" ({self.resent} states resent)" if self.resent else ""))

    def _on_command(self, msg: SteeringCommand) -> None:
        if self.done or not self._started:
            return
        if not math.isfinite(msg.u):
            self.ignored += 1   # the simulator would stop with non_finite; a bad command is dropped instead
            self.get_logger().warning(f"ignoring non-finite command for step {msg.step}", throttle_duration_sec=5.0)
            return
        if not self.lockstep:
            self._u_latest = float(msg.u)
            return
        if msg.step != self.sim.steps:
            self.ignored += 1   # a duplicate answer to an older state
            return
        self._advance(msg.u)

    def _realtime_tick(self) -> None:
        if self._started and not self.done:
            self._advance(self._u_latest)

    def _check(self) -> None:
        now = time.monotonic()
        if not self._started:
            if self.start_gate.ready(now, self._waiting):
                self._started = True
                self._publish_state()
                if self.done:       # the initial state is already outside the domain
                    self._finish()
            return
        if not self.done:
            if self.lockstep and now - self._sent_at >= self.config["resend_period"] and self._last_msg is not None:
                self.state_pub.publish(self._last_msg)
                self._sent_at = now
                self.resent += 1
                self.get_logger().info(f"no command for step {self.sim.steps} yet: state resent",
                                       throttle_duration_sec=2.0)
            return
        if self.config["exit_when_done"] and now >= self._done_at + self.config["linger"]:
            self._exit()

    def _exit(self) -> None:
        for pub in (self.state_pub, self.pose_pub, self.tf_pub):
            if pub is not None:
                pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT_S))
        raise SystemExit(0 if self.sim.status == STATUS_OK else 1)


main = main_for(UnicycleSim)
