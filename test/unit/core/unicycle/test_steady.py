"""Steady states, critical values and stability maps, decided from the model's numerical Jacobian.

Tolerances: critical rates are square roots of ratios of the parameters (<= 3 eps relative);
stability coefficients are polynomials in the parameters evaluated two ways (a few ulps of the
largest term, ~60): rel 1e-9 and 1e-12 leave >= 1000x.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from euc_ros.core.unicycle import dynamics as dyn
from euc_ros.core.unicycle import linearize as lz
from euc_ros.core.unicycle import steady as st

PARAM_SETS = [dyn.UnicycleParams(), dyn.UnicycleParams(m=3.0, m0=12.0, R=0.5, g=9.81),
              dyn.UnicycleParams(m=40.0, m0=0.7, R=0.2, g=3.71)]


def _bisect_stability_boundary(p, lo, hi, wheel):
    assert not st.straight_rolling_is_stable(p, lo, wheel) and st.straight_rolling_is_stable(p, hi, wheel)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if st.straight_rolling_is_stable(p, mid, wheel) else (mid, hi)
    return 0.5 * (lo + hi)


@pytest.mark.parametrize("p", PARAM_SETS)
def test_critical_pitch_rates_eqs_27_54(p):
    """Straight rolling turns (neutrally) stable at sqrt(g/3R) (wheel) and sqrt(g/2R) (unicycle, any m, m0)."""
    wheel = _bisect_stability_boundary(p, 0.1, 50.0, wheel=True)
    uni = _bisect_stability_boundary(p, 0.1, 50.0, wheel=False)
    assert wheel == pytest.approx(np.sqrt(p.g / (3 * p.R)), rel=1e-9)
    assert uni == pytest.approx(np.sqrt(p.g / (2 * p.R)), rel=1e-9)
    assert st.wheel_critical_pitch_rate(p) == pytest.approx(wheel, rel=1e-9)
    assert st.unicycle_critical_pitch_rate(p) == pytest.approx(uni, rel=1e-9)


def test_critical_speed_table_1(params):
    v = st.critical_speed(params)
    assert round(v, 2) == 1.21          # the paper's "about 1.21 m/s"
    assert v == pytest.approx(np.sqrt(params.g * params.R / 2))
    assert not st.straight_rolling_is_stable(params, 1.0 / params.R) and st.straight_rolling_is_stable(
        params, 5.0 / params.R)


@pytest.mark.parametrize("pitch_rate", [0.5, 2.0, 3.3, 6.0, 20.0])
def test_wheel_straight_rolling_roots_eq_26(params, pitch_rate):
    x = lz.wheel_straight_rolling_state(params, pitch_rate * params.R)
    J = lz.wheel_jacobian(params, x)[:4, :4]
    assert st.wheel_stability_coefficients(J) == pytest.approx(
        4 * params.g / (5 * params.R) - 12 / 5 * pitch_rate**2, rel=1e-12, abs=1e-12)
    lam = np.sort_complex(np.linalg.eigvals(J))
    assert np.sum(np.abs(lam) < 1e-6) == 2


@pytest.mark.parametrize("p", PARAM_SETS)
@pytest.mark.parametrize("pitch_rate", [1.0, 4.0, 9.0])
def test_unicycle_straight_rolling_charpoly_eqs_51_52(p, pitch_rate):
    A, _ = lz.linearize_straight_rolling(p, pitch_rate * p.R)
    coeffs = np.real(np.poly(A))                          # 10 states: (a l^4 + b l^2 + c) l^6 / a
    a, b, c = st.straight_rolling_coefficients(p, pitch_rate)
    expected = np.zeros(11)
    expected[[0, 2, 4]] = [1.0, b / a, c / a]
    assert np.allclose(coeffs, expected, rtol=1e-9, atol=1e-9 * max(1.0, abs(c / a)))


def test_critical_tilt_angle_eq_23(params):
    """Above 18.62 deg no yaw rate makes the wheel's turning rolling unstable; below it some does."""
    def worst(theta):   # max over yaw rates of lambda^2 (positive: an unstable band exists)
        pd = np.linspace(0.05, 15, 600)
        s = st.wheel_turning_lambda2(params, theta, pd)
        k = int(np.nanargmax(s))
        res = minimize_scalar(lambda q: -st.wheel_turning_lambda2(params, theta, q),
                              bounds=(pd[max(k - 1, 0)], pd[min(k + 1, len(pd) - 1)]), method="bounded",
                              options={"xatol": 1e-10})
        return -res.fun

    theta_c = brentq(worst, np.radians(10), np.radians(25), xtol=1e-10)
    assert np.degrees(theta_c) == pytest.approx(18.62, abs=0.005)
    assert theta_c == pytest.approx(st.critical_tilt_angle(), abs=1e-6)


