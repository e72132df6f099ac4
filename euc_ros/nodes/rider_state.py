"""Node ``rider_state``: ``MocapFrame`` -> ``RiderState`` (EUC paper, Section 2), with a stated filter lag.

Per frame the rigid bodies give the EUC attitude (yaw psi, tilt theta, pitch gamma), the wheel centre
C, the ankle hinge A and the rider CoG G (mass-weighted segment centres of mass), and the rider pitch
phi (about the hinge A by default, or eq (3)). Two fixed-lag Savitzky-Golay filters (the online twin
of the offline filter of ``euc-ros identify``) give the derivatives: each state is published
``filter_lag = (window - 1) / 2`` frames after its frame (0.45 s at the default 0.9 s window and
120 Hz), stamped with the capture time of *its own* frame. With ``estimator: kalman`` a steady-state
Kalman fixed-lag smoother replaces them (:mod:`euc_ros.core.filters.causal`): states
``lag_s`` late (0.1 s by default), noisier (docs/low_lag.md). The logic lives in
:class:`~euc_ros.core.online.estimators.RiderStateEstimator`; this module only wires ROS.

Bad input never stops the node:

* a frame without the EUC body (or with it untracked) gives no state;
* a frame with a rider segment missing gives a state with ``has_rider`` false and NaN phi and g;
* frames bridged across a short gap (at most ``max_gap``) give no state; a longer gap restarts the
  filters (no state across it);
* repeated and out-of-order frames are dropped; a frame numbering that restarts or a stamp that jumps
  back by more than ``restart_jump`` restarts the filters
  (:class:`~euc_ros.core.online.estimators.FrameSequencer`); frames without a number (``-1``, topic
  sources) are numbered from their stamps;
* a frame that cannot be used (an :class:`~euc_ros.core.errors.EucError`: bytes that are no MocapFrame) is
  dropped with a warning and counted (``errors`` in the diagnostics); any other exception is a bug, logged
  with its traceback and counted apart (``unexpected_errors``): the node keeps running
  (:class:`~euc_ros.ros.runtime.CallbackErrors`).
"""
from __future__ import annotations

import time

from euc_msgs.msg import MocapFrame, RiderState
from rclpy.node import Node

from euc_ros.core.errors import EucError
from euc_ros.core.filters.causal import LOW_LAG_S, STATE_ESTIMATORS
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP
from euc_ros.core.io.cdr_flat import FlatEncoder
from euc_ros.core.mocap.presence import BodyPresence
from euc_ros.core.online.estimators import FrameSequencer, RiderStateEstimator
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, PHI_DEFINITIONS
from euc_ros.core.states.settings import ReconstructionSettings
from euc_ros.core.states.skeleton import COG_METHODS
from euc_ros.ros import convert
from euc_ros.ros import interfaces as itf
from euc_ros.ros.intra import LocalFanout
from euc_ros.ros.params import ParamSpec, declare_params, required_session
from euc_ros.ros.rate_gate import NodeRateGate
from euc_ros.ros.runtime import CallbackErrors, drain, main_for

SPECS = (
    ParamSpec("session_file", "", "session file (docs/session.md): rider segments and EUC geometry (required)"),
    ParamSpec("phi_definition", "hinge", "rider pitch phi: about the ankle hinge A (model) or about the wheel "
              "centre C (eq 3)", choices=PHI_DEFINITIONS),
    ParamSpec("window_s", DEFAULT_WINDOW_S, "Savitzky-Golay window; states are published half of it late",
              "s", 0.02, 10.0),
    ParamSpec("polyorder", DEFAULT_SG_POLYORDER, "Savitzky-Golay polynomial order", "", 2, 8),
    ParamSpec("estimator", "savgol", "derivative filter: savgol (Savitzky-Golay, window_s/polyorder) or kalman "
              f"(low-lag fixed-lag Kalman smoother, {LOW_LAG_S:g} s late by default; noisier, docs/low_lag.md) or "
              "split (low-lag, positions and orientation-borne pieces smoothed separately; 3 s start-up; "
              "phi_definition hinge and cog_method segments only)",
              choices=STATE_ESTIMATORS),
    ParamSpec("lag_s", -1.0, "delay of the published states behind their frames; negative: the estimator's "
              f"default (half the Savitzky-Golay window, {LOW_LAG_S:g} s for kalman and split)", "s", -1.0, 10.0),
    ParamSpec("split_euc_center", [0.0, 0.0, 0.0], "split only: where the EUC body's orientation noise leaves "
              "the position unmoved, in its body frame from its pivot: the pivot (default, Motive's marker centroid "
              "unless moved) or the markers' centroid if the pivot was placed elsewhere", "m"),
    ParamSpec("smoothing_s", 0.0, "smoothing time of the kalman estimator (bandwidth 1/smoothing_s rad/s); 0: the "
              "value measured best for the lag", "s", 0.0, 10.0),
    ParamSpec("max_gap", DEFAULT_MAX_GAP, "longest run of missing frames bridged (bridged frames give no state)",
              "frames", 0, 1000),
    ParamSpec("cog_method", "segments", "rider CoG: per-segment centres of mass, or a kinematic chain fitted to "
              "each frame (no lag; swapped/flipped bodies excluded and counted; docs/cog_artefacts.md)",
              choices=COG_METHODS),
    ParamSpec("skeleton_calibration_s", 2.0, "frames at the start used to estimate the chain's segment lengths "
              "(cog_method skeleton)", "s", 0.05, 600.0),
    ParamSpec("rate_hz", 0.0, "expected mocap frame rate; 0 takes the session's rate_hz. The rate is measured "
              "from the first rate_measure_s of frames; more than 1 % off is a diagnostics ERROR and the "
              "measured rate is used", "Hz", 0.0, 100000.0),
    ParamSpec("rate_measure_s", 0.3, "frames held to measure the frame rate before the filters start", "s",
              0.05, 10.0),
    ParamSpec("restart_jump", 1.0, "stamps jumping back by more than this mean the source restarted", "s",
              0.001, 3600.0),
    ParamSpec("diagnostics_period", 1.0, "period of the diagnostics", "s", 0.05, 60.0),
)


