"""Candidate effects against the ride simulator's truth (an independent sympy derivation, no shared code).

Along the simulator's true states, the model extended with the true effect and parameters must give
M_d1 = M_d2 (to integration tolerance), while the paper's model alone does not.

Tolerances: parameter conversions (amplitude from two components, angles back and forth) are a
few elementary operations: rel 1e-9 / atol 1e-12 are >= 1000 ulps.
"""
# covers: euc_ros/core/model/candidate.py
import numpy as np
import pytest

from euc_ros.core.model.candidate import ModelContext
from euc_ros.core.model.effects import LIBRARY, make_candidates, theta_from_report
from euc_ros.core.model.extended import Model
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.selection import detectability
from euc_ros.core.ridesim.effects import make_effects
from euc_ros.core.ridesim.mocap_synth import MocapNoise
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.contexts import Recording

CASES = {
    "rolling_resistance": ("deceleration", {"c_rr": 0.02}),
    "viscous_friction": ("deceleration", {"c_v": 12.0}),
    "aero_drag": ("deceleration", {"cda_m2": 0.8}),
    "ground_slope": ("deceleration", {"alpha_deg": 3.0}),
    "wheel_radius_error": ("deceleration", {"delta_r_m": 0.02}),
    "rider_mass_error": ("deceleration", {"delta_m_kg": 12.0}),
    "rider_inertia_error": ("deceleration", {"delta_j_kgm2": 6.0}),
    "tilt_gravity": ("figure_eight", {"gain": 1.0}),
    "time_varying_h": ("deceleration", {"amplitude_m": 0.08, "period_s": 4.0}),
    "wheel_body_friction": ("deceleration", {"c_wb": 1.5}),
}


def _truth_recording(effect, maneuver, values, seed=3):
    res = simulate_ride(RideConfig(maneuver=maneuver, runs=1, seed=seed, duration_s=4.0,
                                   effects=make_effects([effect], values), noise=MocapNoise.none()))
    run = res.runs[0]
    params = EucParams.from_session(res.session, 0.61)
    q, qd, qdd = run.q, run.q_dot, run.q_ddot
    ctx = ModelContext(t=run.t, x_dot=qd[:, 0], x_ddot=qdd[:, 0], gamma=q[:, 1], gamma_dot=qd[:, 1],
                       gamma_ddot=qdd[:, 1], phi=q[:, 2], phi_dot=qd[:, 2], phi_ddot=qdd[:, 2], psi=run.psi,
                       psi_dot=run.psi_dot, theta=run.theta, params=params)
    return Recording(run.name, ctx, np.zeros(run.t.size, int)), run


@pytest.mark.parametrize("effect", sorted(CASES))
def test_extended_model_explains_the_true_effect(effect):
    maneuver, values = CASES[effect]
    rec, run = _truth_recording(effect, maneuver, values)
    cand = make_candidates([effect])[0]
    theta = theta_from_report(cand, values)
    if effect == "time_varying_h":
        # the simulator's h(t) = h + a sin(w t_sim): its phase at the recording start, from the true h(t)
        w = 2 * np.pi / values["period_s"]
        basis = np.stack([np.sin(w * rec.ctx.t), np.cos(w * rec.ctx.t)], axis=1)
        ab = np.linalg.lstsq(basis, run.h - 0.61, rcond=None)[0]
        assert np.hypot(*ab) == pytest.approx(values["amplitude_m"], rel=1e-9)
        theta = np.array([ab[0], ab[1], values["period_s"]])
    r_base, _ = Model().residual(rec, np.array([0.61]))
    r_true, mask = Model([cand]).residual(rec, np.concatenate([[0.61], theta]))
    scale = max(np.sqrt(np.mean(r_base ** 2)), 1e-3)
    assert np.sqrt(np.mean(r_true[mask] ** 2)) < 1e-6 * max(scale, 1.0) + 1e-6
    if effect != "wheel_body_friction":
        assert np.sqrt(np.mean(r_base ** 2)) > 1e-3, "the effect should show in the paper's model"
    else:
        assert np.sqrt(np.mean(r_base ** 2)) < 1e-6, "wheel-body friction is invisible in M_d1 - M_d2"


def test_detectability_flags_forces_in_the_input_span():
    rec, _ = _truth_recording("wheel_body_friction", "deceleration", {"c_wb": 1.0})
    vis = {c.name: detectability(c, [rec], 0.61) for c in make_candidates()}
    assert vis["wheel_body_friction"] < 1e-9
    for name, v in vis.items():
        if name not in ("wheel_body_friction", "mocap_time_offset"):
            assert v > 1e-3, name


def test_library_names_follow_the_spec():
    assert set(LIBRARY) >= {"rolling_resistance", "viscous_friction", "aero_drag", "ground_slope",
                            "wheel_radius_error", "mocap_time_offset", "rider_mass_error", "rider_inertia_error",
                            "tilt_gravity", "time_varying_h"}


def test_report_round_trip():
    for cand in make_candidates():
        theta = np.array([q.scale * 0.7 for q in cand.params])
        if cand.name == "time_varying_h":
            theta = np.array([0.03, -0.04, 5.0])
        back = theta_from_report(cand, cand.report(theta))
        np.testing.assert_allclose(back, theta, atol=1e-12)
