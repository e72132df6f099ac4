"""Closed forms of eqs (5)-(10) and (13) against the independent sympy derivation (conftest).

Tolerances: closed forms against lambdified sympy expressions of the same quantities, evaluated
in other orders. Both are sums of ~50 products of terms up to ~1e3 N m (one ulp 1.1e-13), M_d2 and
M_h divided by a denominator that stays >= ~1 % of its terms over the random states: the difference
is a few hundred ulps at most, ~1e-11 relative. rtol 1e-10..1e-9 (with atol for values near zero)
leaves >= 10x; rtol 1e-13 where the same code runs on broadcast and scalar parameters.
"""
# covers: euc_ros/core/model/terms.py
# covers: euc_ros/core/model/torque_compiled.py
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from euc_ros.core.model.terms import (
    EucParams,
    bias_terms,
    consistency_weights,
    gravity_forces,
    input_directions,
    mass_matrix,
)
from euc_ros.core.model.torque import rider_torque, torques, torques_2dof


def _random_params(rng, n=None):
    """Random but physical parameters (scalars, or arrays of shape (n,))."""
    size = n
    return EucParams(m=rng.uniform(40, 110, size), J=rng.uniform(5, 25, size), m0=rng.uniform(8, 25, size),
                     J0=rng.uniform(0.1, 1.5, size), mw=rng.uniform(2, 6, size), Jw=rng.uniform(0.05, 0.3, size),
                     R=rng.uniform(0.15, 0.3, size), h0=rng.uniform(-0.1, 0.15, size),
                     l0=rng.uniform(0.0, 0.12, size), g=rng.uniform(9.7, 9.9, size), h=rng.uniform(0.2, 1.2, size))


def _random_states(rng, n):
    return dict(gamma=rng.uniform(-0.4, 0.4, n), phi=rng.uniform(-0.5, 0.5, n), gamma_dot=rng.normal(0, 1, n),
                phi_dot=rng.normal(0, 1, n), x_ddot=rng.normal(0, 2, n), gamma_ddot=rng.normal(0, 5, n),
                phi_ddot=rng.normal(0, 5, n))


def _pvals(p):
    return [getattr(p, k) for k in ("m", "J", "m0", "J0", "mw", "Jw", "R", "h0", "l0", "g", "h")]


def _sargs(s):
    return (s["gamma"], s["phi"], s["gamma_dot"], s["phi_dot"], s["x_ddot"], s["gamma_ddot"], s["phi_ddot"])


def test_compiled_torque_difference_is_numpys_bit_for_bit_and_the_symbolic_residual(symbolic, rng, monkeypatch):
    """Scalar parameters take the compiled loop: against the sympy eqs (9)-(10) (an independent derivation,
    to the same tolerance as numpy's version), and equal to numpy's expression bit for bit (the same terms in
    the same order), with and without an extra force."""
    from euc_ros.core.model import torque

    for trial in range(5):
        n = 300 + 7 * trial
        p = _random_params(rng)
        s = _random_states(rng, n)
        ref = symbolic.Md1(*_sargs(s), *_pvals(p)) - symbolic.Md2(*_sargs(s), *_pvals(p))
        fast = torque.torque_difference(*_sargs(s), p)
        np.testing.assert_allclose(fast, ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref)))
        dQ = rng.normal(0.0, 20.0, (n, 3))
        fast_q = torque.torque_difference(*_sargs(s), p, extra_Q=dQ)
        assert torque._compiled_difference(*(np.asarray(a, float) for a in _sargs(s)), p, None) is not None
        with monkeypatch.context() as m:
            m.setattr(torque, "_compiled_difference", lambda *a, **k: None)
            np.testing.assert_array_equal(fast, torque.torque_difference(*_sargs(s), p))
            np.testing.assert_array_equal(fast_q, torque.torque_difference(*_sargs(s), p, extra_Q=dQ))


