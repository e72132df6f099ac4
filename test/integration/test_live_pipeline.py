"""The live pipeline as separate processes over DDS:

CSV source -> mocap_ingest -> rider_state -> torque_estimator -> recorder (and the monitor), then the
bag is read back and the recorded torques are compared with the offline torques that ``identify``
computes on the same CSV (``reconstruct_states`` + ``torques`` at the same h).

Expected agreement. The online derivative filter is the fixed-lag twin of the offline
Savitzky-Golay filter (same window, same polynomial, evaluated half a window back), and the online
estimator only publishes states whose whole window was measured. Offline, those samples are interior
samples of their stretch, where the two filters apply the same weights to the same data. So every
published torque equals the offline one up to rounding: each state within savgol_roundoff of the
exact filter output (1.2 s, order 6 at 120 Hz, C up to ~25 m from the origin: 1.8e-10 m/s^2 on
x_ddot; ~1e-11 rad/s^2 on the pitches), times the torques' sensitivities ((m + m0 + mw) R ~ 16 kg m
to x_ddot, J + m h^2 ~ 41 kg m^2 to phi_ddot): ~1e-8 N m. We require 1e-6 N m. The node publishes
the states the test's own core computes from the same doubles: equal to the last bits (1e-9).
Near the edges of a stretch (recording ends, long occlusions) the offline filter fits shorter,
asymmetric stretches (``mode="interp"``); the online one publishes nothing there, which the test
checks as "no state for those frames", not as a tolerance.
"""
from __future__ import annotations

import io
import time
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torques, torques_2dof
from euc_ros.core.online.estimators import RiderStateEstimator
from euc_ros.core.session import load_session
from euc_ros.core.states.kinematics import reconstruct_states
from euc_ros.ros.launcher import Launcher, NodeSpec

pytestmark = [pytest.mark.ros, pytest.mark.integration]
REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config"
H = 0.61
RMSE_WINDOW_S = 2.0


@pytest.fixture(scope="module")
def gappy_ride(tmp_path_factory):
    """A 5 s deceleration run with two occlusion gaps and dropped frames, as Motive CSV + session."""
    from euc_ros.core.ridesim.mocap_synth import MocapNoise
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    d = tmp_path_factory.mktemp("live")
    result = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=12, duration_s=5.0,
                                      noise=MocapNoise(gaps=2, gap_min_s=0.1, gap_max_s=0.4, drop_rate=0.01)))
    write_ride(result, d)
    return d / "deceleration_01.csv", d / "session.yaml"


def _stamp(msg) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def _subscriptions(node, topic: str) -> int:
    return len(node.get_subscriptions_info_by_topic(topic))


