"""Node ``steering_controller``: output feedback ``u = -K (y - y_des(t))`` of the steering paper (eq (64)).

The gains are computed once, at start-up, by pole placement on the model linearised about
straight rolling at ``speed`` (:class:`euc_ros.core.unicycle.steering.SteeringController`; Tables II
and III for ``pole = -8``). The references are the consistent versions of eqs (66) and (71)
documented in ``docs/unicycle.md``: a cosine lane change to ``y_G = lane_offset`` and a cosine
turn to ``psi = turn_angle``, both between ``maneuver_start`` and ``maneuver_start +
maneuver_duration``.

Every ``UnicycleState`` is answered with one ``SteeringCommand`` carrying the same ``step`` and
stamp; the time of the reference is the state's stamp (the simulated time). A state the node has
already answered (the simulator resends a state left unanswered) gets the cached command again,
without recomputing; older states and states whose status is not ``ok`` are ignored. A step 0
after later steps is a restarted simulator and starts over.

Before the first answer the node waits until its command publisher has matched the simulator
and ``wait_observers`` more subscribers (e.g. a recorder), so nothing is lost at start-up.

A speed, pole or maneuver for which the design is impossible or ill-conditioned makes the node
exit at start-up with one line naming the parameter and code 2 (through
:func:`euc_ros.ros.runtime.run_node`).
"""
from __future__ import annotations

import math
import time

from euc_msgs.msg import SteeringCommand, UnicycleState
from rclpy.node import Node

from euc_ros.core.errors import ConfigError
from euc_ros.core.unicycle.dynamics import UnicycleParams
from euc_ros.core.unicycle.simulate import STATUS_OK
from euc_ros.core.unicycle.steering import MANEUVER_DURATION, MANEUVER_START, MANEUVERS, SteeringController
from euc_ros.ros import convert
from euc_ros.ros import interfaces as itf
from euc_ros.ros.matching import MatchGate
from euc_ros.ros.params import ParamSpec, declare_params
from euc_ros.ros.runtime import main_for

_DEFAULTS = UnicycleParams()

SPECS = (
    ParamSpec("maneuver", "lane_change", "reference to follow", choices=MANEUVERS),
    ParamSpec("speed", 1.0, "design speed v = R phi_dot* of the linearisation (straight rolling)", "m/s"),
    ParamSpec("pole", -8.0, "every non-zero closed-loop root is placed here", "1/s"),
    ParamSpec("lane_offset", 0.0, "lane change: final y_G (0: the paper's, -2.5 below the critical speed, "
              "-10 above)", "m"),
    ParamSpec("turn_angle", -math.pi / 2, "turn: final yaw psi (negative: a right turn)", "rad", -2 * math.pi,
              2 * math.pi),
    ParamSpec("maneuver_start", MANEUVER_START, "time at which the reference starts to change", "s", 0.0, 1e6),
    ParamSpec("maneuver_duration", MANEUVER_DURATION, "duration of the reference transition", "s", 1e-3, 1e6),
    ParamSpec("wait_observers", 0, "subscribers besides the simulator (e.g. a recorder) whose subscription to "
              "unicycle/command must have matched before the first answer", "", 0, 100),
    ParamSpec("wheel_mass", _DEFAULTS.m, "wheel mass m used for the design (Table I)", "kg", 1e-6, 1e6),
    ParamSpec("point_mass", _DEFAULTS.m0, "point mass m0 used for the design (Table I)", "kg", 1e-6, 1e6),
    ParamSpec("radius", _DEFAULTS.R, "wheel radius R used for the design (Table I)", "m", 1e-6, 100.0),
    ParamSpec("gravity", _DEFAULTS.g, "gravitational acceleration g used for the design", "m/s^2", 0.0, 1000.0),
)

#: Period of the start-up check [s].
CHECK_PERIOD_S = 0.02

#: Core ConfigError keys -> parameter names.
_KEYS = {"m": "wheel_mass", "m0": "point_mass", "R": "radius", "g": "gravity", "duration": "maneuver_duration"}


