"""Node ``monitor``: the pipeline's health for a rider-assist or lab operator, on ``/diagnostics``.

Every ``period`` seconds it publishes one ``diagnostic_msgs/DiagnosticArray`` with five statuses
(rules and levels in :mod:`euc_ros.core.monitoring`):

* ``monitor: mocap``: arrival rate against ``expected_rate_hz``, dropped frames (gaps in the frame
  numbering) and bodies untracked over the last ``rate_window_s``;
* ``monitor: model consistency``: the sliding RMSE of M_d1 - M_d2 from the torque estimator against
  ``rmse_threshold_nm`` (WARN above, ERROR above twice it): a rising residual means the model no
  longer explains the ride;
* ``monitor: rider lean``: peak abs(phi) since the last report against ``max_phi_deg``;
* ``monitor: EUC attitude``: peak abs(gamma) against ``max_gamma_deg`` and abs(theta) against
  ``max_tilt_deg``;
* ``monitor: motor torque``: peak abs(M_d1) against ``motor_limit_nm``.

Each status is STALE when its stream has sent nothing for ``timeout_s``. WARN starts at
``warn_fraction`` of a limit, ERROR above it. Each also counts the messages of its stream that could not be
read: ``messages_not_read`` (an :class:`~euc_ros.core.errors.EucError`, with a warning) and
``unexpected_errors`` (any other exception, a bug logged with its traceback); the monitor keeps running
(:class:`~euc_ros.ros.runtime.CallbackErrors`).
"""
from __future__ import annotations

import math
import time

from diagnostic_msgs.msg import DiagnosticArray
from euc_msgs.msg import MocapFrame, RiderState, TorqueEstimate
from rclpy.node import Node

from euc_ros.core.errors import EucError
from euc_ros.core.online import monitoring as mon
from euc_ros.ros import convert
from euc_ros.ros import interfaces as itf
from euc_ros.ros.drain import SubscriptionDrain
from euc_ros.ros.params import ParamSpec, declare_params
from euc_ros.ros.runtime import CallbackErrors, main_for

SPECS = (
    ParamSpec("period", 1.0, "period of the diagnostics", "s", 0.02, 60.0),
    ParamSpec("timeout_s", 1.0, "a stream silent for longer than this is STALE", "s", 0.01, 3600.0, live=True),
    ParamSpec("expected_rate_hz", 120.0, "nominal mocap frame rate", "Hz", 0.0, 100000.0, live=True),
    ParamSpec("rate_tolerance", 0.1, "relative shortfall of the rate before a warning (error below half)", "",
              0.0, 1.0, live=True),
    ParamSpec("rate_window_s", 2.0, "window of the rate, dropout and tracking statistics", "s", 0.1, 600.0),
    ParamSpec("max_dropout_fraction", 0.01, "share of dropped frames before a warning (error at 10x)", "",
              0.0, 1.0, live=True),
    ParamSpec("max_untracked_fraction", 0.1, "share of frames a body may be untracked in before a warning", "",
              0.0, 1.0, live=True),
    ParamSpec("rmse_threshold_nm", 5.0, "sliding RMSE of M_d1 - M_d2 above which the model is inconsistent "
              "(error above twice it)", "N m", 0.0, 1e6, live=True),
    ParamSpec("max_phi_deg", 20.0, "limit of the rider lean abs(phi)", "deg", 0.0, 180.0, live=True),
    ParamSpec("max_gamma_deg", 15.0, "limit of the EUC pitch abs(gamma)", "deg", 0.0, 180.0, live=True),
    ParamSpec("max_tilt_deg", 30.0, "limit of the EUC tilt abs(theta)", "deg", 0.0, 180.0, live=True),
    ParamSpec("motor_limit_nm", 120.0, "limit of the estimated motor torque abs(M_d1)", "N m", 0.0, 1e6, live=True),
    ParamSpec("batch_s", 0.02, "inputs are counted in batches: while messages flow they are taken every batch_s "
              "(one wake-up per batch, not per message); 0 takes what each wake-up finds", "s", 0.0, 1.0),
    ParamSpec("warn_fraction", 0.8, "a quantity above this fraction of its limit is a warning", "", 0.0, 1.0, live=True),  # noqa: E501
)

