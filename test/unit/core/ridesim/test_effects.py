"""One test per effect: it changes the truth exactly as its virtual-power derivation says.

Pattern: the paper's eqs (5)-(8), written by hand in conftest.py with the *nominal* parameters, are
evaluated along a trajectory generated *with* the effect. Their residual ``M q_ddot + h - Q`` must
equal the effect's generalized force dQ as documented in docs/ridesim.md (formulas written again
here, by hand), to integration tolerance; and it must be large enough to matter.

Tolerances: the accelerations along the trajectory are the simulator's own (evaluated at each
state, not differentiated), so the residual equals dQ up to the round-off of two algebraic routes
through terms of up to ~1e3 N m: ~1e-12 N m, far inside TOL = 1e-8 of max(|dQ|, 1 N m). Closed-form
checks of geometry (a few operations on <= 1 m values) use 1e-12..1e-9, >= 1000 ulps.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.rotations import rotate
from euc_ros.core.session import default_rider

G = 9.81
TOL = 1e-8


def _states(run):
    x, ga, ph = run.q.T
    xd, gd, pd = run.q_dot.T
    return x, ga, ph, xd, gd, pd


def _assert_residual_is(res, expected, min_size):
    scale = np.abs(expected).max()
    assert scale > min_size, f"effect too small to test: {scale}"
    np.testing.assert_allclose(res, expected, rtol=0, atol=TOL * max(scale, 1.0))


def test_baseline_without_effect_has_zero_residual(effect_ride, paper):
    ride = effect_ride(None)
    run = ride.runs[0]
    assert np.abs(paper.run_residual(ride, run, ride.params_nominal)).max() < TOL * np.abs(run.M_d).max()


def test_rolling_resistance(effect_ride, paper):
    ride = effect_ride("rolling_resistance", c_rr=0.02)
    run, p = ride.runs[0], ride.params_nominal
    xd = run.q_dot[:, 0]
    N = (p.m + p.m0 + p.mw) * G
    F = -0.02 * N * np.tanh(xd / 0.05)
    expected = np.column_stack([F, 0 * F, 0 * F])
    _assert_residual_is(paper.run_residual(ride, run, p), expected, 10.0)


def test_viscous_friction(effect_ride, paper):
    ride = effect_ride("viscous_friction", c_v=8.0)
    run, p = ride.runs[0], ride.params_nominal
    F = -8.0 * run.q_dot[:, 0]
    _assert_residual_is(paper.run_residual(ride, run, p), np.column_stack([F, 0 * F, 0 * F]), 5.0)


def test_aero_drag(effect_ride, paper):
    ride = effect_ride("aero_drag", cda_m2=0.8)
    run, p = ride.runs[0], ride.params_nominal
    x, ga, ph, xd, gd, pd = _states(run)
    h = run.h
    # G = (x - l0 sin(gamma) + h sin(phi), R - l0 cos(gamma) + h cos(phi))
    vx = xd - p.l0 * np.cos(ga) * gd + h * np.cos(ph) * pd
    vz = p.l0 * np.sin(ga) * gd - h * np.sin(ph) * pd
    speed = np.hypot(vx, vz)
    Fx, Fz = -0.5 * 1.2 * 0.8 * speed * vx, -0.5 * 1.2 * 0.8 * speed * vz
    expected = np.column_stack([Fx, -p.l0 * np.cos(ga) * Fx + p.l0 * np.sin(ga) * Fz,
                                h * np.cos(ph) * Fx - h * np.sin(ph) * Fz])
    _assert_residual_is(paper.run_residual(ride, run, p), expected, 2.0)


def test_ground_slope(effect_ride, paper):
    alpha = np.radians(3.0)
    ride = effect_ride("ground_slope", runs=2, alpha_deg=3.0)
    p = ride.params_nominal
    mean_dq_x = []
    for run in ride.runs:
        # the floor rises along +x; in the floor (recorded) frame gravity is tilted
        g_x = -G * np.sin(alpha) * np.cos(run.psi)
        g_z = -G * np.cos(alpha) + 0 * g_x
        ga, ph = run.q[:, 1], run.q[:, 2]
        m, m0, mw, l0, h0, h = p.m, p.m0, p.mw, p.l0, p.h0, run.h
        expected = np.column_stack([
            (m + m0 + mw) * g_x,
            (m0 * h0 - m * l0) * (g_x * np.cos(ga) - g_z * np.sin(ga)) - (m0 * h0 - m * l0) * G * np.sin(ga),
            m * h * (g_x * np.cos(ph) - g_z * np.sin(ph)) - m * G * h * np.sin(ph),
        ])
        _assert_residual_is(paper.run_residual(ride, run, p), expected, 20.0)
        assert np.abs(paper.run_residual(ride, run, p, g_x=g_x, g_z=g_z)).max() < TOL * 100
        mean_dq_x.append(expected[:, 0].mean())
    # psi = 0 rides uphill (pulled back), psi = pi downhill
    assert [r.plan.path.psi0 for r in ride.runs] == [0.0, np.pi]
    assert mean_dq_x[0] < -30 and mean_dq_x[1] > 30


def test_wheel_radius_error(effect_ride, paper):
    ride = effect_ride("wheel_radius_error", delta_r_m=0.012)
    run, p = ride.runs[0], ride.params_nominal
    assert ride.session.euc.wheel_radius == p.R == 0.2  # the session keeps the nominal radius
    true = p.with_changes(R=p.R + 0.012)
    assert np.abs(paper.run_residual(ride, run, true)).max() < TOL * 100
    assert np.abs(paper.run_residual(ride, run, p)[:, 0]).max() > 2.0
    # C (from E with the session's pivot) sits at the true rolling radius
    mc = run.mocap_clean
    i = mc.bodies.index("E")
    C = mc.position[i] + rotate(mc.quat[i], np.asarray(ride.session.euc.pivot_to_wheel_center))
    np.testing.assert_allclose(C[:, 2], 0.212 * np.cos(run.theta), atol=1e-12)


def _cog(series, session):
    names, fr, off = session.segment_arrays()
    idx = [series.bodies.index(n) for n in names]
    return np.einsum("b,bni->ni", fr, series.position[idx] + rotate(series.quat[idx], off[:, None, :]))


def test_mocap_time_offset(effect_ride):
    base = effect_ride(None)
    ride = effect_ride("mocap_time_offset", dt_ms=25.0)  # 3 frames at 120 Hz
    run, run0 = ride.runs[0], base.runs[0]
    # measurement only: the dynamics are untouched
    np.testing.assert_array_equal(run.M_d, run0.M_d)
    np.testing.assert_array_equal(run.q, run0.q)
    # E is on time, the rider segments show the rider of 25 ms earlier
    iE = run.mocap_clean.bodies.index("E")
    np.testing.assert_allclose(run.mocap_clean.position[iE], run0.mocap_clean.position[iE], atol=1e-12)
    G_rec = _cog(run.mocap_clean, ride.session)
    assert np.abs(G_rec[3:] - run.G[:-3]).max() < 1e-8
    assert np.abs(G_rec[3:] - run.G[3:]).max() > 0.05  # ~ 25 ms x 3 m/s


def test_rider_mass_error(effect_ride, paper):
    ride = effect_ride("rider_mass_error", delta_m_kg=12.0)
    run, p = ride.runs[0], ride.params_nominal
    assert ride.session.rider.mass == 65.0 and ride.params_true.m == 77.0
    x, ga, ph, xd, gd, pd = _states(run)
    xdd, gdd, pdd = run.q_ddot.T
    h, l0 = run.h, p.l0
    # d(residual)/dm, from eqs (5)-(8): every term carrying the rider mass m
    d_dm = np.column_stack([
        xdd - l0 * np.cos(ga) * gdd + h * np.cos(ph) * pdd - h * pd**2 * np.sin(ph) + l0 * gd**2 * np.sin(ga),
        -l0 * np.cos(ga) * xdd + l0**2 * gdd - h * l0 * np.cos(ph - ga) * pdd + h * l0 * pd**2 * np.sin(ph - ga)
        + l0 * G * np.sin(ga),
        h * np.cos(ph) * xdd - h * l0 * np.cos(ph - ga) * gdd + h**2 * pdd - h * l0 * gd**2 * np.sin(ph - ga)
        - G * h * np.sin(ph),
    ])
    _assert_residual_is(paper.run_residual(ride, run, p), -12.0 * d_dm, 5.0)


def test_rider_inertia_error(effect_ride, paper):
    ride = effect_ride("rider_inertia_error", delta_j_kgm2=6.0)
    run, p = ride.runs[0], ride.params_nominal
    nominal = ride.session.rider.inertia_pitch
    assert nominal == default_rider().inertia_pitch and ride.params_true.J == pytest.approx(nominal + 6.0)
    pdd = run.q_ddot[:, 2]
    expected = np.column_stack([0 * pdd, 0 * pdd, -6.0 * pdd])
    _assert_residual_is(paper.run_residual(ride, run, p), expected, 0.5)


def test_tilt_gravity(effect_ride, paper):
    ride = effect_ride("tilt_gravity", gain=1.0)
    run, p = ride.runs[0], ride.params_nominal
    # apparent gravity along the tilted plane's -z: g cos(theta) - a_c sin(theta), a_c = x_dot psi_dot
    a_c = run.q_dot[:, 0] * run.psi_dot
    g_eff = G * np.cos(run.theta) - a_c * np.sin(run.theta)
    ga, ph, h = run.q[:, 1], run.q[:, 2], run.h
    expected = np.column_stack([0 * ga, (p.m0 * p.h0 - p.m * p.l0) * (g_eff - G) * np.sin(ga),
                                p.m * h * (g_eff - G) * np.sin(ph)])
    _assert_residual_is(paper.run_residual(ride, run, p), expected, 0.3)
    assert np.abs(paper.run_residual(ride, run, p, g_z=-g_eff)).max() < TOL * 100
    # leaning into the turn makes the apparent gravity larger (coordinated turn: sqrt(g^2 + a_c^2))
    assert np.mean(g_eff - G) > 0.05
    turn = np.abs(a_c) > 1.5
    np.testing.assert_allclose(g_eff[turn], np.hypot(G, a_c[turn]), rtol=0.01)


def test_time_varying_h(effect_ride, paper):
    ride = effect_ride("time_varying_h", amplitude_m=0.06, period_s=2.0)
    run, p = ride.runs[0], ride.params_nominal
    t = run.t
    np.testing.assert_allclose(run.h, 0.61 + 0.06 * np.sin(np.pi * t), atol=1e-14)
    hd = 0.06 * np.pi * np.cos(np.pi * t)
    hdd = -0.06 * np.pi**2 * np.sin(np.pi * t)
    ga, ph, pd = run.q[:, 1], run.q[:, 2], run.q_dot[:, 2]
    m, l0, h = p.m, p.l0, run.h
    # rheonomic terms from d/dt dT/dq_dot - dT/dq with G = A + h(t) e_phi (docs/ridesim.md)
    extra = np.column_stack([
        m * hdd * np.sin(ph) + 2 * m * hd * pd * np.cos(ph),
        -m * l0 * (hdd * np.sin(ph - ga) + 2 * hd * pd * np.cos(ph - ga)),
        2 * m * h * hd * pd,
    ])
    _assert_residual_is(paper.run_residual(ride, run, p), -extra, 5.0)
    # the skeleton stretches with h(t): the segment CoG is the true G at distance h(t) from A
    G_rec = _cog(run.mocap_clean, ride.session)
    assert np.abs(G_rec - run.G).max() < 1e-9
    np.testing.assert_allclose(np.linalg.norm(G_rec - run.A, axis=1), h, atol=1e-9)


def _md1_md2(p, run):
    """M_d from row 1 alone and from rows 2 + 3 (M_h eliminated), paper eqs (5)-(8), nominal p."""
    x, ga, ph, xd, gd, pd = _states(run)
    xdd, gdd, pdd = run.q_ddot.T
    m, m0, mw, Jw, J0, J, R, l0, h0 = p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R, p.l0, p.h0
    h = run.h
    m11, m12, m13 = m + m0 + mw + Jw / R**2, -(m * l0 - m0 * h0) * np.cos(ga), m * h * np.cos(ph)
    m22, m23, m33 = J0 + m0 * h0**2 + m * l0**2, -m * h * l0 * np.cos(ph - ga), J + m * h**2
    h1 = -m * h * pd**2 * np.sin(ph) + (m * l0 - m0 * h0) * gd**2 * np.sin(ga)
    h2 = m * h * l0 * pd**2 * np.sin(ph - ga)
    h3 = -m * h * l0 * gd**2 * np.sin(ph - ga)
    Md1 = R * (m11 * xdd + m12 * gdd + m13 * pdd + h1)
    rows23 = (m12 + m13) * xdd + (m22 + m23) * gdd + (m23 + m33) * pdd + h2 + h3
    Md2 = (m0 * h0 - m * l0) * G * np.sin(ga) + m * G * h * np.sin(ph) - rows23
    return Md1, Md2


def test_wheel_body_friction_is_invisible_to_md1_minus_md2(effect_ride, paper):
    """Negative control: dQ = tau [1/R, -1, 0] is in span(b_d), so the data look like a motor torque
    M_d + tau and M_d1 = M_d2; a contact force like rolling resistance is not."""
    ride = effect_ride("wheel_body_friction", c_wb=0.3)
    run, p = ride.runs[0], ride.params_nominal
    xd, gd = run.q_dot[:, 0], run.q_dot[:, 1]
    tau = -0.3 * (xd / p.R - gd)
    assert np.abs(tau).max() > 3.0
    res = paper.residual(p, run.q, run.q_dot, run.q_ddot, run.h, run.M_d + tau, run.M_h)
    assert np.abs(res).max() < TOL * 100
    Md1, Md2 = _md1_md2(p, run)
    assert np.abs(Md1 - Md2).max() < 1e-7
    np.testing.assert_allclose(Md1, run.M_d + tau, atol=1e-7)
    assert np.abs(Md1 - run.M_d).max() > 3.0
    rr = effect_ride("rolling_resistance", c_rr=0.02)
    Md1, Md2 = _md1_md2(p, rr.runs[0])
    assert np.abs(Md1 - Md2).max() > 1.0
