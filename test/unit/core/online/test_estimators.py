"""Frame-by-frame estimators (the nodes' cores) against the offline reconstruction and torques.

Tolerances: states, streamed against offline, are bounded by the filter's round-off
(:func:`euc_ros.testing.savgol_roundoff`, derived there). Torques from the same states go through
the same closed forms (rel/abs 1e-12: a few ulps of the terms), or through the simulator's
independent sympy forms (~1e-12 N m of round-off on torques of ~20 N m: atol 1e-9); the sliding RMSE
against a direct mean differs by its running sum's round-off (~1e-13 relative: rel 1e-9).
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torques, torques_2dof
from euc_ros.core.online.estimators import RiderStateEstimator, TorqueEstimator
from euc_ros.core.session import default_session
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, reconstruct_states
from euc_ros.testing import savgol_roundoff

SESSION = default_session("z")
P = EucParams.from_session(SESSION, 0.61)


@pytest.fixture(scope="module")
def recording(symbolic, synth):
    ride = synth.planar_ride(symbolic, P, duration=8.0, seed=21, decel=0.05)
    n = ride["t"].size
    psi0 = 0.4
    C = np.column_stack([np.cos(psi0) * ride["x"], np.sin(psi0) * ride["x"], np.full(n, P.R)])
    s = synth.synthesize_mocap(SESSION, t=ride["t"], C=C, psi=np.full(n, psi0), theta=np.zeros(n),
                               gamma=ride["gamma"], phi=ride["phi"], h=0.61, rng=np.random.default_rng(3),
                               pos_noise=2e-4, rot_noise=np.radians(0.2))
    e, chl = s.bodies.index("E"), s.bodies.index("CHL")
    s.tracked[e, 400:420] = False          # EUC lost: no state
    s.tracked[chl, 600:602] = False        # rider segment lost 2 frames: bridged per body
    s.tracked[chl, 700:760] = False        # rider segment lost long: EUC state goes on, phi does not
    keep = np.ones(n, bool)
    keep[[150, 151, 800]] = False          # dropped frames
    keep[850:870] = False
    return s.select(s.bodies).__class__(s.t[keep], s.frame[keep], s.bodies, s.position[:, keep], s.quat[:, keep],
                                        s.tracked[:, keep], s.mean_marker_error[:, keep], s.name, dict(s.meta))


def test_frame_by_frame_states_equal_the_offline_reconstruction(recording):
    s = recording
    off = reconstruct_states(s, SESSION)
    est = RiderStateEstimator(SESSION, 1 / 120)
    got = {}
    for _, out in est.update_series(s):
        got[out.frame] = out
    assert est.lag_s == pytest.approx((off.window // 2) / 120)
    # Both paths apply the same Savitzky-Golay fit to the same samples, so they differ by round-off
    # only: each is within savgol_roundoff of the exact filter output. Scales: C is up to ~25 m from
    # the origin; the angles are computed from ~1 m vectors, so their round-off is absolute (a few eps
    # rad) whatever their size: scale 1 rad, with 16 ulps for the geometry before the filter.
    w, po, dt = off.window, DEFAULT_SG_POLYORDER, 1 / 120
    c_scale = float(np.nanmax(np.abs(s.position))) + float(np.linalg.norm(SESSION.euc.pivot_to_wheel_center))
    tol = {"C": 2 * savgol_roundoff(w, po, 0, dt, c_scale)}
    for d, suffix in enumerate(("", "_dot", "_ddot")):
        for angle in ("gamma", "phi"):
            tol[angle + suffix] = 2 * savgol_roundoff(w, po, d, dt, 1.0, input_ulps=16)
        if d:
            tol["x" + suffix] = 2 * savgol_roundoff(w, po, d, dt, c_scale)
    idx = {int(f): i for i, f in enumerate(s.frame)}
    compared = 0
    for f, o in got.items():
        i = idx[f]
        assert o.t == s.t[i]
        if not o.valid:
            assert not off.valid[i] or not np.isfinite(o.phi)
            continue
        for name in ("gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "x_dot", "x_ddot"):
            assert getattr(o, name) == pytest.approx(getattr(off, name)[i], rel=0, abs=tol[name]), name
        np.testing.assert_allclose(o.C, off.C[i], rtol=0, atol=tol["C"])
        compared += 1
    assert compared > 0.3 * s.n_frames  # a 1.2 s window loses 144 edge frames per stretch
    # No state while E is lost, and none for frames that were never recorded.
    assert not any(400 <= f < 420 for f in got) and 150 not in got and 860 not in got
    # The short rider loss is bridged per body before the geometry: those states are valid (and equal
    # offline, above); the long one leaves the EUC state without phi.
    assert got[600].valid and got[601].valid and off.valid[idx[600]] and off.valid[idx[601]]
    assert 730 in got and not got[730].valid and np.isnan(got[730].phi) and np.isfinite(got[730].gamma)
    assert not got[730].has_rider


def test_torque_estimator_never_returns_nan_and_matches_the_offline_torques(recording):
    s = recording
    st = reconstruct_states(s, SESSION)
    te = TorqueEstimator(P, 1 / 120, rmse_window_s=2.0, h_window_s=6.0, h_update_every=30)
    outs, residuals = [], []
    for i in range(st.n):
        state = type("S", (), {k: getattr(st, k)[i] for k in ("gamma", "phi", "gamma_dot", "phi_dot", "x_ddot",
                                                              "gamma_ddot", "phi_ddot", "valid", "frame", "t")})
        o = te.update(state)
        if not st.valid[i]:
            assert o is None
            residuals.append(np.nan)
            continue
        assert o is not None
        assert all(np.isfinite([o.M_d1, o.M_d2, o.M_d1_2dof, o.M_d2_2dof, o.residual_nm]))
        d1, d2 = torques(*[a[i] for a in st.torque_args()], P)
        e1, e2 = torques_2dof(st.phi[i], st.phi_dot[i], st.x_ddot[i], st.phi_ddot[i], P)
        assert (o.M_d1, o.M_d2, o.M_d1_2dof, o.M_d2_2dof) == pytest.approx((d1, d2, e1, e2), rel=1e-12, abs=1e-12)
        residuals.append(d1 - d2)
        outs.append(o)
        last = i
    # the window of the last output: its 240 frames (2 s), by frame number (a dropped frame is a frame of it)
    in_window = (st.frame > st.frame[last] - 240) & (st.frame <= st.frame[last])
    r = np.array(residuals)[in_window[:len(residuals)]]
    r = r[np.isfinite(r)]
    assert outs[-1].rmse_window_nm == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-9)
    assert outs[-1].window_s == pytest.approx(2.0)
    assert np.isfinite(outs[-1].h_online_m) and abs(outs[-1].h_online_m - 0.61) < 0.1
    # A state full of NaN, or an invalid one, gives nothing.
    bad = type("S", (), dict(gamma=np.nan, phi=0.0, gamma_dot=0.0, phi_dot=0.0, x_ddot=0.0, gamma_ddot=0.0,
                             phi_ddot=0.0, valid=True, frame=1, t=0.0))
    assert te.update(bad) is None


# --- stream handling: frame numbers, gaps, restarts ---------------------------------------------------------
def test_frame_sequencer_orders_frames_and_detects_restarts():
    from euc_ros.core.online.estimators import FrameSequencer

    ms = 1_000_000
    seq = FrameSequencer(100.0, restart_jump_s=1.0)
    got = [seq.accept(f, t * ms) for f, t in (
        (10, 0), (11, 10), (13, 30),        # a skipped frame number is a missing frame, not an error
        (13, 30), (12, 20),                  # repeated and out-of-order frames are dropped
        (1, 40),                             # numbering restarted while time went on (a looping replay)
        (2, 50), (3, -5000),                 # time jumped back by 5 s: the source restarted
        (4, -4990))]
    assert [a for a, _ in got] == ["start", "ok", "ok", "drop", "drop", "restart", "ok", "restart", "ok"]
    assert [f for _, f in got] == [10, 11, 13, 13, 12, 1, 2, 3, 4]
    assert seq.restarts == 2 and seq.dropped == 2


def test_frame_sequencer_numbers_frames_from_stamps_when_the_source_has_none():
    from euc_ros.core.online.estimators import FrameSequencer

    seq = FrameSequencer(120.0)
    t0 = 1_700_000_000_000_000_000
    period = 1e9 / 120
    stamps = [t0 + int(round(k * period)) + j for k, j in ((0, 0), (1, 300), (2, -200), (5, 0), (5, 1000), (6, 0))]
    got = [seq.accept(-1, s) for s in stamps]
    assert got == [("start", 0), ("ok", 1), ("ok", 2), ("ok", 5), ("drop", 5), ("ok", 6)]


def _states_of(st, idx):
    keys = ("gamma", "phi", "gamma_dot", "phi_dot", "x_ddot", "gamma_ddot", "phi_ddot", "valid", "frame", "t",
            "x_dot", "psi", "theta")
    return [type("S", (), {k: getattr(st, k)[i] for k in keys}) for i in idx]


def test_torque_estimator_window_covers_time_across_gaps_and_forgets_on_a_jump_back(recording):
    s = recording
    st = reconstruct_states(s, SESSION)
    good = np.flatnonzero(st.valid)
    first = good[(good > 200) & (good < 380)]     # a stretch of valid states ...
    second = good[(good >= first[-1] + 120) & (good < first[-1] + 200)]  # ... 1 s later another one
    te = TorqueEstimator(P, 1 / 120, rmse_window_s=1.5, h_window_s=6.0)
    outs = [te.update(x) for x in _states_of(st, np.concatenate([first, second]))]
    assert all(o is not None for o in outs)
    t = np.array([o.t for o in outs])
    r = np.array([o.residual_nm for o in outs])
    for k in (len(first) - 1, len(first) + 10, len(outs) - 1):
        inside = (t > t[k] - 1.5 + 0.5 / 120) & (t <= t[k])   # the states of the last 1.5 s only
        assert outs[k].rmse_window_nm == pytest.approx(np.sqrt(np.mean(r[inside] ** 2)), rel=1e-9)
    assert te.counts["missing"] == int(round((t[len(first)] - t[len(first) - 1]) * 120)) - 1
    assert te.counts["resets"] == 0
    # The same time again is dropped; a jump back in time (a restarted source) forgets everything.
    assert te.update(_states_of(st, second[-1:])[0]) is None and te.counts["repeated"] == 1
    again = [te.update(x) for x in _states_of(st, first[:30])]
    assert te.counts["resets"] == 1
    r_again = np.array([o.residual_nm for o in again])
    assert again[-1].rmse_window_nm == pytest.approx(np.sqrt(np.mean(r_again ** 2)), rel=1e-9)
    assert np.isnan(again[-1].h_online_m)     # the online h starts over too
    # A gap longer than the RMSE window is a reset as well.
    te.update(_states_of(st, [first[29] + 200])[0])
    assert te.counts["resets"] == 2


# --- the extended model ---------------------------------------------------------------------
def _truth_states(run):
    from types import SimpleNamespace

    return [SimpleNamespace(t=run.t[i], x_dot=run.q_dot[i, 0], x_ddot=run.q_ddot[i, 0], gamma=run.q[i, 1],
                            gamma_dot=run.q_dot[i, 1], gamma_ddot=run.q_ddot[i, 1], phi=run.q[i, 2],
                            phi_dot=run.q_dot[i, 2], phi_ddot=run.q_ddot[i, 2], psi=run.psi[i], theta=run.theta[i],
                            valid=True, frame=int(run.frame[i])) for i in range(run.t.size)]


def _plain_and_extended(ride, effects, rmse_window_s):
    """Outputs of a 3-DoF and of an extended-model TorqueEstimator (h 0.61 m) on the true states of the
    ride's first run; and the extended estimator."""
    from euc_ros.core.model.extended import Model

    p = EucParams.from_session(ride.session, 0.61)
    plain = TorqueEstimator(p, 1 / 120, rmse_window_s=rmse_window_s)
    ext = TorqueEstimator(p, 1 / 120, rmse_window_s=rmse_window_s, model=Model.from_report(p, effects, online=True))
    states = _truth_states(ride.runs[0])
    return [plain.update(x) for x in states], [ext.update(x) for x in states], ext