@pytest.mark.parametrize("theta_deg", [-15.0, 3.0, 10.0, 17.0])
def test_critical_yaw_rates_eq_22(params, theta_deg):
    th = np.radians(theta_deg)
    c1, c2 = st.wheel_critical_yaw_rates(th, params)
    for c in (c1, c2):
        s = st.wheel_turning_lambda2(params, th, np.array([c * (1 - 1e-6), c, c * (1 + 1e-6)]))
        assert abs(s[1]) < 1e-6 * np.max(np.abs(s))   # lambda^2 vanishes on the boundary
        assert s[0] * s[2] < 0
    mid = st.wheel_turning_lambda2(params, th, 0.5 * (c1 + c2))
    assert mid > 0                                      # unstable between the critical rates
    assert st.wheel_turning_lambda2(params, th, 0.5 * c1) < 0
    assert np.all(np.isnan(st.wheel_critical_yaw_rates(np.radians(19.0), params)))


def test_lambda_squared_eq_21_with_errata(params):
    rng = np.random.default_rng(30)
    th = np.radians(rng.uniform(-70, 70, 300))
    pd = rng.uniform(0.1, 10, 300) * rng.choice([-1, 1], 300)
    fd = st.wheel_turning_pitch_rate(th, pd, params)
    eq21 = 4 * params.g / (5 * params.R) * np.cos(th) - (pd**2 + 14 / 5 * pd * fd * np.sin(th) + 12 / 5 * fd**2)
    s = st.wheel_turning_lambda2(params, th, pd)
    assert np.allclose(s, eq21, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("p", PARAM_SETS)
def test_closed_form_steady_states_are_equilibria(p):
    """Eqs (14), (41), (44), (46) make the essential right-hand side vanish."""
    rng = np.random.default_rng(31)
    th = np.radians(rng.uniform(-70, 70, 400))
    pd = rng.uniform(0.2, 9, 400) * rng.choice([-1, 1], 400)
    fd = st.wheel_turning_pitch_rate(th, pd, p)
    xw = st.wheel_steady_state(th, pd, fd)
    assert np.max(np.abs(dyn.wheel_rhs(xw, p)[:4])) < 1e-10 * (1 + np.max(np.abs(xw[:3])) ** 2)

    fd, r = st.unicycle_turning_steady_state(th, pd, p)
    x = st.unicycle_steady_state(th, pd, fd, r)
    keep = np.abs(r) < 10                                  # away from the singular yaw rates (42)
    assert keep.sum() > 300
    f = dyn.unicycle_rhs(x[:, keep], 0.0, p)[:6]
    assert np.max(np.abs(f) / (1 + np.abs(x[:3, keep]).max(axis=0) ** 2)) < 1e-10

    rr = rng.uniform(-0.3, 0.3, 20)
    for sign in (1, -1):
        psi_dot, phi_dot = st.non_tilted_turning(rr, p, sign)
        x = st.unicycle_steady_state(0.0, psi_dot, phi_dot, rr)
        assert np.max(np.abs(dyn.unicycle_rhs(x, 0.0, p)[:6])) < 1e-12

    ths = np.radians(np.linspace(-80, 80, 41))
    w, r = st.tilted_spinning(ths, p)
    ok = np.isfinite(w)
    assert ok.sum() >= 38 and np.all(r[ok] * ths[ok] > 0)   # the mass sits above the centre
    for sign in (1, -1):
        x = st.unicycle_steady_state(ths[ok], sign * w[ok], 0.0, r[ok])
        assert np.max(np.abs(dyn.unicycle_rhs(x, 0.0, p)[:6]) / (1 + w[ok] ** 2)) < 1e-10


def test_unicycle_charpoly_structure_and_classification(params):
    """Essential charpoly is l^2 (l^4 + p l^2 + q) at turning states; the (p, q) test matches eigenvalues."""
    rng = np.random.default_rng(32)
    th = np.radians(rng.uniform(-70, 70, 300))
    pd = rng.uniform(0.2, 12, 300) * rng.choice([-1, 1], 300)
    fd, r = st.unicycle_turning_steady_state(th, pd, params)
    keep = np.abs(r) < 2
    x = st.unicycle_steady_state(th[keep], pd[keep], fd[keep], r[keep])
    A, _ = lz.linearize(params, x)
    J = A[:, :6, :6]
    coeffs = np.array([np.real(np.poly(j)) for j in J])
    scale = np.max(np.abs(coeffs), axis=1)
    assert np.max(np.abs(coeffs[:, [1, 3, 5, 6]]) / scale[:, None]) < 1e-9
    p, q = st.unicycle_stability_coefficients(J)
    assert np.allclose(p, coeffs[:, 2], rtol=1e-8) and np.allclose(q, coeffs[:, 4], rtol=1e-6,
                                                                       atol=1e-9 * scale.max())
    stable = st._unicycle_stable(p, q)
    max_re = np.array([np.max(np.linalg.eigvals(j).real) for j in J])
    rate = np.sqrt(np.abs(p)) + 1
    clear = (max_re > 1e-3 * rate) | (max_re < 1e-7 * rate)
    assert clear.sum() > 0.9 * len(J)
    assert np.array_equal(stable[clear], (max_re < 1e-7 * rate)[clear])
    assert 0 < stable.sum() < len(stable)                    # both kinds occur


def test_wheel_map_matches_eq_22(params):
    th = np.radians(np.linspace(-30, 30, 61))
    pd = np.linspace(-8, 8, 80)
    m = st.wheel_stability_map(params, th, pd)
    c1, c2 = st.wheel_critical_yaw_rates(th, params)
    inside = (np.abs(pd)[None, :] > np.nan_to_num(c1, nan=np.inf)[:, None]) & (
        np.abs(pd)[None, :] < np.nan_to_num(c2, nan=-np.inf)[:, None])
    assert np.array_equal(~m.stable, inside)
    assert inside.sum() > 100 and m.stable.sum() > 100


def test_unicycle_map_consistent(params):
    th = np.radians(np.linspace(-85, 85, 60))
    pd = np.linspace(-15, 15, 60)
    m = st.unicycle_stability_map(params, th, pd)
    assert np.array_equal(m.feasible, np.isfinite(m.phi_dot) & (m.mass_height > 0))
    assert not np.any(m.stable & ~m.feasible)
    assert 0 < m.stable.sum() < m.feasible.sum() < m.feasible.size
    # spot check a few stable and unstable cells with eigenvalues
    rng = np.random.default_rng(33)
    for cls in (True, False):
        ii, jj = np.nonzero(m.feasible & (m.stable == cls))
        for k in rng.choice(len(ii), 5, replace=False):
            x = st.unicycle_steady_state(th[ii[k]], pd[jj[k]], m.phi_dot[ii[k], jj[k]], m.r[ii[k], jj[k]])
            ev = np.linalg.eigvals(lz.linearize(params, x)[0][:6, :6])
            assert (np.max(ev.real) < 1e-6 * (1 + np.max(np.abs(ev)))) == cls
    # m0 = 0 is the wheel
    w = st.unicycle_stability_map(dyn.UnicycleParams(m0=0.0), th, pd)
    assert np.array_equal(w.stable, st.wheel_stability_map(params, th, pd).stable)


def test_fold_counts_contain_every_map_state(params):
    th = np.radians(np.linspace(-60, 60, 24))    # theta = 0 (spinning, straight rolling) is not turning
    pd = np.linspace(-9, 9, 26)
    m = st.wheel_stability_map(params, th, pd)
    TH, PD = np.meshgrid(th, pd, indexing="ij")
    ok = np.abs(m.phi_dot) < 40
    ns, nu = st.wheel_steady_state_counts_tilt(params, TH[ok], m.phi_dot[ok])
    assert np.all(np.where(m.stable[ok], ns, nu) >= 1)
    ns, nu = st.wheel_steady_state_counts_rates(params, PD[ok], m.phi_dot[ok], max_tilt=np.radians(80))
    assert np.all(np.where(m.stable[ok], ns, nu) >= 1)
    # the sand glass of Fig. 3: no turning state at 10 deg and 0.1 rad/s, two stable ones at 20 rad/s
    ns, nu = st.wheel_steady_state_counts_tilt(params, np.radians(10.0), 0.1)
    assert ns + nu == 0
    ns, nu = st.wheel_steady_state_counts_tilt(params, np.radians(10.0), 20.0)
    assert ns == 2 and nu == 0