STATUS_NAMES = ("monitor: mocap", "monitor: model consistency", "monitor: rider lean", "monitor: EUC attitude",
                "monitor: motor torque")
#: The input stream each status judges (its messages that could not be read are counted in its values).
STATUS_STREAMS = {"monitor: mocap": itf.MOCAP_FRAME, "monitor: model consistency": itf.TORQUE,
                  "monitor: rider lean": itf.RIDER_STATE, "monitor: EUC attitude": itf.RIDER_STATE,
                  "monitor: motor torque": itf.TORQUE}


class Monitor(Node):
    """Publish the health statuses of the pipeline (see the module docstring).

    ===========  ==================  ================================  ===========================================
    direction    topic               type                              what
    ===========  ==================  ================================  ===========================================
    Subscribes   ``mocap/frame``     euc_msgs/MocapFrame               reliable; taken raw in batches every
    Subscribes   ``rider/state``     euc_msgs/RiderState               ``batch_s`` (a SubscriptionDrain), counted
    Subscribes   ``euc/torque``      euc_msgs/TorqueEstimate           as the other two
    Publishes    ``/diagnostics``    diagnostic_msgs/DiagnosticArray   the five statuses, every ``period``
    ===========  ==================  ================================  ===========================================

    Parameters: :data:`SPECS` (period, staleness, rates, limits; all but the windows settable while running).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node`.

    Attributes
    ----------
    last : dict of str -> Health
        The statuses of the latest report, by name.
    received : dict of str -> int
        Messages received per stream (``frames``, ``states``, ``torques``).
    """

    NAME = "monitor"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = cfg = declare_params(self, SPECS)
        self.frames = mon.StreamWindow(cfg["rate_window_s"])
        self.peaks = {k: mon.PeakAbs() for k in ("phi", "gamma", "theta", "m_d1")}
        self._last_state_wall: float | None = None
        self._last_torque_wall: float | None = None
        self._torque: TorqueEstimate | None = None
        self.last: dict[str, mon.Health] = {}
        self.received = {"frames": 0, "states": 0, "torques": 0}
        self.drops = {topic: CallbackErrors(self, f"{topic}: message not read", key="messages_not_read")
                      for topic in (itf.MOCAP_FRAME, itf.RIDER_STATE, itf.TORQUE)}
        self.reports = 0
        self.diag_pub = itf.diagnostics_publisher(self)
        # frames, states and torques are counted, not acted on one by one: taken in batches (one executor
        # wake-up per ~20 ms instead of one per message: 1080 messages/s at 360 Hz)
        self._inputs = SubscriptionDrain(self, self._on_batch, poll_s=cfg["batch_s"], max_poll_s=5 * cfg["batch_s"])
        for topic, cls in ((itf.MOCAP_FRAME, MocapFrame), (itf.RIDER_STATE, RiderState), (itf.TORQUE, TorqueEstimate)):
            self._inputs.subscribe(topic, cls.__name__, cls, itf.RELIABLE_QOS)
        self.add_waitable(self._inputs)
        self.create_timer(cfg["period"], self.report)

    # -- inputs: record only ---------------------------------------------------------------------
    def _on_batch(self, batch) -> None:
        handlers = {itf.MOCAP_FRAME: (self._on_frame, None), itf.RIDER_STATE: (self._on_state, RiderState),
                    itf.TORQUE: (self._on_torque, TorqueEstimate)}
        for topic, _, datas in batch:
            handler, cls = handlers[topic]
            drops = self.drops[topic]
            for raw in datas:
                try:
                    handler(raw if cls is None else convert.deserialize(raw, cls))
                except EucError as exc:    # bad input: dropped, counted, warned
                    drops.input_error(exc)
                except Exception:          # a bug: logged with its traceback; the node never dies on input
                    drops.unexpected_error()

    def _on_frame(self, raw: bytes) -> None:
        self.received["frames"] += 1
        frame, _ = convert.raw_to_frame(raw)     # numpy, not ~15 message objects per frame
        self.frames.push(time.monotonic(), frame.frame_number, frame.bodies, frame.tracked.tolist())

    def _on_state(self, msg: RiderState) -> None:
        self.received["states"] += 1
        self._last_state_wall = time.monotonic()
        self.peaks["phi"].push(msg.phi)
        self.peaks["gamma"].push(msg.gamma)
        self.peaks["theta"].push(msg.theta)

    def _on_torque(self, msg: TorqueEstimate) -> None:
        self.received["torques"] += 1
        self._last_torque_wall = time.monotonic()
        self._torque = msg
        self.peaks["m_d1"].push(msg.m_d1 if msg.valid else float("nan"))

    # -- the report ------------------------------------------------------------------------------
    def evaluate(self, now: float | None = None) -> dict[str, mon.Health]:
        """Apply the health rules to what arrived since the last report (and start a new period)."""
        cfg = self.config
        now = time.monotonic() if now is None else now
        timeout = cfg["timeout_s"]
        out: dict[str, mon.Health] = {}

        out["monitor: mocap"] = mon.stale_health(self.frames.age(now), timeout, "mocap frames") or mon.mocap_health(
            self.frames.stats(now), cfg["expected_rate_hz"], rate_tolerance=cfg["rate_tolerance"],
            max_dropout_fraction=cfg["max_dropout_fraction"], max_untracked_fraction=cfg["max_untracked_fraction"])

        torque_age = None if self._last_torque_wall is None else now - self._last_torque_wall
        stale_t = mon.stale_health(torque_age, timeout, "torque estimates")
        m_d1 = self.peaks["m_d1"].take()
        if stale_t is not None:
            out["monitor: model consistency"] = stale_t
            out["monitor: motor torque"] = stale_t
        else:
            t = self._torque
            out["monitor: model consistency"] = mon.consistency_health(
                t.rmse_window, cfg["rmse_threshold_nm"], residual_nm=t.residual, h_online_m=t.h_online,
                h_online_std_m=t.h_online_std, model=t.model)
            out["monitor: motor torque"] = mon.limits_health(
                [mon.Limit("M_d1", m_d1[0], cfg["motor_limit_nm"], "N m", m_d1[1])],
                warn_fraction=cfg["warn_fraction"], missing="no valid torque")

        state_age = None if self._last_state_wall is None else now - self._last_state_wall
        stale_s = mon.stale_health(state_age, timeout, "rider states")
        phi, gamma, theta = (self.peaks[k].take() for k in ("phi", "gamma", "theta"))
        if stale_s is not None:
            out["monitor: rider lean"] = stale_s
            out["monitor: EUC attitude"] = stale_s
        else:
            # mostly without a rider (has_rider false, phi NaN): say so rather than judge a few samples
            phi_peak = phi[0] if phi[3] <= 0.5 * phi[2] else math.nan
            out["monitor: rider lean"] = mon.limits_health(
                [mon.Limit("phi", mon.degrees(phi_peak), cfg["max_phi_deg"], "deg", mon.degrees(phi[1]))],
                warn_fraction=cfg["warn_fraction"], missing="rider not tracked")
            out["monitor: EUC attitude"] = mon.limits_health(
                [mon.Limit("gamma", mon.degrees(gamma[0]), cfg["max_gamma_deg"], "deg", mon.degrees(gamma[1])),
                 mon.Limit("theta", mon.degrees(theta[0]), cfg["max_tilt_deg"], "deg", mon.degrees(theta[1]))],
                warn_fraction=cfg["warn_fraction"], missing="no EUC attitude")
        self.last = out
        return out

    def report(self) -> None:
        """Publish the statuses (timer callback)."""
        health = self.evaluate()
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        for name in STATUS_NAMES:
            h = health[name]
            values = dict(h.values, **self.drops[STATUS_STREAMS[name]].counts)
            arr.status.append(convert.status(name, h.level, h.message, values,
                                             "mocap" if name == "monitor: mocap" else "euc"))
        self.diag_pub.publish(arr)
        self.reports += 1

    def close(self) -> None:
        """Destroy the batch subscriptions (called by the runtime before the node is destroyed)."""
        self._inputs.destroy()


main = main_for(Monitor)
