"""The sympy-derived truth model against the paper's eqs (5)-(8) written by hand, and invariants.

Tolerances: the two sides are closed forms of the same quantities evaluated in other orders, so
they differ by round-off: a few ulps of the largest term that enters (terms up to ~1e3 N m here,
one ulp 1.1e-13), never more than ~100 ulps. The tolerances leave >= 30x over that bound.
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from euc_ros.core.ridesim.truth_model import PlanarModel, PlanarParams

RNG_SEED = 1234


def _random_params(rng):
    # perturb every nominal value so that swapped parameters cannot pass
    base = PlanarParams()
    return base.with_changes(**{k: getattr(base, k) * rng.uniform(0.7, 1.3)
                                for k in ("m", "m0", "mw", "Jw", "J0", "J", "R", "l0", "h0")})


def _random_states(rng, n):
    q = np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-0.3, 0.3, n), rng.uniform(-0.5, 0.5, n)])
    qd = rng.normal(0, [2.0, 1.0, 1.5], (n, 3))
    qdd = rng.normal(0, [3.0, 5.0, 5.0], (n, 3))
    return q, qd, qdd


def _model_residual(model, q, qd, qdd, h, hd, hdd, gx, gz, M_d, M_h):
    p = model.params
    M = model.mass_matrix(q[:, 1], q[:, 2], h)
    b = model.bias(q[:, 1], q[:, 2], qd[:, 0], qd[:, 1], qd[:, 2], h, hd, hdd, gx, gz)
    Q = np.column_stack([M_d / p.R, M_h - M_d, -M_h])
    return np.einsum("nij,nj->ni", M, qdd) + b - Q


def test_derived_model_equals_paper_eqs_5_to_8(paper):
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(5):
        p = _random_params(rng)
        model = PlanarModel(p)
        q, qd, qdd = _random_states(rng, 200)
        h = rng.uniform(0.3, 1.0, 200)
        M_d, M_h = rng.normal(0, 40, 200), rng.normal(0, 40, 200)
        ours = _model_residual(model, q, qd, qdd, h, 0.0, 0.0, 0.0, -paper.g, M_d, M_h)
        theirs = paper.residual(p, q, qd, qdd, h, M_d, M_h)
        scale = np.abs(theirs).max()
        assert scale > 1.0
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-11 * scale)   # 45000 ulps of the scale


def test_general_gravity_vector_is_sum_of_point_forces(paper):
    rng = np.random.default_rng(RNG_SEED + 1)
    p = _random_params(rng)
    model = PlanarModel(p)
    q, qd, qdd = _random_states(rng, 300)
    gx, gz = rng.normal(0, 2, 300), -9.81 + rng.normal(0, 1, 300)
    ours = _model_residual(model, q, qd, qdd, 0.61, 0.0, 0.0, gx, gz, 0.0, 0.0)
    theirs = paper.residual(p, q, qd, qdd, 0.61, 0.0, 0.0, g_x=gx, g_z=gz)
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-10)   # terms <= ~1e3 N m: ~900 ulps


def test_time_varying_h_adds_the_rheonomic_terms_of_the_docs():
    """h(t) adds [m h'' sin(phi) + 2 m h' phi' cos(phi), -m l0 (h'' sin(phi-gamma) + 2 h' phi' cos(phi-gamma)),
    2 m h h' phi'] to the left-hand side (docs/ridesim.md, time_varying_h), derived there by hand."""
    rng = np.random.default_rng(RNG_SEED + 2)
    p = _random_params(rng)
    model = PlanarModel(p)
    q, qd, _ = _random_states(rng, 300)
    ga, ph, pd = q[:, 1], q[:, 2], qd[:, 2]
    h, hd, hdd = rng.uniform(0.4, 0.9, 300), rng.normal(0, 0.3, 300), rng.normal(0, 2.0, 300)
    args = (ga, ph, qd[:, 0], qd[:, 1], pd, h)
    delta = model.bias(*args, hd, hdd, 0.0, -9.81) - model.bias(*args, 0.0, 0.0, 0.0, -9.81)
    m, l0 = p.m, p.l0
    expected = np.column_stack([
        m * hdd * np.sin(ph) + 2 * m * hd * pd * np.cos(ph),
        -m * l0 * (hdd * np.sin(ph - ga) + 2 * hd * pd * np.cos(ph - ga)),
        2 * m * h * hd * pd,
    ])
    # the difference of two biases of up to ~500 N m: a few ulps of 500 (1e-13) each
    np.testing.assert_allclose(delta, expected, rtol=0, atol=1e-11)
    # and the mass matrix uses the instantaneous h
    M = model.mass_matrix(ga, ph, h)
    np.testing.assert_allclose(M[:, 2, 2], p.J + p.m * h**2, rtol=1e-14)   # 3 ops on positive terms: <= 3 eps


def _energy(p, y, g=9.81, h=0.61):
    """Kinetic + potential energy from the point velocities (written independently of the model)."""
    x, ga, ph, xd, gd, pd = y
    vC = np.array([xd, 0 * xd])
    vG0 = np.array([xd + p.h0 * np.cos(ga) * gd, -p.h0 * np.sin(ga) * gd])
    vG = np.array([xd - p.l0 * np.cos(ga) * gd + h * np.cos(ph) * pd, p.l0 * np.sin(ga) * gd - h * np.sin(ph) * pd])
    T = (0.5 * p.mw * (vC**2).sum(0) + 0.5 * p.Jw * (xd / p.R) ** 2 + 0.5 * p.m0 * (vG0**2).sum(0)
         + 0.5 * p.J0 * gd**2 + 0.5 * p.m * (vG**2).sum(0) + 0.5 * p.J * pd**2)
    V = g * (p.mw * p.R + p.m0 * (p.R + p.h0 * np.cos(ga)) + p.m * (p.R - p.l0 * np.cos(ga) + h * np.cos(ph)))
    return T + V


def test_unforced_motion_conserves_energy():
    p = PlanarParams()
    model = PlanarModel(p)

    def rhs(t, y):
        a = model.accel_scalar(y[1], y[2], y[3], y[4], y[5], 0.61, 0.0, 0.0, 0.0, -9.81, 0.0, 0.0, 0.0)
        return [y[3], y[4], y[5], *a]

    y0 = [0.0, 0.05, 0.1, 1.0, -0.2, 0.3]
    sol = solve_ivp(rhs, (0, 0.8), y0, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=np.linspace(0, 0.8, 50))
    assert sol.success
    assert np.ptp(sol.y[2]) > 0.2  # the rider really falls: energy moves between T and V
    E = _energy(p, sol.y)
    assert np.abs(E - E[0]).max() < 1e-8 * abs(E[0])
