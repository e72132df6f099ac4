"""torque_estimator node in-process: rider_state -> torque_estimator over DDS, against the ROS-free core.

Covers: torques equal to the core on the same states, a NaN never published, the extended model
configured by parameters (the live residual drops on a ride simulated with a ground slope), and
restarts mid-stream of the upstream node, of the mocap source and of the estimator itself.

Tolerances: the node and the core run the same code on the same doubles (rel 1e-12); the sliding
RMSE against a direct mean differs by its running sum's round-off (~1e-13 relative: rel 1e-9).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

from euc_msgs.msg import RiderState  # noqa: E402

from euc_ros.core.errors import ConfigError  # noqa: E402
from euc_ros.core.session import save_session  # noqa: E402
from euc_ros.nodes.torque_estimator import TorqueEstimatorNode  # noqa: E402
from euc_ros.testing import load_module  # noqa: E402

pytestmark = pytest.mark.ros


H = load_module(Path(__file__).with_name("helpers.py"), "node_helpers")
stamp_ns, torque_node, core_torques = H.stamp_ns, H.torque_node, H.core_torques


def assert_all_finite(torques):
    vals = np.array([[m.m_d1, m.m_d2, m.m_d1_2dof, m.m_d2_2dof, m.residual, m.rmse_window, m.h] for m in torques])
    assert vals.size and np.all(np.isfinite(vals)) and all(m.valid for m in torques)


def test_torques_equal_the_core_and_no_nan_is_published(pipes, ros_context, ride):
    series, session, path = ride
    rs = H.rider_node(ros_context, path)
    te = torque_node(ros_context, path, rmse_window_s=1.0, h_window_s=3.0)
    pipe = pipes([rs, te])
    pipe.feed(H.frame_msgs(series))
    want, core = core_torques(pipe.states, session, rmse_window_s=1.0, h_window_s=3.0)
    got = {stamp_ns(m.header.stamp): m for m in pipe.torques}
    assert set(got) == set(want) and len(pipe.torques) == len(want) == te.published
    # every state with a rider and finite derivatives gives a torque; the others none
    usable = {stamp_ns(m.header.stamp) for m in pipe.states
              if np.all(np.isfinite([m.phi, m.phi_dot, m.phi_ddot, m.gamma_ddot, m.x_ddot]))}
    assert set(got) == usable and len(pipe.states) - len(usable) > 40
    assert te.estimator.counts["invalid"] == len(pipe.states) - len(usable)
    assert_all_finite(pipe.torques)
    for stamp, m in got.items():
        o = want[stamp]
        assert (m.m_d1, m.m_d2, m.m_d1_2dof, m.m_d2_2dof) == pytest.approx((o.M_d1, o.M_d2, o.M_d1_2dof, o.M_d2_2dof),
                                                                        rel=1e-12, abs=1e-12)
        assert m.rmse_window == pytest.approx(o.rmse_window_nm, rel=1e-12)
        assert m.h == 0.61 and m.window == pytest.approx(1.0) and m.model == "3dof"
        np.testing.assert_equal(m.h_online, o.h_online_m)
        assert m.header.frame_id == "world"
    assert core.counts["missing"] == te.estimator.counts["missing"] > 0   # states the lost EUC never gave


def test_unusable_states_are_counted_not_published(pipes, ros_context, ride):
    _, _, path = ride
    te = torque_node(ros_context, path, diagnostics_period=0.05)
    pipe = pipes([te])
    base = dict(x=0.0, x_dot=3.0, x_ddot=-1.0, gamma=0.02, gamma_dot=0.0, gamma_ddot=0.1, phi=-0.1, phi_dot=0.05,
                phi_ddot=0.2, phi_eq3=-0.12, phi_hinge=-0.1, psi=0.0, theta=0.0, filter_lag=0.45)
    bad = [dict(phi=float("nan"), has_rider=False), dict(gamma_ddot=float("inf")), dict(x_ddot=float("nan")),
           dict(phi_ddot=float("-inf"))]
    msgs = []
    for k in range(12):
        m = RiderState(has_rider=True, phi_definition="hinge", **base)
        for key, v in (bad[k % 4] if k % 3 == 1 else {}).items():
            setattr(m, key, v)
        m.header.stamp.sec, m.header.stamp.nanosec = 1000, k * 8_333_333
        msgs.append(m)
    pipe.feed_states(msgs)
    n_bad = sum(1 for k in range(12) if k % 3 == 1)
    assert len(pipe.torques) == 12 - n_bad and te.estimator.counts["invalid"] == n_bad
    assert_all_finite(pipe.torques)
    pipe.spin_until(lambda: any(kv.key == "not_usable" and kv.value == str(n_bad)
                                for a in pipe.diag for st in a.status if st.name == "torque_estimator: torques"
                                for kv in st.values), what="diagnostics counting the unusable states")


@pytest.fixture(scope="module")
def sloped(tmp_path_factory):
    """One deceleration run simulated on a floor rising 3 deg."""
    from euc_ros.core.ridesim.effects import make_effects
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    result = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=6, duration_s=4.0,
                                      effects=make_effects(["ground_slope"], {"alpha_deg": 3.0})))
    d = tmp_path_factory.mktemp("sloped")
    save_session(result.session, d / "session.yaml")
    return result.runs[0].mocap, d / "session.yaml"


def test_configured_effect_drops_the_live_residual(ros_context, sloped):
    series, path = sloped
    medians = {}
    for effects in ([""], ["ground_slope"]):
        extra = {} if effects == [""] else {"effects": effects, "effect_parameters": ["ground_slope.alpha_deg=3.0"]}
        pipe = H.Pipe(ros_context, [H.rider_node(ros_context, path),
                                    torque_node(ros_context, path, rmse_window_s=2.0, **extra)])
        try:
            pipe.feed(H.frame_msgs(series))
            assert_all_finite(pipe.torques)
            rmse = np.array([m.rmse_window for m in pipe.torques])
            medians[pipe.torques[-1].model] = float(np.median(rmse[240:]))   # once the 2 s window is full
        finally:
            pipe.close()
    print("live RMSE medians", medians)
    assert set(medians) == {"3dof", "3dof+ground_slope"}
    assert medians["3dof"] > 3.0                       # a 3 deg slope leaves a large residual ...
    assert medians["3dof+ground_slope"] < 0.15 * medians["3dof"]   # ... which the configured effect explains


def test_upstream_restart_mid_stream_resumes_without_stale_or_nan_output(pipes, ros_context, ride):
    series, session, path = ride
    te = torque_node(ros_context, path, rmse_window_s=2.0)
    pipe = pipes([te])
    rs = pipe.add(H.rider_node(ros_context, path))
    pipe.feed(H.frame_msgs(series, frames=range(160, 300)))
    n_a, t_a = len(pipe.torques), len(pipe.states)
    last_a = stamp_ns(pipe.states[-1].header.stamp)
    pipe.remove(rs)                                    # rider_state dies ...
    pipe.feed(H.frame_msgs(series, frames=range(300, 330)))   # ... frames go on unseen ...
    pipe.add(H.rider_node(ros_context, path))          # ... and a new rider_state comes up
    pipe.feed(H.frame_msgs(series, frames=range(330, 470)))
    assert len(pipe.torques) > n_a + 20
    assert_all_finite(pipe.torques)
    stamps = [stamp_ns(m.header.stamp) for m in pipe.torques]
    assert np.all(np.diff(stamps) > 0)                # nothing repeated, nothing out of order
    first_b = stamp_ns(pipe.states[t_a].header.stamp)
    assert first_b > last_a and not any(last_a < s < first_b for s in stamps)
    # the windows aged over the missing states: the RMSE covers the last 2 s of time only
    assert te.estimator.counts["resets"] == 0 and te.estimator.counts["missing"] > 30
    t = np.array(stamps) * 1e-9
    r = np.array([m.residual for m in pipe.torques])
    for k in (n_a, len(stamps) - 1):
        inside = (t > t[k] - 2.0 + 0.5 / 120) & (t <= t[k] + 1e-12)
        assert pipe.torques[k].rmse_window == pytest.approx(np.sqrt(np.mean(r[inside] ** 2)), rel=1e-9)


def test_estimator_restart_and_source_restart_start_from_scratch(pipes, ros_context, ride):
    series, session, path = ride
    rs = H.rider_node(ros_context, path)
    pipe = pipes([rs])
    te = pipe.add(torque_node(ros_context, path, rmse_window_s=2.0))
    pipe.feed(H.frame_msgs(series, frames=range(160, 300)))
    first = list(pipe.torques)
    pipe.remove(te)                                    # the estimator itself restarts
    te2 = pipe.add(torque_node(ros_context, path, rmse_window_s=2.0))
    pipe.feed(H.frame_msgs(series, frames=range(300, 470)))   # (the rider is lost in frames 300-339)
    fresh = pipe.torques[len(first):]
    assert fresh and fresh[0].rmse_window == pytest.approx(abs(fresh[0].residual), rel=1e-12)
    # the mocap source restarts (same recording, time jumps back): both downstream nodes start over and
    # give exactly what they gave the first time
    n_before = len(pipe.torques)
    pipe.feed(H.frame_msgs(series, frames=range(160, 300)))
    again = pipe.torques[n_before:]
    assert rs.sequencer.restarts == 1 and te2.estimator.counts["resets"] == 1
    assert [stamp_ns(m.header.stamp) for m in again] == [stamp_ns(m.header.stamp) for m in first]
    for a, b in zip(first, again):
        assert (b.m_d1, b.m_d2, b.rmse_window) == (a.m_d1, a.m_d2, a.rmse_window)
        np.testing.assert_equal(b.h_online, a.h_online)
    assert_all_finite(pipe.torques)


def test_configuration_errors_name_the_key(ros_context, ride, tmp_path):
    _, _, path = ride
    with pytest.raises(ConfigError, match="session_file"):
        TorqueEstimatorNode(context=ros_context)
    with pytest.raises(ConfigError, match="effect_parameters"):
        torque_node(ros_context, path, effects=["ground_slope"], effect_parameters=["ground_slope.alpha_deg"])
    with pytest.raises(ConfigError, match="not in the list of effects"):
        torque_node(ros_context, path, effects=[""], effect_parameters=["ground_slope.alpha_deg=1"])
    with pytest.raises(ConfigError, match="alpha_deg"):
        torque_node(ros_context, path, effects=["ground_slope"])
    with pytest.raises(ConfigError, match="unknown effect"):
        torque_node(ros_context, path, effects=["ground_slop"])
    with pytest.raises(ConfigError, match="offline only"):
        torque_node(ros_context, path, effects=["mocap_time_offset"], effect_parameters=["mocap_time_offset.dt_ms=5"])