@pytest.mark.parametrize("per_sample", [("h",), ("g",), ("h", "g", "R", "m0")])
def test_compiled_torque_difference_with_per_sample_parameters_is_numpys_bit_for_bit(symbolic, rng, monkeypatch,
                                                                                    per_sample):
    """Parameters given per sample (an effect that moves h or g sample by sample) take the compiled loop too:
    against the sympy eqs (9)-(10) per sample, and equal to numpy's broadcast expression bit for bit."""
    import dataclasses

    from euc_ros.core.model import torque

    n = 257
    p = _random_params(rng)
    each = _random_params(rng, n)
    p = dataclasses.replace(p, **{k: getattr(each, k) for k in per_sample})
    s = _random_states(rng, n)
    ref = symbolic.Md1(*_sargs(s), *_pvals(p)) - symbolic.Md2(*_sargs(s), *_pvals(p))
    assert torque._compiled_difference(*(np.asarray(a, float) for a in _sargs(s)), p, None) is not None
    dQ = rng.normal(0.0, 20.0, (n, 3))
    fast, fast_q = torque.torque_difference(*_sargs(s), p), torque.torque_difference(*_sargs(s), p, extra_Q=dQ)
    np.testing.assert_allclose(fast, ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref)))
    with monkeypatch.context() as m:
        m.setattr(torque, "_compiled_difference", lambda *a, **k: None)
        np.testing.assert_array_equal(fast, torque.torque_difference(*_sargs(s), p))
        np.testing.assert_array_equal(fast_q, torque.torque_difference(*_sargs(s), p, extra_Q=dQ))
    # parameters per sample of another length are numpy's (broadcasting decides)
    other = dataclasses.replace(p, h=rng.uniform(0.2, 1.2, n + 1))
    assert torque._compiled_difference(*(np.asarray(a, float) for a in _sargs(s)), other, None) is None


def test_kinetic_energy_from_geometry_equals_paper_A1(symbolic):
    assert sp.simplify(sp.expand_trig(symbolic.T_geometry - symbolic.T_A1)) == 0


def test_mass_matrix_bias_and_gravity_match_lagrange_equations(symbolic, rng):
    """The residual of each symbolic Lagrange equation equals (M q_dd + h - Q_g - M_d b_d - M_h b_h)_i."""
    n = 200
    p = _random_params(rng, n)
    s = _random_states(rng, n)
    Md, Mh = rng.normal(0, 40, n), rng.normal(0, 40, n)
    sym_syms = sp.symbols("xdd gdd pdd xd gd pd gs ps xs M_d M_h", real=True)
    f = sp.lambdify(sym_syms + symbolic.params, symbolic.eqs, "numpy")
    xd = rng.normal(0, 3, n)
    ev = np.stack([np.broadcast_to(v, (n,)) for v in f(s["x_ddot"], s["gamma_ddot"], s["phi_ddot"], xd,
                                                        s["gamma_dot"], s["phi_dot"], s["gamma"], s["phi"],
                                                        np.zeros(n), Md, Mh, *_pvals(p))], -1)
    q = np.stack([np.zeros(n), s["gamma"], s["phi"]], -1)
    qd = np.stack([xd, s["gamma_dot"], s["phi_dot"]], -1)
    qdd = np.stack([s["x_ddot"], s["gamma_ddot"], s["phi_ddot"]], -1)
    b_d, b_h = input_directions(p)
    closed = (np.einsum("nij,nj->ni", mass_matrix(q, p), qdd) + bias_terms(q, qd, p) - gravity_forces(q, p)
              - Md[:, None] * b_d - Mh[:, None] * b_h)
    np.testing.assert_allclose(closed, ev, rtol=1e-10, atol=1e-9)
    w = consistency_weights(p)
    assert np.allclose(np.sum(w * b_d, -1), 0) and np.allclose(np.sum(w * b_h, -1), 0)