@pytest.fixture(scope="module")
def sloped_ride():
    from euc_ros.core.ridesim.effects import make_effects
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    return simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=2, duration_s=4.0,
                                    effects=make_effects(["ground_slope"], {"alpha_deg": 3.0})))


def test_extended_model_explains_a_slope_on_the_simulators_true_states(sloped_ride):
    """The simulator derives the slope's gravity independently: with the effect, M_d1 = M_d2 = true M_d."""
    run = sloped_ride.runs[0]
    a, b, _ = _plain_and_extended(sloped_ride, {"ground_slope": {"alpha_deg": 3.0}}, rmse_window_s=2.0)
    assert all(o is not None for o in a + b)
    assert b[-1].model == "3dof+ground_slope" and a[-1].model == "3dof"
    d1, d2 = np.array([o.M_d1 for o in b]), np.array([o.M_d2 for o in b])
    np.testing.assert_allclose(d1, run.M_d, atol=1e-9)
    np.testing.assert_allclose(d2, run.M_d, atol=1e-9)
    assert b[-1].rmse_window_nm < 1e-9 and a[-1].rmse_window_nm > 3.0
    # the 2-DoF torques are the paper's model either way
    assert [o.M_d2_2dof for o in b] == pytest.approx([o.M_d2_2dof for o in a], rel=1e-12)