@pytest.mark.parametrize("composed", [False, True], ids=["processes", "container"])
def test_live_torques_match_the_offline_identification(ros_context, gappy_ride, tmp_path, composed):
    """Separate processes, and ingest + rider_state + torque_estimator composed in one
    ``pipeline_container`` (linked in-process): the same states and torques, every one."""
    import rclpy

    csv, session_file = gappy_ride
    bag = tmp_path / "bag"
    log = io.StringIO()
    session_params = {"session_file": str(session_file)}
    nodes = [
        NodeSpec("recorder", params_file=str(CONFIG / "recorder.yaml"), parameters={"output": str(bag)},
                 required=False),
        NodeSpec("monitor", params_file=str(CONFIG / "monitor.yaml"), parameters={"timeout_s": 5.0},
                 required=False),
    ]
    ingest_params = {"csv_path": str(csv), "exit_when_done": True, "rate_factor": 1.0, "start_delay": 0.0,
                     "wait_subscribers": 3, "linger": 1.5}
    if composed:
        # one process: its rider_state counts as one of the 3 frame subscriptions it waits for
        ingest = [NodeSpec("pipeline_container", params_file=str(CONFIG / "mocap_ingest.yaml"),
                           params_files=[str(CONFIG / "rider_state.yaml"), str(CONFIG / "torque_estimator.yaml")],
                           parameters=dict(session_params, h=H, rmse_window_s=RMSE_WINDOW_S, **ingest_params))]
    else:
        nodes += [
            NodeSpec("torque_estimator", params_file=str(CONFIG / "torque_estimator.yaml"),
                     parameters=dict(session_params, h=H, rmse_window_s=RMSE_WINDOW_S)),
            NodeSpec("rider_state", params_file=str(CONFIG / "rider_state.yaml"), parameters=session_params),
        ]
        ingest = [NodeSpec("mocap_ingest", params_file=str(CONFIG / "mocap_ingest.yaml"), parameters=ingest_params)]
    probe = rclpy.create_node("graph_probe", context=ros_context)
    t_start = time.monotonic()
    try:
        with Launcher(nodes, stream=log) as pipeline:
            # Start the source only once every downstream subscription exists, so nothing is lost to
            # discovery (the recorder subscribes to rider/state and euc/torque when they appear).
            def graph_ready():
                if composed:
                    return (_subscriptions(probe, "/rider/state") >= 2 and _subscriptions(probe, "/euc/torque") >= 2
                            and _subscriptions(probe, "/mocap/frame") >= 2)
                return (_subscriptions(probe, "/rider/state") >= 3 and _subscriptions(probe, "/euc/torque") >= 2
                        and _subscriptions(probe, "/mocap/frame") >= 2)

            assert pipeline.wait(timeout=45, until=graph_ready), "nodes did not come up:\n" + log.getvalue()
            with Launcher(ingest, stream=log) as source:
                assert source.wait(timeout=45), "replay did not finish:\n" + log.getvalue()
            assert source.exit_codes[ingest[0].label] == 0, log.getvalue()
            assert pipeline.poll(), "a pipeline node died:\n" + log.getvalue()
        assert all(code == 0 for code in pipeline.exit_codes.values()), (pipeline.exit_codes, log.getvalue())
    finally:
        probe.destroy_node()
    if composed:   # the links were made in-process: no DDS subscription of rider_state or torque_estimator
        assert "in-process: mocap_ingest -> rider_state on /mocap/frame" in log.getvalue(), log.getvalue()
        assert "in-process: rider_state -> torque_estimator on /rider/state" in log.getvalue(), log.getvalue()
    wall = time.monotonic() - t_start
    assert check_bag(bag) == []

    recorded = {t: [] for t in ("/mocap/frame", "/rider/state", "/euc/torque", "/diagnostics")}
    for topic, _, _, msg in read_bag(bag, topics=list(recorded)):
        recorded[topic].append(msg)
    series = read_motive_csv(csv, world_up="y")
    session = load_session(session_file)

    # -- no frame lost, anywhere ---------------------------------------------------------------------
    frames = recorded["/mocap/frame"]
    assert [f.frame_number for f in frames] == [int(f) for f in series.frame]
    t0 = _stamp(frames[0])
    index = {_stamp(f): k for k, f in enumerate(frames)}           # stamp -> row of the CSV
    core = RiderStateEstimator(session, 1 / session.rate_hz)
    expected_states = {}
    for _, s in core.update_series(series):
        expected_states[int(np.flatnonzero(series.frame == s.frame)[0])] = s
    states = recorded["/rider/state"]
    state_rows = [index[_stamp(m)] for m in states]                 # every state carries its frame's stamp
    assert sorted(state_rows) == sorted(expected_states) and len(states) == len(expected_states)
    for m, k in zip(states, state_rows):
        s = expected_states[k]
        assert m.gamma_ddot == pytest.approx(s.gamma_ddot, abs=1e-9) and m.x_ddot == pytest.approx(s.x_ddot, abs=1e-9)
        assert (np.isnan(m.phi_ddot) and np.isnan(s.phi_ddot)) or m.phi_ddot == pytest.approx(s.phi_ddot, abs=1e-9)

    # -- the torques: never NaN, one per usable state, equal to the offline ones ------------------------
    tq = recorded["/euc/torque"]
    usable = [k for m, k in zip(states, state_rows)
              if np.all(np.isfinite([m.phi, m.phi_dot, m.phi_ddot, m.gamma_ddot, m.x_ddot]))]
    assert len(states) - len(usable) > 0                            # the occlusions cost states their rider
    rows = [index[_stamp(m)] for m in tq]
    assert rows == usable                                           # in order, none lost, none invented
    vals = np.array([[m.m_d1, m.m_d2, m.m_d1_2dof, m.m_d2_2dof, m.residual, m.rmse_window] for m in tq])
    assert np.all(np.isfinite(vals)) and all(m.valid for m in tq) and all(m.h == H for m in tq)

    off = reconstruct_states(series, session)                       # what `euc-ros identify` computes
    p = EucParams.from_session(session, H)
    d1, d2 = torques(*off.torque_args(), p)
    e1, e2 = torques_2dof(off.phi, off.phi_dot, off.x_ddot, off.phi_ddot, p)
    rows = np.array(rows)
    assert off.valid[rows].all()                                    # every published sample is valid offline
    diff = np.abs(vals[:, :4] - np.column_stack([d1, d2, e1, e2])[rows])
    assert diff.max() < 1e-6, f"live vs offline torque difference {diff.max():.3g} N m"
    # the offline valid samples the live filter cannot give: only within half a window of a stretch edge
    lag = core.lag_s * session.rate_hz
    missing = np.setdiff1d(np.flatnonzero(off.valid), rows)
    edges = _stretch_edges(series.frame, off.valid)
    assert all(min(abs(series.frame[k] - e) for e in edges) <= lag + 1 for k in missing)

    # the sliding RMSE: the residuals of the last 2 s of published samples
    t = (np.array([_stamp(m) for m in tq]) - t0) * 1e-9
    r_off = (d1 - d2)[rows]
    for k in range(0, len(tq), 37):
        inside = (t > t[k] - RMSE_WINDOW_S + 0.5 / session.rate_hz) & (t <= t[k] + 1e-9)
        assert vals[k, 5] == pytest.approx(np.sqrt(np.mean(r_off[inside] ** 2)), rel=1e-6, abs=1e-9)

    # -- the monitor and the estimators report on /diagnostics ------------------------------------------
    statuses = [s for a in recorded["/diagnostics"] for s in a.status]
    names = {s.name for s in statuses}
    assert {"monitor: mocap", "monitor: model consistency", "rider_state: states", "torque_estimator: torques"} <= names
    consistency = [s for s in statuses if s.name == "monitor: model consistency" and s.level == 0]
    assert consistency, "the model consistency was never OK on a ride the model explains"
    te_last = [s for s in statuses if s.name == "torque_estimator: torques"][-1]
    te_vals = {kv.key: kv.value for kv in te_last.values}
    assert int(te_vals["published"]) == len(tq) and int(te_vals["not_usable"]) == len(states) - len(usable)
    print(f"live pipeline: {len(frames)} frames, {len(states)} states, {len(tq)} torques, "
          f"max |live - offline| = {diff.max():.2e} N m, wall {wall:.1f} s")


def _stretch_edges(frame: np.ndarray, valid: np.ndarray) -> list[int]:
    """Frame numbers where a stretch of measured samples starts or ends (recording ends, long gaps, losses)."""
    edges = [int(frame[0]), int(frame[-1])]
    for k in range(1, frame.size):
        if frame[k] - frame[k - 1] > 1 or valid[k] != valid[k - 1]:
            edges += [int(frame[k - 1]), int(frame[k])]
    return edges
