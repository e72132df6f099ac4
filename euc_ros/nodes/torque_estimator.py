"""Node ``torque_estimator``: ``RiderState`` -> ``TorqueEstimate`` at the mocap rate (EUC paper, eqs 9, 10, 13).

For every usable state: M_d1 (eq 9) and M_d2 (eq 10) of the 3-DoF model at the configured CoG height
``h``, the reduced model's eq (13), the residual ``M_d1 - M_d2``, its RMSE over a sliding window and an
online sliding-window estimate of h with its standard deviation. With ``effects`` (and
``effect_parameters``) the 3-DoF torques are those of the model extended with the effects the
residual analysis selected (``model`` then reads ``"3dof+ground_slope"``), so the live residual drops
too. The logic lives in :class:`~euc_ros.core.online.estimators.TorqueEstimator`; this module only wires
ROS.

A NaN never reaches a published torque: a state that is not usable (no rider, a NaN derivative, a
torque that would not be finite) is not published and only counted in the diagnostics. States
missing from the stream age the sliding windows by the time they cover; a jump back in time (a
restarted upstream) or a gap longer than the RMSE window resets them, so nothing stale is published. A
state that cannot be used (an :class:`~euc_ros.core.errors.EucError`) is dropped with a warning and
counted (``errors``); any other exception is a bug, logged with its traceback and counted apart
(``unexpected_errors``): the node keeps running (:class:`~euc_ros.ros.runtime.CallbackErrors`).
"""
from __future__ import annotations

import time
from types import SimpleNamespace

from diagnostic_msgs.msg import DiagnosticArray
from euc_msgs.msg import RiderState, TorqueEstimate
from rclpy.node import Node

from euc_ros.core.errors import ConfigError, EucError
from euc_ros.core.identify.model_file import read_model_file
from euc_ros.core.io.cdr_flat import FlatEncoder
from euc_ros.core.model.terms import EucParams
from euc_ros.core.online.estimators import TorqueEstimator, extended_model_from_config
from euc_ros.ros import convert
from euc_ros.ros import interfaces as itf
from euc_ros.ros.params import ParamSpec, declare_params, required_session
from euc_ros.ros.rate_gate import NodeRateGate
from euc_ros.ros.runtime import CallbackErrors, drain, main_for

SPECS = (
    ParamSpec("session_file", "", "session file (docs/session.md): rider and EUC parameters (required)"),
    ParamSpec("h", 0.61, "rider CoG height above the ankle hinge A used for the torques (the identified value); "
              "with model: 0 or this default take the model's h", "m", 0.0, 3.0, live=True),
    ParamSpec("model", "", "the JSON of 'euc-ros residual' or 'euc-ros identify': h, effects and their parameters "
              "from it (its session must be this session_file)"),
    ParamSpec("model_force", False, "use model even when it was made with another session file"),
    ParamSpec("rmse_window_s", 5.0, "window of the sliding RMSE of M_d1 - M_d2", "s", 0.01, 3600.0),
    ParamSpec("h_window_s", 30.0, "window of the online h estimate", "s", 0.1, 3600.0),
    ParamSpec("h_update_every", 0, "re-estimate h every this many states (0: every 0.1 s of states, 12 at 120 Hz)",
              "states", 0, 1_000_000),
    ParamSpec("min_sensitivity", 5.0, "excitation needed before the online h is given (RMS dResidual/dh)",
              "N m/m", 0.0, 1e6),
    ParamSpec("effects", [""], "effects of the residual analysis added to the 3-DoF model (e.g. ground_slope)"),
    ParamSpec("effect_parameters", [""], "their parameters as <effect>.<parameter>=<value> in the residual "
              "report's units (e.g. ground_slope.alpha_deg=2.9)"),
    ParamSpec("rate_hz", 0.0, "expected state rate; 0 takes the session's rate_hz. Measured from the first "
              "0.03 s of states; more than 1 % off is a diagnostics ERROR and the measured rate is used", "Hz",
              0.0, 100000.0),
    ParamSpec("psi_rate_window_s", 0.3, "window of the causal yaw rate some effects need (tilt_gravity)", "s",
              0.01, 10.0),
    ParamSpec("diagnostics_period", 1.0, "period of the diagnostics", "s", 0.05, 60.0),
)

