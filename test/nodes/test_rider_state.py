"""rider_state node in-process: MocapFrame messages of a simulated ride in, RiderState messages out.

The frames are published over DDS by a feeder node and the states read back by a probe, all in one
private rclpy context; each frame is drained through the graph before the next one is sent, so the
comparison with the ROS-free core is exact and nothing is lost to queue depths. The node and the core
run the same code on the same doubles, so they agree to the last bits (rtol/atol 1e-12); against the
offline reconstruction the tolerance is the filter's round-off (:func:`euc_ros.testing.savgol_roundoff`).
The helpers (:class:`Pipe`, the frames' messages, the node with the tests' filter) are in helpers.py.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

from euc_ros.core.errors import ConfigError, InputError  # noqa: E402
from euc_ros.core.states.kinematics import reconstruct_states  # noqa: E402
from euc_ros.nodes.rider_state import RiderStateNode  # noqa: E402
from euc_ros.testing import load_module, savgol_roundoff  # noqa: E402

pytestmark = pytest.mark.ros

H = load_module(Path(__file__).with_name("helpers.py"), "node_helpers")
T0_NS, TEST_FILTER, stamp_ns, frame_msgs, rider_node, core_states = (
    H.T0_NS, H.TEST_FILTER, H.stamp_ns, H.frame_msgs, H.rider_node, H.core_states)

FIELDS = ("x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "phi_eq3",
          "phi_hinge", "psi", "theta")


def test_states_equal_the_core_and_carry_their_own_frames_stamp(pipes, ros_context, ride):
    series, session, path = ride
    node = rider_node(ros_context, path)
    pipe = pipes([node])
    pipe.feed(frame_msgs(series))
    want = core_states(series, session)
    got = {stamp_ns(m.header.stamp): m for m in pipe.states}
    assert len(pipe.states) == len(want) == node.counts["states"] and set(got) == set(want)
    frame_stamps = {T0_NS + int(round(float(t) * 1e9)) for t in series.t}
    assert set(got) <= frame_stamps                      # each state is stamped with its own frame's time
    for stamp, m in got.items():
        s = want[stamp]
        for k in FIELDS:
            np.testing.assert_allclose(getattr(m, k), getattr(s, k), rtol=1e-12, atol=1e-12, equal_nan=True,
                                       err_msg=k)
        np.testing.assert_allclose([m.c.x, m.c.y, m.c.z], s.C, rtol=1e-12, atol=1e-12)
        assert m.has_rider == s.has_rider and m.phi_definition == "hinge" and m.header.frame_id == "world"
        assert m.filter_lag == pytest.approx(54 / 120)
    # ... and away from the edges of each stretch, equal to the offline reconstruction
    off = reconstruct_states(series, session, **TEST_FILTER)
    idx = {T0_NS + int(round(float(t) * 1e9)): i for i, t in enumerate(series.t)}
    interior = [st for st, m in got.items() if off.valid[idx[st]] and np.isfinite(m.phi)]
    assert len(interior) > 80
    # the same fit on the same samples by the streaming and the offline filter: each within
    # savgol_roundoff of the exact output (C up to max|pivot| + |p| from the origin; phi's round-off
    # is absolute, from ~1 m vectors: scale 1 rad, 16 ulps for the geometry)
    w, po, dt = off.window, TEST_FILTER["polyorder"], 1 / session.rate_hz
    c_scale = float(np.nanmax(np.abs(series.position))) + float(np.linalg.norm(session.euc.pivot_to_wheel_center))
    tol_x = 2 * savgol_roundoff(w, po, 2, dt, c_scale)
    tol_phi = 2 * savgol_roundoff(w, po, 2, dt, 1.0, input_ulps=16)
    for st in interior:
        i = idx[st]
        assert got[st].x_ddot == pytest.approx(off.x_ddot[i], rel=0, abs=tol_x)
        assert got[st].phi_ddot == pytest.approx(off.phi_ddot[i], rel=0, abs=tol_phi)


def test_missing_bodies_and_frames(pipes, ros_context, ride):
    series, session, path = ride
    node = rider_node(ros_context, path)
    pipe = pipes([node])
    pipe.feed(frame_msgs(series))
    by_frame = {int(series.frame[np.flatnonzero(T0_NS + np.round(series.t * 1e9).astype(np.int64)
                                                == stamp_ns(m.header.stamp))[0]]): m for m in pipe.states}
    # a lost EUC gives no state (nor do frames that never came, or were bridged around it)
    assert not any(150 <= f < 160 for f in by_frame) and 100 not in by_frame and 400 not in by_frame
    assert node.counts["no_euc"] == 10
    # a rider segment lost for 2 frames (<= max_gap) is bridged per body: rider present, G finite (phi
    # there is NaN for another reason: the long loss from frame 300 lies within half a window)
    for f in (250, 251):
        m = by_frame[f]
        assert m.has_rider and np.all(np.isfinite([m.gamma, m.x_ddot, m.g.x]))
    # lost longer: the EUC state goes on, has_rider false, phi and G NaN
    m = by_frame[320]
    assert np.isfinite(m.gamma) and np.isfinite(m.x_ddot)
    assert np.isnan(m.phi) and np.isnan(m.phi_ddot) and np.isnan(m.g.x)
    assert not m.has_rider
    assert by_frame[230].has_rider and np.isfinite(by_frame[230].phi) and np.isfinite(by_frame[230].g.z)
    assert node.counts["no_rider"] == sum(not m.has_rider for m in pipe.states) == 40   # frames 300-339


def test_repeated_frames_are_dropped_and_a_restarted_source_restarts_the_filters(pipes, ros_context, ride):
    series, session, path = ride
    node = rider_node(ros_context, path)
    pipe = pipes([node])
    msgs = frame_msgs(series, frames=range(0, 120))
    pipe.feed(msgs[:80] + [msgs[79], msgs[60]] + msgs[80:])     # a repeat and an out-of-order frame
    assert node.sequencer.dropped == 2
    n_first = len(pipe.states)
    assert n_first == len(core_states(series, session, frames=range(0, 120)))
    # The source restarts: the same recording again with the same stamps (time jumps back 1 s).
    pipe.feed(frame_msgs(series, frames=range(0, 120)))
    assert node.sequencer.restarts == 1
    second = pipe.states[n_first:]
    assert len(second) == n_first                   # a fresh start: no state mixes the two streams
    for a, b in zip(pipe.states[:n_first], second):
        assert stamp_ns(a.header.stamp) == stamp_ns(b.header.stamp)
        assert b.gamma_ddot == a.gamma_ddot and b.x_ddot == a.x_ddot
    # A looping replay: numbering restarts while the stamps go on.
    later = frame_msgs(series, t0_ns=T0_NS + 10**10, frames=range(0, 120))
    pipe.feed(later)
    assert node.sequencer.restarts == 2 and len(pipe.states) == 3 * n_first


def test_frames_without_numbers_are_numbered_from_their_stamps(pipes, ros_context, ride):
    series, session, path = ride
    node = rider_node(ros_context, path)
    pipe = pipes([node])
    msgs = frame_msgs(series, frames=range(0, 200))
    for m in msgs:
        m.frame_number = -1
    pipe.feed(msgs)
    want = core_states(series, session, frames=range(0, 200))
    assert {stamp_ns(m.header.stamp) for m in pipe.states} == set(want)  # frames 100-101 missing, as numbered


def test_eq3_definition_and_filter_settings_are_honoured(pipes, ros_context, ride):
    series, session, path = ride
    node = rider_node(ros_context, path, phi_definition="eq3", window_s=0.3, polyorder=3)
    pipe = pipes([node])
    pipe.feed(frame_msgs(series, frames=range(0, 100)))
    want = core_states(series, session, frames=range(0, 100), phi_definition="eq3", window_s=0.3, polyorder=3)
    assert len(pipe.states) == len(want) > 0
    m = pipe.states[10]
    s = want[stamp_ns(m.header.stamp)]
    assert m.phi_definition == "eq3" and m.phi == pytest.approx(s.phi, abs=1e-12)
    assert m.filter_lag == pytest.approx(node.estimator.lag_s) and m.filter_lag < 0.2


def test_diagnostics_count_what_happened(pipes, ros_context, ride):
    series, session, path = ride
    node = rider_node(ros_context, path, diagnostics_period=0.05)
    pipe = pipes([node])
    pipe.feed(frame_msgs(series, frames=range(140, 200)))
    pipe.spin_until(lambda: any(st.name == "rider_state: states" and any(
        kv.key == "frames" and kv.value == "60" for kv in st.values) for a in pipe.diag for st in a.status),
        what="diagnostics")
    vals = {kv.key: kv.value for a in pipe.diag for st in a.status if st.name == "rider_state: states"
            for kv in st.values}
    assert vals["no_euc"] == "10" and vals["filter_lag_s"] == "0.45"


def test_session_errors(ros_context, tmp_path, ride):
    _, _, path = ride
    with pytest.raises(ConfigError, match="session_file"):
        RiderStateNode(context=ros_context)
    bad = tmp_path / "bad.yaml"
    bad.write_text(path.read_text().replace("wheel_radius", "wheel_radios"))
    with pytest.raises(InputError, match="wheel_radios"):
        rider_node(ros_context, bad)


def test_session_error_is_one_line_and_exit_2(ros_domain, tmp_path, ride):
    _, _, path = ride
    bad = tmp_path / "bad.yaml"
    bad.write_text(path.read_text().replace("wheel_radius", "wheel_radios"))
    exe = Path(sys.executable).parent / "rider_state"
    r = subprocess.run([str(exe), "--ros-args", "-p", f"session_file:={bad}"], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(bad) in lines[0] and "wheel_radios" in lines[0], r.stderr
