"""The generator's Newton-Euler dynamics against closed forms, invariants and the energy balance."""
# covers: euc_ros/core/worldsim/simulate.py
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from euc_ros.core.worldsim.dynamics import (
    PlantParams,
    accelerations,
    energy,
    newton_euler_system,
    solve,
    solve_one,
    torque_power,
)
from euc_ros.core.worldsim.simulate import ATOL_SCALE, draw_spec, integrate

EPS = np.finfo(float).eps
P = PlantParams(R=0.21, m_w=3.5, J_w=0.11, m_0=14.0, J_0=0.55, h_0=0.08, l_0=0.06, m=72.0, J=13.0, h=0.87)


def paper_accelerations(q, qd, M_d, M_h, p: PlantParams) -> np.ndarray:
    """Accelerations from the Lagrangian form printed in the EUC paper, eqs (5)-(8) (written out here)."""
    g, ph = q[..., 1], q[..., 2]
    gd, pd = qd[..., 1], qd[..., 2]
    m, m0, l0, h0, h = p.m, p.m_0, p.l_0, p.h_0, p.h
    M = np.zeros(q.shape[:-1] + (3, 3))
    M[..., 0, 0] = m + m0 + p.m_w + p.J_w / p.R**2
    M[..., 0, 1] = M[..., 1, 0] = -(m * l0 - m0 * h0) * np.cos(g)
    M[..., 0, 2] = M[..., 2, 0] = m * h * np.cos(ph)
    M[..., 1, 1] = p.J_0 + m0 * h0**2 + m * l0**2
    M[..., 1, 2] = M[..., 2, 1] = -m * h * l0 * np.cos(ph - g)
    M[..., 2, 2] = p.J + m * h**2
    hv = np.stack([-m * h * pd**2 * np.sin(ph) + (m * l0 - m0 * h0) * gd**2 * np.sin(g),
                   m * h * l0 * pd**2 * np.sin(ph - g), -m * h * l0 * gd**2 * np.sin(ph - g)], -1)
    Q = np.stack([M_d / p.R, M_h - M_d + (m0 * h0 - m * l0) * p.g * np.sin(g), m * p.g * h * np.sin(ph) - M_h], -1)
    return np.linalg.solve(M, (Q - hv)[..., None])[..., 0], np.linalg.cond(M)


def test_newton_euler_agrees_with_the_papers_lagrangian_form():
    rng = np.random.default_rng(0)
    n = 500
    q = rng.normal(size=(n, 3)) * [2.0, 0.4, 0.6]
    qd = rng.normal(size=(n, 3)) * [3.0, 2.0, 2.0]
    M_d, M_h = rng.normal(size=n) * 60, rng.normal(size=n) * 60
    mine = accelerations(q, qd, M_d, M_h, P)
    theirs, cond_M = paper_accelerations(q, qd, M_d, M_h, P)
    K, _ = newton_euler_system(q, qd, M_d, M_h, P)
    # both are linear solves: forward error <= cond * eps * |result| each (a factor 10 for the assembly)
    tol = 10 * EPS * (np.linalg.cond(K) + cond_M)[:, None] * np.abs(np.concatenate([mine, theirs], 1)).max(1)[:, None]
    assert np.all(np.abs(mine - theirs) <= tol)


def test_scalar_and_vectorized_solves_agree():
    rng = np.random.default_rng(1)
    for _ in range(20):
        q, qd = rng.normal(size=3), rng.normal(size=3)
        a = solve_one(q, qd, 12.0, -7.0, P)
        b = solve(q, qd, 12.0, -7.0, P)
        assert np.allclose(a, b, rtol=0, atol=100 * EPS * np.abs(b).max())


def _free_rhs(p):
    def rhs(t, y):
        acc = solve_one(y[:3], y[3:6], 0.0, 0.0, p)[:3]
        return np.concatenate([y[3:6], acc])
    return rhs


