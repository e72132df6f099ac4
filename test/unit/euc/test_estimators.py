"""Frame-by-frame estimators (the nodes' cores) against the offline reconstruction and torques."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.euc.estimators import RiderStateEstimator, TorqueEstimator
from euc_ros.core.euc.kinematics import reconstruct_states
from euc_ros.core.euc.model import EucParams
from euc_ros.core.euc.torque import torques, torques_2dof
from euc_ros.core.session import default_session

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
    s.tracked[chl, 600:602] = False        # rider segment lost 2 frames: bridged, flagged
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
    for k in range(s.n_frames):
        for out in est.update(int(s.frame[k]), float(s.t[k]), s.position[:, k], s.quat[:, k], s.tracked[:, k],
                              s.bodies):
            got[out.frame] = out
    assert est.lag_s == pytest.approx(54 / 120)
    idx = {int(f): i for i, f in enumerate(s.frame)}
    compared = 0
    for f, o in got.items():
        i = idx[f]
        assert o.t == s.t[i]
        if not o.valid:
            assert not off.valid[i] or not np.isfinite(o.phi)
            continue
        for name in ("gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "x_dot", "x_ddot"):
            v = getattr(o, name)
            assert v == pytest.approx(getattr(off, name)[i], abs=1e-9 * max(1, abs(v))), name
        np.testing.assert_allclose(o.C, off.C[i], atol=1e-9)
        compared += 1
    assert compared > 0.4 * s.n_frames  # a 0.9 s window loses 108 edge frames per stretch
    # No state while E is lost, and none for frames that were never recorded.
    assert not any(400 <= f < 420 for f in got) and 150 not in got and 860 not in got
    # The short rider loss is bridged but flagged; the long one leaves the EUC state without phi.
    assert not got[600].valid and not got[601].valid
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
    r = np.array(residuals[last - 239:last + 1])  # the window of the last output
    r = r[np.isfinite(r)]
    assert outs[-1].rmse_window_nm == pytest.approx(np.sqrt(np.mean(r**2)), rel=1e-9)
    assert outs[-1].window_s == pytest.approx(2.0)
    assert np.isfinite(outs[-1].h_online_m) and abs(outs[-1].h_online_m - 0.61) < 0.1
    # A state full of NaN, or an invalid one, gives nothing.
    bad = type("S", (), dict(gamma=np.nan, phi=0.0, gamma_dot=0.0, phi_dot=0.0, x_ddot=0.0, gamma_ddot=0.0,
                             phi_ddot=0.0, valid=True, frame=1, t=0.0))
    assert te.update(bad) is None
