"""Rider_state with ``estimator: kalman`` or ``split`` -> torque_estimator -> monitor.

The ride: a level-calibrated lab whose floor turns into a 5 deg ramp at X = 12 m, ridden at constant
speed (test/unit/core/online/test_low_lag_monitor.py does the same with the core classes). The frames are fed
one at a time through the graph (each drained before the next, as in test_rider_state.py) and the
monitor's rules evaluated after every frame, so the flag's time is the newest frame's capture time.
The monitor's threshold comes from a level calibration ride through the core chain
(:func:`euc_ros.core.online.alarm.rmse_threshold`). Checked: the states are 0.1 s late and say so
(``filter_lag``, diagnostics), the node's states equal the core estimator's to the last bits, no flag
before the onset, a flag within 1 s after it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402

from euc_ros.core.model.terms import EucParams  # noqa: E402
from euc_ros.core.online.alarm import rmse_threshold  # noqa: E402
from euc_ros.core.online.estimators import RiderStateEstimator, TorqueEstimator, series_torques  # noqa: E402
from euc_ros.core.online.monitoring import OK, WARN  # noqa: E402
from euc_ros.core.ridesim.floors import FloorProfile  # noqa: E402
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride  # noqa: E402
from euc_ros.core.session import save_session  # noqa: E402
from euc_ros.nodes.monitor import Monitor  # noqa: E402
from euc_ros.nodes.rider_state import RiderStateNode  # noqa: E402
from euc_ros.nodes.torque_estimator import TorqueEstimatorNode  # noqa: E402
from euc_ros.testing import load_module  # noqa: E402

pytestmark = pytest.mark.ros

SLOPE_DEG = 5.0
RMSE_WINDOW_S = 0.5
ALPHA = 1e-8          # as the core test (heavier-than-Gaussian tail of the level rides' sliding RMSE)


H = load_module(Path(__file__).with_name("helpers.py"), "node_helpers")


def _calibrate(ride, estimator="kalman") -> float:
    dt = 1.0 / ride.session.rate_hz
    states = RiderStateEstimator(ride.session, dt, estimator=estimator)
    torque = TorqueEstimator(EucParams.from_session(ride.session, ride.config.h), dt, rmse_window_s=RMSE_WINDOW_S)
    m = ride.runs[0].mocap
    res = []
    for _, _, out in series_torques(m, states, torque):
        res.append(out.residual_nm)
    return rmse_threshold(res, int(round(RMSE_WINDOW_S / dt)), ALPHA)


# kalman: 0.1 s lag, 1.6 s memory; split: 0.1 s lag, 3.1 s memory (longer rides, a later ramp: level
# riding enough for the sliding window before the onset)
CASES = {"kalman": dict(level_s=6.0, x0_m=12.0, ride_s=5.5, onset=(3.0, 4.5)),
         "split": dict(level_s=14.0, x0_m=26.0, ride_s=10.5, onset=(8.0, 9.5))}


@pytest.mark.parametrize("estimator", list(CASES))
def test_low_lag_pipeline_flags_a_slope_within_one_second(pipes, ros_context, tmp_path, estimator):
    case = CASES[estimator]
    threshold = _calibrate(simulate_ride(RideConfig(maneuver="constant_speed", runs=1, seed=11,
                                                    duration_s=case["level_s"])), estimator)
    floor = FloorProfile.of(("ramp_from", {"slope_deg": SLOPE_DEG, "x0_m": case["x0_m"], "width_m": 0.05}))
    ride = simulate_ride(RideConfig(maneuver="constant_speed", runs=1, seed=3, floor=floor,
                                    duration_s=case["ride_s"]))
    run = ride.runs[0]
    onset = float(run.t[np.argmax(np.abs(run.signals["floor_slope"]) > 0.05 * np.radians(SLOPE_DEG))])
    assert case["onset"][0] < onset < case["onset"][1]
    save_session(ride.session, tmp_path / "session.yaml")
    path = str(tmp_path / "session.yaml")
    rider = RiderStateNode(context=ros_context, parameter_overrides=[
        Parameter("session_file", value=path), Parameter("estimator", value=estimator)])
    assert rider.estimator.lag_s == pytest.approx(0.1)
    te = TorqueEstimatorNode(context=ros_context, parameter_overrides=[
        Parameter("session_file", value=path), Parameter("rmse_window_s", value=RMSE_WINDOW_S),
        Parameter("h", value=ride.config.h)])
    # batch_s 0: the frames are fed one at a time and waited for, nothing to batch (each batch's wait
    # would only add itself to every frame)
    mon = Monitor(context=ros_context, parameter_overrides=[
        Parameter("rmse_threshold_nm", value=threshold), Parameter("batch_s", value=0.0),
        Parameter("period", value=60.0), Parameter("timeout_s", value=60.0)])
    pipe = pipes([rider, te, mon])
    series = run.mocap
    msgs = H.frame_msgs(series)
    first_flag = None
    n_window = int(round(RMSE_WINDOW_S * ride.session.rate_hz))
    for k, msg in enumerate(msgs):
        pipe.feed([msg])
        if mon._torque is None or te.estimator._rmse.count < n_window:
            continue
        level = mon.evaluate()["monitor: model consistency"].level
        t = float(series.t[k])
        if t < onset:
            assert level == OK, f"false alarm at {t:.2f} s (threshold {threshold:.2f} N m)"
        elif level >= WARN and first_flag is None:
            first_flag = t
    assert first_flag is not None and first_flag - onset <= 1.0, (first_flag, onset, threshold)
    # every state 0.1 s after its frame, equal to the core estimator's
    assert pipe.states and all(s.filter_lag == pytest.approx(0.1) for s in pipe.states)
    core = H.core_states(series, ride.session, estimator=estimator, window_s=1.2, polyorder=6)
    for s in pipe.states:
        c = core[H.stamp_ns(s.header.stamp)]
        assert s.x_ddot == c.x_ddot and s.phi_ddot == c.phi_ddot and s.gamma_ddot == c.gamma_ddot
    rider._publish_diagnostics()
    pipe.spin_until(lambda: any(kv.key == "estimator" and kv.value == estimator
                                for a in pipe.diag for st in a.status for kv in st.values),
                    what="rider_state diagnostics naming the estimator")