def test_pendulum_on_a_cart_frequency():
    """A hanging rider on a free wheel with h0 = l0 = 0: theta = eps cos(w t) with the textbook w."""
    p = P.with_(h_0=0.0, l_0=0.0)
    m_eq = p.m + p.m_0 + p.m_w + p.J_w / p.R**2
    w = np.sqrt(p.m * p.g * p.h * m_eq / (m_eq * (p.J + p.m * p.h**2) - (p.m * p.h) ** 2))
    eps = 1e-3
    t = np.linspace(0.0, 4 * 2 * np.pi / w, 400)
    rtol = 1e-11
    sol = solve_ivp(_free_rhs(p), (0, t[-1]), [0.0, 0.0, np.pi + eps, 0.0, 0.0, 0.0], method="DOP853",
                    t_eval=t, rtol=rtol, atol=rtol * eps)
    err = sol.y[2] - np.pi - eps * np.cos(w * t)
    # the linearization drops O(eps^3) terms; their effect grows with the phase w t
    assert np.max(np.abs(err)) <= eps**3 * (1 + w * t[-1])
    assert np.max(np.abs(sol.y[1])) <= 1e3 * rtol   # the body's pitch decouples (J_0 gamma_ddot = 0)


def test_free_motion_conserves_energy_and_the_wheels_generalized_momentum():
    """No torques: E and p_x = dT/dx_dot (x cyclic, Q_x = M_d / R = 0) stay constant."""
    p = P
    y0 = np.array([0.0, 0.3, np.pi - 0.8, 1.5, -1.0, 2.0])          # rider hanging and swinging
    rtol = 1e-11
    t = np.linspace(0, 3.0, 301)
    sol = solve_ivp(_free_rhs(p), (0, 3.0), y0, method="DOP853", t_eval=t, rtol=rtol, atol=rtol)
    q, qd = sol.y[:3].T, sol.y[3:].T
    E = energy(q, qd, p)
    d = 1e-6
    px = (energy(q, qd + [d, 0, 0], p) - energy(q, qd - [d, 0, 0], p)) / (2 * d)
    steps = sol.nfev / 12
    # local errors of at most (atol + rtol |y|) per step and component, summed over the steps,
    # weighted by the gradient of the invariant (|dE/dy| <= |E| scale per unit state here)
    scale = np.abs(E).max() + np.abs(px).max()
    tol = steps * rtol * (1 + np.abs(sol.y).max()) * scale
    assert np.ptp(E) <= tol
    assert np.ptp(px) <= tol + 1e-8 * np.abs(px).max()   # + the central difference's rounding


def test_controlled_ride_energy_equals_the_work_of_the_torques():
    spec = draw_spec(5000, duration=3.0)
    t = np.linspace(0.0, 3.0, 361)
    rtol = 1e-10
    sol = integrate(spec, t, rtol=rtol, warmup=0.5)
    y = sol.y.T
    E = energy(y[:, :3], y[:, 3:6], spec.plant)
    mismatch = (E - E[0]) - (y[:, 8] - y[0, 8])
    # gradient of E - W with respect to the state, along the ride (central differences)
    grad = np.zeros_like(y)
    for i in range(6):
        dy = np.zeros(9)
        dy[i] = 1e-6
        yp, ym = y + dy, y - dy
        grad[:, i] = (energy(yp[:, :3], yp[:, 3:6], spec.plant) - energy(ym[:, :3], ym[:, 3:6], spec.plant)) / 2e-6
    grad[:, 8] = 1.0
    local = np.max(np.sum(np.abs(grad) * rtol * (ATOL_SCALE + np.abs(y)), axis=1))
    steps = sol.nfev / 12
    assert np.max(np.abs(mismatch)) <= steps * local
    # and the power the truth records is the derivative of the work
    power = torque_power(y[:, 3:6], y[:, 6], y[:, 7], spec.plant)
    assert np.allclose(np.gradient(y[:, 8], t), power, rtol=0, atol=np.abs(np.gradient(power, t, edge_order=2)).max()
                       * (t[1] - t[0]) + 1e-6)


@pytest.mark.parametrize("seed", [1, 2])
def test_closed_loop_is_stable_and_the_ride_stays_up(seed):
    spec = draw_spec(seed * 1000, duration=2.0)
    lam = np.array(spec.info["closed_loop_eigenvalues"])
    assert np.all(lam[:, 0] < 0)
    assert 0 < spec.info["pitch_mode_hz"]
