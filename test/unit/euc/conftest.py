"""Shared fixtures of the EUC model tests.

``symbolic`` is an independent derivation of the 3-DoF model with sympy: the kinetic energy is built
from the point kinematics of the geometry (C, A, G0, G, rolling wheel) rather than typed from the
paper, the generalized forces from the virtual power of gravity and the two internal torques, then
Lagrange's equations of the second kind (4) are solved for the unknown torques. Nothing here imports
the closed forms under test.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import sympy as sp

PARAM_NAMES = ("m", "J", "m0", "J0", "mw", "Jw", "R", "h0", "l0", "g", "h")


def _derive():
    t = sp.symbols("t")
    m, J, m0, J0, mw, Jw, R, h0, l0, g, h = sp.symbols(PARAM_NAMES, real=True)
    Md, Mh = sp.symbols("M_d M_h", real=True)
    x, gam, ph = (sp.Function(n)(t) for n in ("x", "gamma", "phi"))
    q = [x, gam, ph]
    qd = [c.diff(t) for c in q]
    # Geometry (ERRATA): C = (x, R); A below C along the body axis; G0 above C; G above A.
    C = sp.Matrix([x, R])
    A = C + l0 * sp.Matrix([-sp.sin(gam), -sp.cos(gam)])
    G0 = C + h0 * sp.Matrix([sp.sin(gam), sp.cos(gam)])
    G = A + h * sp.Matrix([sp.sin(ph), sp.cos(ph)])
    vC, vG0, vG = C.diff(t), G0.diff(t), G.diff(t)
    beta_dot = qd[0] / R  # rolling without slip: wheel pitch rate
    T = (sp.Rational(1, 2) * mw * vC.dot(vC) + sp.Rational(1, 2) * Jw * beta_dot**2
         + sp.Rational(1, 2) * m0 * vG0.dot(vG0) + sp.Rational(1, 2) * J0 * qd[1] ** 2
         + sp.Rational(1, 2) * m * vG.dot(vG) + sp.Rational(1, 2) * J * qd[2] ** 2)
    # Power of the active forces: gravity on G and G0; M_d on the wheel (+) and body (-);
    # M_h on the body (+) and rider (-). Contact forces do no work (pure rolling).
    P = (-m * g * vG[1] - m0 * g * vG0[1] + Md * (beta_dot - qd[1]) + Mh * (qd[1] - qd[2]))
    Q = [sp.expand(P).coeff(v) for v in qd]
    eqs = [sp.diff(T.diff(qd[i]), t) - T.diff(q[i]) - Q[i] for i in range(3)]
    xdd, gdd, pdd, xd, gd, pd_ = sp.symbols("xdd gdd pdd xd gd pd", real=True)
    gs, ps, xs = sp.symbols("gs ps xs", real=True)
    subs = {c.diff(t, 2): s for c, s in zip(q, (xdd, gdd, pdd))}
    subs2 = {c.diff(t): s for c, s in zip(q, (xd, gd, pd_))}
    subs3 = {x: xs, gam: gs, ph: ps}
    eqs = [sp.expand(e.subs(subs).subs(subs2).subs(subs3)) for e in eqs]
    T_s = sp.expand(T.subs(subs2).subs(subs3))
    # The equations are linear in the unknowns: solve them as linear systems (Cramer, unsimplified).
    # Eq (9): first row alone.
    A1, b1 = sp.linear_eq_to_matrix([eqs[0]], [Md])
    Md1 = b1[0] / A1[0, 0]
    # Eq (10): all three rows, eliminating x_ddot.
    A3, b3 = sp.linear_eq_to_matrix(eqs, [xdd, Md, Mh])
    det = A3.det(method="berkowitz")
    sol = {}
    for j, unknown in enumerate((xdd, Md, Mh)):
        Aj = A3.copy()
        Aj[:, j] = b3
        sol[unknown] = Aj.det(method="berkowitz") / det
    Md2 = sol[Md]
    # Rider torque with x_ddot measured (rows 1 and 3).
    A13, b13 = sp.linear_eq_to_matrix([eqs[0], eqs[2]], [Md, Mh])
    Mh_meas = A13.LUsolve(b13)[1]
    params = sp.symbols(PARAM_NAMES, real=True)
    args = (gs, ps, gd, pd_, xdd, gdd, pdd) + tuple(params)
    f_Md1 = sp.lambdify(args, Md1, "numpy")
    f_Md2 = sp.lambdify(args, Md2, "numpy")
    f_Mh = sp.lambdify(args, Mh_meas, "numpy")
    # The acceleration the model needs for a given pitch motion (from the same elimination).
    f_xdd = sp.lambdify((gs, ps, gd, pd_, gdd, pdd) + tuple(params), sol[xdd], "numpy")
    # Kinetic energy as printed in the paper (A.1), to compare with the one derived from geometry.
    T_A1 = (sp.Rational(1, 2) * (m + m0 + mw + Jw / R**2) * xd**2
            + sp.Rational(1, 2) * (J0 + m * l0**2 + m0 * h0**2) * gd**2
            + sp.Rational(1, 2) * (J + m * h**2) * pd_**2
            - (m * l0 - m0 * h0) * xd * gd * sp.cos(gs) + m * h * xd * pd_ * sp.cos(ps)
            - m * h * l0 * gd * pd_ * sp.cos(ps - gs))
    return SimpleNamespace(Md1=f_Md1, Md2=f_Md2, Mh=f_Mh, xdd=f_xdd, T_geometry=T_s, T_A1=T_A1,
                           eqs=eqs, params=params)


@pytest.fixture(scope="session")
def symbolic():
    """Lambdified torques from the independent sympy derivation (args: states then PARAM_NAMES)."""
    return _derive()


@pytest.fixture(scope="session")
def rng():
    return np.random.default_rng(20240502)