_STATE_FIELDS = ("x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "psi", "theta")


class TorqueEstimatorNode(Node):
    """Driving torque of both models, sliding RMSE and online h from rider states (module docstring).

    ===========  ==================  ================================  ===========================================
    direction    topic               type                              what
    ===========  ==================  ================================  ===========================================
    Subscribes   ``rider/state``     euc_msgs/RiderState               reliable
    Subscribes   ``/diagnostics``    diagnostic_msgs/DiagnosticArray   the bodies rider_state misses
    Publishes    ``euc/torque``      euc_msgs/TorqueEstimate           reliable; header copied from the state
    Publishes    ``/diagnostics``    diagnostic_msgs/DiagnosticArray   states, published, not usable, resets,
                                                                       model, RMSE, online h, rates
    ===========  ==================  ================================  ===========================================

    Parameters: :data:`SPECS` (session, ``h`` (settable while running), windows, effects, rate).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node`.

    Attributes
    ----------
    estimator : TorqueEstimator
        Its ``counts`` are published in the diagnostics.
    published : int
        TorqueEstimate messages published.
    drops : CallbackErrors
        States dropped on bad input (``errors`` in the diagnostics) or on an unexpected error, a bug logged
        with its traceback (``unexpected_errors``).
    """

    NAME = "torque_estimator"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = cfg = declare_params(self, SPECS)
        key = f"{self.NAME}.ros__parameters"
        session, self.hardware_id = required_session(self.NAME, cfg)
        h, effects, assignments, self._base_h = self._model_settings(cfg, key)
        params = EucParams.from_session(session, h)
        model = extended_model_from_config(params, effects, assignments, key=f"{key}.effect_parameters")
        rate = cfg["rate_hz"] or session.rate_hz
        self._params, self._model = params, model
        # states are held until their rate is measured (the estimator's windows count samples)
        self._build(rate)
        self.rate_gate = NodeRateGate(self, rate, self._build, self._process, min_span_s=0.03, min_frames=4)
        self.published = 0
        self.drops = CallbackErrors(self, "state dropped")
        self.last = None
        self._origin_ns: int | None = None
        self._last_state_wall: float | None = None
        self._published_at_last_diag = 0
        self._encoder = FlatEncoder(convert.checked_flat_fields(TorqueEstimate, convert.TORQUE_FIELDS))
        self.torque_pub = self.create_publisher(TorqueEstimate, itf.TORQUE, itf.RELIABLE_QOS,
                                                event_callbacks=itf.pub_events())
        self.diag_pub = itf.diagnostics_publisher(self)
        self._state_sub = self.create_subscription(RiderState, itf.RIDER_STATE, self._on_states, itf.RELIABLE_QOS,
                                                   event_callbacks=itf.sub_events())
        # rider_state names the bodies it misses; a torque that cannot be computed then says which
        self.upstream_missing = ""
        self.create_subscription(DiagnosticArray, itf.DIAGNOSTICS, self._on_diagnostics, itf.DIAGNOSTICS_QOS,
                                 event_callbacks=itf.sub_events())
        self.create_timer(cfg["diagnostics_period"], self._publish_diagnostics)
        self.get_logger().info(f"model {self.estimator.model_name}, h = {cfg['h']:g} m, "
                               f"RMSE window {self.estimator.window_s:g} s")

    def _model_settings(self, cfg: dict, key: str) -> tuple[float, list, list, float | None]:
        """h, effects, their assignments and the base model's h: from ``model`` when given, else the parameters.

        Raises
        ------
        ConfigError
            ``model`` with ``effects`` or an h of its own, h 0 without ``model``, a model file that cannot
            be read, or one made with another session (unless ``model_force``).
        """
        if not cfg["model"]:
            if cfg["h"] <= 0:
                raise ConfigError("h = 0 takes the h of 'model', and no model is given: set h (the value 'euc-ros "
                                  "identify' gives) or model (its JSON)", key=f"{key}.h")
            return cfg["h"], cfg["effects"], cfg["effect_parameters"], None
        if any(e.strip() for e in cfg["effects"]) or any(a.strip() for a in cfg["effect_parameters"]):
            raise ConfigError("the model file gives the effects and their parameters: leave effects and "
                              "effect_parameters empty, or model empty", key=f"{key}.model")
        applied = read_model_file(cfg["model"])
        default_h = next(p.default for p in SPECS if p.name == "h")
        if cfg["h"] not in (0.0, default_h) and abs(cfg["h"] - applied.h_m) > 1e-9:
            raise ConfigError(f"h = {cfg['h']:g} m and model {cfg['model']} (h = {applied.h_m:.4f} m) are both given: "
                              "the model's h belongs to its effects; leave h unset", key=f"{key}.h")
        log = self.get_logger()
        for line in applied.check(session=cfg["session_file"], force=cfg["model_force"],
                                  force_option="model_force:=true"):
            log.warning(line)
        for line in applied.left_out:
            log.warning(f"{cfg['model']}: not in the live model (it needs the recordings it was fitted on): {line}")
        if applied.identifiable is False and applied.kind == "identify":
            log.warning(f"{cfg['model']}: its h is not identifiable from the recordings it was made from")
        log.info(f"model {applied.name} from {cfg['model']}: h = {applied.h_m:.4f} m"
                 + (f", {', '.join(applied.assignments())}" if applied.effects else ""))
        return applied.h_m, list(applied.effects), applied.assignments(), applied.base_h_m

    @property
    def errors(self) -> int:
        """States dropped on bad input (:attr:`drops`)."""
        return self.drops.errors

    def on_parameter(self, name: str, value) -> None:
        """``ros2 param set /torque_estimator h 0.58``: torques use the new h from the next state on."""
        if name == "h":
            self.estimator.set_h(value)
            self._params = self.estimator.params      # kept if the estimator is rebuilt at the measured rate
            self.get_logger().info(f"h set to {value:g} m: torques use it from the next state; RMSE window restarts")

    def _build(self, rate: float) -> None:
        cfg = self.config
        self.estimator = TorqueEstimator(self._params, 1.0 / rate, rmse_window_s=cfg["rmse_window_s"],
                                         h_window_s=cfg["h_window_s"], h_update_every=cfg["h_update_every"],
                                         min_sensitivity=cfg["min_sensitivity"], model=self._model,
                                         psi_rate_window_s=cfg["psi_rate_window_s"],
                                         base_h=self._base_h if self._model is not None else None)

    def _on_states(self, msg: RiderState) -> None:
        self._on_state(msg)
        drain(self._state_sub, self._on_state)   # a backlog in one wake-up

    def _on_state(self, msg) -> None:
        """One RiderState message, or a :class:`~euc_ros.ros.convert.LocalState` handed over in-process."""
        self._last_state_wall = time.monotonic()
        try:
            stamp = msg.stamp_ns if type(msg) is convert.LocalState else convert.stamp_to_ns(msg.header.stamp)
        except EucError as exc:    # bad input: dropped, counted, warned
            self.drops.input_error(exc)
            return
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            self.drops.unexpected_error()
            return
        self.rate_gate.push(-1, stamp, msg)

    def _process(self, msg) -> None:
        try:
            if type(msg) is convert.LocalState:
                stamp, frame_id, src = msg.stamp_ns, msg.frame_id, msg.sample
            else:
                stamp, frame_id, src = convert.stamp_to_ns(msg.header.stamp), msg.header.frame_id, msg
            if self._origin_ns is None:
                self._origin_ns = stamp
            state = SimpleNamespace(t=(stamp - self._origin_ns) * 1e-9, frame=-1, valid=True,
                                    **{k: float(getattr(src, k)) for k in _STATE_FIELDS})
            out = self.estimator.update(state)
        except EucError as exc:    # bad input: dropped, counted, warned
            self.drops.input_error(exc)
            return
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            self.drops.unexpected_error()
            return
        if out is None:
            return
        # serialized directly (cdr_flat), header copied from the state: a message object costs twice as much
        self.torque_pub.publish(self._encoder.encode(stamp, frame_id, convert.torque_values(out)))
        self.published += 1
        self.last = out

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for st in msg.status:
            if st.name == "rider_state: states":
                self.upstream_missing = next((kv.value for kv in st.values if kv.key == "missing_bodies"), "")

    def _publish_diagnostics(self) -> None:
        c = self.estimator.counts
        last = self.last
        nan = float("nan")
        values = {"states": c["states"], "published": self.published, "not_usable": c["invalid"],
                  "resets": c["resets"], "repeated_dropped": c["repeated"], "missing_states": c["missing"],
                  "errors": self.drops.errors, "unexpected_errors": self.drops.unexpected,
                  "model": self.estimator.model_name, "h_m": float(self.estimator.params.h),
                  "rmse_window_nm": last.rmse_window_nm if last else nan,
                  "h_online_m": last.h_online_m if last else nan,
                  "h_online_std_m": last.h_online_std_m if last else nan,
                  "h_online": (f"{last.h_online_m:.3f} m" if last.h_online_status == "ok" else last.h_online_status)
                  if last else "not yet (no state)",
                  "missing_bodies_upstream": self.upstream_missing,
                  "rmse_window_base_model_nm": last.extra.get("rmse_base_nm", nan) if last else nan,
                  "expected_rate_hz": self.rate_gate.meter.nominal_hz,
                  "measured_rate_hz": self.rate_gate.meter.measured_hz}
        fresh = self.published - self._published_at_last_diag
        self._published_at_last_diag = self.published
        stale = self._last_state_wall is None or time.monotonic() - self._last_state_wall > 1.0
        meter = self.rate_gate.meter
        if meter.error:
            level, message = convert.ERROR, self.rate_gate.error_message()
        elif stale:
            level, message = convert.STALE, "no states yet" if c["states"] == 0 else "no states for > 1 s"
        elif fresh == 0:
            level, message = convert.WARN, ("states arrive but none is usable: " + (
                f"rider_state has no pose for {self.upstream_missing}" if self.upstream_missing
                else "rider missing or derivatives not finite"))
        elif self._fits_worse(last):
            base = last.extra["rmse_base_nm"]
            level, message = convert.WARN, (
                f"{self.estimator.model_name} fits worse than the 3-DoF model without its effects over the last "
                f"{self.estimator.window_s:g} s (RMSE {last.rmse_window_nm:.3f} against {base:.3f} N m): its effects "
                "may not belong to this ride")
        else:
            level, message = convert.OK, f"{self.estimator.model_name}: publishing torques"
        convert.publish_status(self, self.diag_pub, "torque_estimator: torques", level, message, values,
                               self.hardware_id)


    def _fits_worse(self, last) -> bool:
        """Whether the extended model's sliding RMSE is above its base model's (both over a full window)."""
        if last is None or "rmse_base_nm" not in last.extra:
            return False
        return bool(last.rmse_window_nm > last.extra["rmse_base_nm"])


main = main_for(TorqueEstimatorNode)