def test_extended_model_with_a_yaw_rate_effect_uses_a_causal_yaw_rate():
    from euc_ros.core.ridesim.effects import make_effects
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    ride = simulate_ride(RideConfig(maneuver="figure_eight", runs=1, seed=2, duration_s=8.0,
                                    effects=make_effects(["tilt_gravity"], {"gain": 1.0})))
    a, b, ext = _plain_and_extended(ride, {"tilt_gravity": {"gain": 1.0}}, rmse_window_s=8.0)
    n_missing = sum(o is None for o in b)
    assert n_missing == ext._psi_rate.window - 1        # no yaw rate until its first window is full
    assert a[-1].rmse_window_nm > 0.02 and b[-1].rmse_window_nm < 0.15 * a[-1].rmse_window_nm


def test_the_base_model_is_tracked_beside_an_extended_one(sloped_ride):
    """With ``base_h`` the 3-DoF model's sliding RMSE runs beside the extended model's, sample for sample as
    a plain estimator at that h computes it: on the sloped ride the slope model fits better; a slope claimed
    with the wrong sign fits worse than the base model, which is what the node warns about."""
    from euc_ros.core.model.extended import Model

    p = EucParams.from_session(sloped_ride.session, 0.61)
    states = _truth_states(sloped_ride.runs[0])
    plain_estimator = TorqueEstimator(p, 1 / 120, rmse_window_s=2.0)
    plain = [plain_estimator.update(x) for x in states]
    for alpha, better in ((3.0, True), (-3.0, False)):
        ext = TorqueEstimator(p, 1 / 120, rmse_window_s=2.0, base_h=0.61,
                              model=Model.from_report(p, {"ground_slope": {"alpha_deg": alpha}}, online=True))
        out = [ext.update(x) for x in states]
        base = np.array([o.extra["rmse_base_nm"] for o in out])
        np.testing.assert_allclose(base, [o.rmse_window_nm for o in plain], rtol=1e-9)
        assert bool(out[-1].rmse_window_nm < base[-1]) is better
    assert "rmse_base_nm" not in plain[-1].extra