def build_controller(cfg: dict, node_name: str = "steering_controller") -> SteeringController:
    """The core controller for a parameter dict (:data:`SPECS` names); errors name the parameter.

    Raises
    ------
    ConfigError
        With key ``<node_name>.ros__parameters.<parameter>`` (e.g. ``speed`` where the gains are
        ill-conditioned, see :func:`euc_ros.core.unicycle.steering.steering_gains`).
    """
    try:
        params = UnicycleParams(m=cfg["wheel_mass"], m0=cfg["point_mass"], R=cfg["radius"], g=cfg["gravity"])
        if cfg["maneuver"] == "lane_change":
            target = cfg["lane_offset"] if cfg["lane_offset"] != 0.0 else None
        else:
            target = cfg["turn_angle"]
        return SteeringController(params, cfg["maneuver"], cfg["speed"], cfg["pole"], target=target,
                                  start=cfg["maneuver_start"], duration=cfg["maneuver_duration"])
    except ConfigError as exc:
        key = exc.key or "speed"
        if key == "target":
            key = "lane_offset" if cfg["maneuver"] == "lane_change" else "turn_angle"
        raise ConfigError(exc.detail, key=f"{node_name}.ros__parameters.{_KEYS.get(key, key)}") from None


class SteeringControllerNode(Node):
    """Answer every unicycle state with the steering force of the selected maneuver.

    ===========  =====================  ===========================  ==============================================
    direction    topic                  type                         what
    ===========  =====================  ===========================  ==============================================
    Subscribes   ``unicycle/state``     euc_msgs/UnicycleState       LOCKSTEP_QOS
    Publishes    ``unicycle/command``   euc_msgs/SteeringCommand     LOCKSTEP_QOS: ``u`` [N], ``step``, ``maneuver``,
                                                                     ``reference`` = ``y_des(t)`` in the maneuver's
                                                                     output order (``omega1, theta, sigma, r,
                                                                     psi(, y_G)``)
    ===========  =====================  ===========================  ==============================================

    Parameters: :data:`SPECS` (maneuver, design speed and pole, references, the model's Table I).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ``namespace``...).

    Attributes
    ----------
    controller : SteeringController
        Gains (``controller.gains``) and references.
    answered : int
        States answered with a new command.
    duplicates : int
        States answered again with the cached command.
    ignored : int
        Stale states (older step) and states whose status is not ``ok``.
    """

    NAME = "steering_controller"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = cfg = declare_params(self, SPECS)
        self.controller = build_controller(cfg, self.get_name())
        self.answered = 0
        self.duplicates = 0
        self.ignored = 0
        self._last: SteeringCommand | None = None
        self._pending: UnicycleState | None = None
        self._ready = False
        self.pub = self.create_publisher(SteeringCommand, itf.STEERING_COMMAND, itf.LOCKSTEP_QOS)
        self.start_gate = MatchGate(lambda: [(itf.STEERING_COMMAND + " subscriptions",
                                              self.pub.get_subscription_count(), 1 + cfg["wait_observers"])])
        self.create_subscription(UnicycleState, itf.UNICYCLE_STATE, self._on_state, itf.LOCKSTEP_QOS)
        self._start_timer = self.create_timer(CHECK_PERIOD_S, self._check_ready)
        g = self.controller.gains
        self.get_logger().info(
            f"{g.maneuver} at {g.speed:g} m/s, target {self.controller.target:g}, roots at {g.pole:g} 1/s: "
            + ", ".join(f"{n} {k:.2f}" for n, k in zip(g.names, g.K)))

    def _check_ready(self) -> None:
        """Answer nothing until the simulator and ``wait_observers`` observers matched (then the settle time)."""
        if not self.start_gate.ready(time.monotonic()):
            return
        self._ready = True
        self._start_timer.cancel()
        if self._pending is not None:
            pending, self._pending = self._pending, None
            self._on_state(pending)

    def _on_state(self, msg: UnicycleState) -> None:
        if not self._ready:
            self._pending = msg      # the latest state is answered once the subscribers matched
            return
        last = self._last
        if last is not None and 0 < msg.step <= last.step:
            if msg.step == last.step:
                self.duplicates += 1
                self.pub.publish(last)
            else:
                self.ignored += 1
            return
        if msg.status != STATUS_OK:
            self.ignored += 1
            return
        t = convert.stamp_to_ns(msg.header.stamp) / 1e9
        u, y_des = self.controller.command(t, convert.msg_to_unicycle_state(msg))
        out = SteeringCommand()
        out.header.stamp = msg.header.stamp
        out.header.frame_id = msg.header.frame_id
        out.u = u
        out.step = msg.step
        out.maneuver = self.controller.maneuver
        out.reference = [float(v) for v in y_des]
        self.pub.publish(out)
        self._last = out
        self.answered += 1


main = main_for(SteeringControllerNode)