class RiderStateNode(Node):
    """Reconstruct the planar model's state from mocap frames (see the module docstring).

    ===========  ==================  ================================  ==========================================
    direction    topic               type                              what
    ===========  ==================  ================================  ==========================================
    Subscribes   ``mocap/frame``     euc_msgs/MocapFrame               reliable; raw, read with numpy
    Publishes    ``rider/state``     euc_msgs/RiderState               reliable; stamped with its frame's capture
    Publishes    ``/diagnostics``    diagnostic_msgs/DiagnosticArray   frames, states, no EUC, no rider, restarts,
                                                                       drops, filter lag, rates, the CoG method,
                                                                       its lag ``cog_lag_s`` and the body-frames
                                                                       excluded from G (``cog_method: skeleton``)
    ===========  ==================  ================================  ==========================================

    Parameters: :data:`SPECS` (session, phi definition, estimator and its window or lag, gaps, CoG
    method, frame rate).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ``namespace``...).

    Attributes
    ----------
    estimator : RiderStateEstimator
    sequencer : FrameSequencer
    counts : dict
        ``frames`` received, ``states`` published, ``no_euc`` frames, ``no_rider`` states, ``errors``.
    """

    NAME = "rider_state"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = cfg = declare_params(self, SPECS)
        self.session, self.hardware_id = required_session(self.NAME, cfg)
        rate = cfg["rate_hz"] or self.session.rate_hz
        if cfg["cog_method"] == "skeleton":    # compile (or load) the chain fit now, not on the first frame
            from euc_ros.core.states.skeleton_compiled import warm_up
            self.get_logger().info(f"skeleton chain fit ready in {warm_up():.1f} s")
        # the filters are built once the rate is measured (the frames meanwhile are held, not lost)
        self._build(rate)
        self.rate_gate = NodeRateGate(self, rate, self._build, lambda item: self._process(*item),
                                      min_span_s=cfg["rate_measure_s"])
        self.counts = {"frames": 0, "states": 0, "no_euc": 0, "no_rider": 0, "errors": 0, "unexpected_errors": 0}
        self.drops = CallbackErrors(self, "frame dropped", self.counts)
        names, fractions, _ = self.session.segment_arrays()
        self.presence = BodyPresence([self.session.euc.body] + [n for n, f in zip(names, fractions) if f > 0])
        self._origin_ns: int | None = None
        self._last_frame_wall: float | None = None
        self._encoder = FlatEncoder(convert.checked_flat_fields(RiderState, convert.RIDER_STATE_FIELDS))
        self.state_pub = self.create_publisher(RiderState, itf.RIDER_STATE, itf.RELIABLE_QOS,
                                               event_callbacks=itf.pub_events())
        self.diag_pub = itf.diagnostics_publisher(self)
        # raw: the frame is read with numpy (convert.raw_to_frame), not through ~15 message objects
        self._frame_sub = self.create_subscription(MocapFrame, itf.MOCAP_FRAME, self._on_frames, itf.RELIABLE_QOS,
                                                   raw=True, event_callbacks=itf.sub_events())
        self.create_timer(cfg["diagnostics_period"], self._publish_diagnostics)
        self.get_logger().info(f"session {cfg['session_file']}: {rate:g} Hz, phi {cfg['phi_definition']}, "
                               f"estimator {cfg['estimator']}, filter lag {self.estimator.lag_s:.3f} s")

    def _build(self, rate: float) -> None:
        cfg = self.config
        settings = ReconstructionSettings(window_s=cfg["window_s"], polyorder=cfg["polyorder"],
                                          phi_definition=cfg["phi_definition"], cog_method=cfg["cog_method"],
                                          max_gap=cfg["max_gap"])
        self.estimator = RiderStateEstimator(self.session, 1.0 / rate, settings=settings, estimator=cfg["estimator"],
                                             lag_s=cfg["lag_s"] if cfg["lag_s"] >= 0 else None,
                                             smoothing_s=cfg["smoothing_s"] or None,
                                             skeleton_calibration_frames=max(
                                                 1, int(round(cfg["skeleton_calibration_s"] * rate))),
                                             split_euc_center=cfg["split_euc_center"])
        self.sequencer = FrameSequencer(rate, cfg["restart_jump"])

    def _on_frames(self, raw: bytes) -> None:
        self._on_frame(raw)
        drain(self._frame_sub, self._on_frame)   # a backlog in one wake-up

    def _on_frame(self, raw: bytes) -> None:
        try:
            item = convert.raw_to_frame(raw)
        except EucError as exc:    # bytes that are no MocapFrame: dropped, counted, warned
            self.counts["frames"] += 1
            self.drops.input_error(exc)
            return
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            self.counts["frames"] += 1
            self.drops.unexpected_error()
            return
        self._on_frame_local(item)

    def _on_frame_local(self, item) -> None:
        """One frame as ``(core Frame, frame_id)``: from :meth:`_on_frame` or in-process (container)."""
        self.counts["frames"] += 1
        self._last_frame_wall = time.monotonic()
        frame = item[0]
        try:
            self.presence.update(frame.bodies, frame.tracked)
        except EucError as exc:
            self.drops.input_error(exc)
            return
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            self.drops.unexpected_error()
            return
        self.rate_gate.push(frame.frame_number, frame.stamp_ns, item)

    def _process(self, frame, frame_id: str) -> None:
        try:
            action, number = self.sequencer.accept(frame.frame_number, frame.stamp_ns)
            if action == "drop":
                return
            if action == "restart":
                self.estimator.reset()
                self.get_logger().info(f"mocap stream restarted at frame {frame.frame_number}: filters reset")
            if self._origin_ns is None:
                self._origin_ns = frame.stamp_ns
            body = self.session.euc.body
            if body not in frame.bodies or not frame.tracked[frame.bodies.index(body)]:
                self.counts["no_euc"] += 1
            t = (frame.stamp_ns - self._origin_ns) * 1e-9
            samples = self.estimator.update(number, t, frame.position, frame.quat, frame.tracked, frame.bodies)
        except EucError as exc:    # bad input: dropped, counted, warned
            self.drops.input_error(exc)
            return
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            self.drops.unexpected_error()
            return
        local = isinstance(self.state_pub, LocalFanout)
        for s in samples:
            # serialized directly (cdr_flat): a message object costs twice as much to publish, plus its build
            stamp_ns = self._origin_ns + int(round(s.t * 1e9))
            raw = self._encoder.encode(stamp_ns, frame_id, convert.rider_state_values(s))
            if local:
                self.state_pub.publish(raw, local=convert.LocalState(stamp_ns, frame_id, s))
            else:
                self.state_pub.publish(raw)
            self.counts["states"] += 1
            self.counts["no_rider"] += not s.has_rider

    def _publish_diagnostics(self) -> None:
        c = self.counts
        meter = self.rate_gate.meter
        values = dict(c, restarts=self.sequencer.restarts, dropped_frames=self.sequencer.dropped,
                      filter_lag_s=self.estimator.lag_s, estimator=self.config["estimator"],
                      cog_method=self.config["cog_method"], cog_lag_s=self.estimator.cog_lag_s,
                      cog_excluded_body_frames=self.estimator.cog_faults,
                      cog_excluded_bodies=", ".join(f"{k} {v}"
                                                    for k, v in sorted(self.estimator.cog_fault_bodies.items())),
                      phi_definition=self.config["phi_definition"],
                      expected_rate_hz=meter.nominal_hz, measured_rate_hz=meter.measured_hz,
                      rate_used_hz=meter.rate_hz if meter.decided else float("nan"))
        missing = self.presence.report()
        values["missing_bodies"] = ", ".join(self.presence.last_missing)
        stale = self._last_frame_wall is None or time.monotonic() - self._last_frame_wall > 1.0
        if meter.error:
            level, message = convert.ERROR, self.rate_gate.error_message()
        elif stale:
            level, message = convert.STALE, "no frames yet" if c["frames"] == 0 else "no frames for > 1 s"
        elif missing:
            level, message = convert.WARN, f"{missing} in the last {self.config['diagnostics_period']:g} s"
        elif c["errors"] or c["unexpected_errors"]:
            level, message = convert.WARN, f"{c['errors'] + c['unexpected_errors']} frame(s) could not be used" + (
                f" ({c['unexpected_errors']} by an unexpected error: see the log)" if c["unexpected_errors"] else "")
        else:
            level, message = convert.OK, f"publishing states {self.estimator.lag_s:.3f} s after their frames"
        convert.publish_status(self, self.diag_pub, "rider_state: states", level, message, values,
                               self.hardware_id)


main = main_for(RiderStateNode)