def test_torques_match_symbolic_eqs_9_and_10_at_random_states(symbolic, rng):
    n = 500
    p = _random_params(rng, n)
    s = _random_states(rng, n)
    M_d1, M_d2 = torques(*_sargs(s), p)
    np.testing.assert_allclose(M_d1, symbolic.Md1(*_sargs(s), *_pvals(p)), rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(M_d2, symbolic.Md2(*_sargs(s), *_pvals(p)), rtol=1e-9, atol=1e-8)
    # M_d2 does not use the measured x_ddot.
    s2 = dict(s, x_ddot=s["x_ddot"] + 10.0)
    assert np.array_equal(torques(*_sargs(s2), p)[1], M_d2)
    np.testing.assert_allclose(rider_torque(*_sargs(s), p), symbolic.Mh(*_sargs(s), *_pvals(p)), rtol=1e-9,
                               atol=1e-8)


def test_reduced_model_eq_13_matches_symbolic_and_3dof_with_zero_body_terms(symbolic, rng):
    n = 300
    p = _random_params(rng, n).reduced()
    s = _random_states(rng, n)
    d1, d2 = torques_2dof(s["phi"], s["phi_dot"], s["x_ddot"], s["phi_ddot"], p)
    vals = _pvals(p)
    np.testing.assert_allclose(d1, symbolic.Md1(*_sargs(s), *vals), rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(d2, symbolic.Md2(*_sargs(s), *vals), rtol=1e-9, atol=1e-8)
    e1, e2 = torques(*_sargs(s), p)
    np.testing.assert_allclose(d1, e1, rtol=1e-11, atol=1e-10)
    np.testing.assert_allclose(d2, e2, rtol=1e-11, atol=1e-10)
    # ... and the full model really differs when the body terms are present.
    f1, f2 = torques(*_sargs(s), _random_params(np.random.default_rng(1), n))
    assert np.max(np.abs((f1 - f2) - (e1 - e2))) > 1.0


def test_extra_force_in_input_span_leaves_the_residual_unchanged(rng):
    n = 100
    p = _random_params(rng, n)
    s = _random_states(rng, n)
    b_d, b_h = input_directions(p)
    alpha, beta = rng.normal(0, 20, n), rng.normal(0, 20, n)
    extra = alpha[:, None] * b_d + beta[:, None] * b_h
    d1, d2 = torques(*_sargs(s), p)
    e1, e2 = torques(*_sargs(s), p, extra_Q=extra)
    np.testing.assert_allclose(e1 - e2, d1 - d2, atol=1e-9)
    # The torque the EUC must supply drops by exactly the part of the extra force along b_d.
    np.testing.assert_allclose(e1, d1 - alpha, atol=1e-9)
    # A generalized force outside the span does change the residual.
    f1, f2 = torques(*_sargs(s), p, extra_Q=np.tile([5.0, 0.0, 0.0], (n, 1)))
    assert np.min(np.abs((f1 - f2) - (d1 - d2))) > 0.1


def test_parameters_broadcast_against_samples(rng):
    s = _random_states(rng, 50)
    grid = np.linspace(0.2, 1.0, 7)
    p = EucParams().with_h(grid[:, None])
    d1, d2 = torques(*_sargs(s), p)
    assert d1.shape == (7, 50)
    for i, h in enumerate(grid):
        r1, r2 = torques(*_sargs(s), EucParams(h=h))
        np.testing.assert_allclose(d1[i], r1, rtol=1e-13)
        np.testing.assert_allclose(d2[i], r2, rtol=1e-13)


def test_params_from_session_uses_nominal_values():
    from euc_ros.core.session import default_session

    session = default_session()
    p = EucParams.from_session(session, 0.5)
    assert (p.m, p.J, p.m0, p.J0, p.mw, p.Jw, p.R, p.h0, p.l0, p.h) == (65.0, session.rider.inertia_pitch, 13.0, 0.5,
                                                                          3.0, 0.12, 0.2, 0.075, 0.05, 0.5)
    assert p.m_eq == pytest.approx(65 + 13 + 3 + 0.12 / 0.04)


def test_torque_difference_matches_the_symbolic_residual(symbolic, rng):
    """The residual analysis' direct M_d1 - M_d2 (no torques formed), against the sympy eqs (9)-(10),
    with per-sample parameters and an extra generalized force (which enters w . dQ)."""
    from euc_ros.core.model.torque import torque_difference

    n = 500
    p = _random_params(rng, n)
    s = _random_states(rng, n)
    ref = symbolic.Md1(*_sargs(s), *_pvals(p)) - symbolic.Md2(*_sargs(s), *_pvals(p))
    scale = np.max(np.abs(ref))
    np.testing.assert_allclose(torque_difference(*_sargs(s), p), ref, rtol=1e-9, atol=1e-9 * scale)
    dQ = rng.normal(0.0, 20.0, (n, 3))
    m1, m2 = torques(*_sargs(s), p, extra_Q=dQ)
    np.testing.assert_allclose(torque_difference(*_sargs(s), p, extra_Q=dQ), m1 - m2, rtol=1e-9,
                               atol=1e-9 * np.max(np.abs(m1 - m2)))


def test_one_sample_torques_match_the_symbolic_eqs_and_the_array_path(symbolic, rng):
    """The live path (torques_one: one sample, scalar parameters, written out) against the sympy
    eqs (9)-(10), and against torques() with an extra generalized force. Same tolerances as the
    array path's test above (both are double-precision evaluations of the same closed forms)."""
    from euc_ros.core.model.torque import torques_one

    for _ in range(200):
        p = _random_params(rng)
        s = {k: float(v[0]) for k, v in _random_states(rng, 1).items()}
        m1, m2 = torques_one(*_sargs(s), p)
        assert isinstance(m1, float) and isinstance(m2, float)
        assert m1 == pytest.approx(float(symbolic.Md1(*_sargs(s), *_pvals(p))), rel=1e-10, abs=1e-9)
        assert m2 == pytest.approx(float(symbolic.Md2(*_sargs(s), *_pvals(p))), rel=1e-9, abs=1e-8)
        dQ = rng.normal(0.0, 20.0, 3)
        w1, w2 = torques(*_sargs(s), p, extra_Q=dQ)
        o1, o2 = torques_one(*_sargs(s), p, extra_Q=dQ)
        # terms up to ~1e3 N m summed in another order: ~1e-13 relative each, 1e-8 N m absolute is 100x that
        assert o1 == pytest.approx(float(w1), rel=1e-10, abs=1e-8)
        assert o2 == pytest.approx(float(w2), rel=1e-10, abs=1e-8)
