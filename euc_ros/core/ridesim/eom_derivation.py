"""Lagrange's equations of the ride simulator's three truth geometries, derived with sympy.

The geometries are those of :mod:`.truth_model`'s models: the planar EUC + rider on level ground
(:func:`derive_planar`, the point kinematics of the EUC paper's Fig. 5 with the geometry of
``papers/ERRATA.md``), a floor of varying slope in a level lab (:func:`derive_floor`) and pedals that flex
(:func:`derive_pedal`). Each writes down the points' positions, lets sympy form the kinetic and potential
energy and Lagrange's equations of the second kind (EUC paper, eq. 4), once per process on first use, and
lambdifies the mass matrix ``M``, the bias ``b`` (velocity and rheonomic terms minus gravity) and the rider
CoG's Jacobian and velocity. :mod:`.eom_codegen` prints them into :mod:`.eom_generated`, which the
simulator runs without sympy. None of this shares code with the model and states packages (the estimator).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    import sympy as sp


@dataclass(frozen=True)
class Derivation:
    """Lambdified pieces of a derived model and its sympy expressions.

    Each piece comes in a scalar ``math`` (``_s``) and a vectorized ``numpy`` (``_v``) version; the arguments are
    the derivation's symbols (SI units, rad), the physical parameters last
    (:class:`~euc_ros.core.ridesim.truth_model.PlanarParams` order, ``g`` left out).

    Parameters
    ----------
    mass_s, mass_v : callable
        Mass matrix entries (upper triangle of the 3x3 matrix, or all 16 of the 4x4).
    bias_s, bias_v : callable
        Bias vector b.
    jac_g_s, jac_g_v : callable
        dG/d(x, gamma, phi) of the rider CoG, row-major (2, 3).
    vel_g_s, vel_g_v : callable
        In-plane velocity of the rider CoG (2,).
    M, b : sympy.Matrix
        The mass matrix and bias as sympy expressions.
    syms : dict
        The symbols by role (``q``, ``qd``, ``qdd``, ``h``, ``g``, ``params``...).
    functions : dict
        ``{"mass": (args, exprs), "bias": ...}``: what each function computes (for code generation).
    """

    mass_s: Callable
    bias_s: Callable
    jac_g_s: Callable
    vel_g_s: Callable
    mass_v: Callable
    bias_v: Callable
    jac_g_v: Callable
    vel_g_v: Callable
    # sympy expressions kept for the docs, for independent checks and for code generation
    M: sp.Matrix
    b: sp.Matrix
    syms: dict
    #: ``{"mass": (args, exprs), "bias": ..., "jac_g": ..., "vel_g": ...}``: what each function computes
    functions: dict


def _time_to_symbols(t, pairs) -> dict:
    """``{f'': s2, f': s1, f: s0}`` for each ``(f(t), s0, s1, s2)``: functions of time to plain symbols."""
    subs = {}
    for f, s0, s1, s2 in pairs:
        subs[f.diff(t, 2)] = s2
        subs[f.diff(t)] = s1
        subs[f] = s0
    return subs


def _substitute(e, subs):
    """Apply :func:`_time_to_symbols`' map, second derivatives first.

    Second derivatives go first so that Derivative(f, t) inside them is not replaced early.
    """
    for k in sorted(subs, key=lambda d: -getattr(d, "derivative_count", 0)):
        e = e.subs(k, subs[k])
    return e


def _lam(args, expr, module):
    import sympy as sp  # lazily: only simulations need it

    return sp.lambdify(args, expr, modules=module, cse=True)


def _extension(M, b, mass_args, m_entries, bias_args, syms) -> Derivation:
    """A model that extends the planar one (:func:`derive_planar`).

    Its own mass matrix and bias, lambdified, with the planar model's rider-CoG Jacobian and velocity (the
    rider's geometry is the same).
    """
    base = derive_planar()
    return Derivation(
        mass_s=_lam(mass_args, m_entries, "math"), bias_s=_lam(bias_args, list(b), "math"),
        jac_g_s=base.jac_g_s, vel_g_s=base.vel_g_s,
        mass_v=_lam(mass_args, m_entries, "numpy"), bias_v=_lam(bias_args, list(b), "numpy"),
        jac_g_v=base.jac_g_v, vel_g_v=base.vel_g_v, M=M, b=b, syms=syms,
        functions={"mass": (mass_args, m_entries), "bias": (bias_args, list(b))})


@lru_cache(maxsize=1)
def derive_planar() -> Derivation:
    """Lagrange's equations of the planar model from the point kinematics (once per process, about 0.8 s).

    Returns
    -------
    Derivation
        The mass matrix (3, 3), the bias (3,) and the rider CoG's Jacobian and velocity, lambdified.
    """
    import sympy as sp  # lazily: only simulations need it

    t = sp.Symbol("t")
    m, m0, mw, Jw, J0, J, R, l0, h0 = sp.symbols("m m0 mw Jw J0 J R l0 h0", positive=True)
    gx, gz = sp.symbols("g_x g_z")
    xf, gf, pf, hf = (sp.Function(n)(t) for n in ("x", "gamma", "phi", "h"))

    def planar(v0, v1):
        return sp.Matrix([v0, v1])

    C = planar(xf, R)
    A = C + l0 * planar(-sp.sin(gf), -sp.cos(gf))
    G0 = C + h0 * planar(sp.sin(gf), sp.cos(gf))
    G = A + hf * planar(sp.sin(pf), sp.cos(pf))
    g_vec = planar(gx, gz)

    def kin(point, mass):
        v = point.diff(t)
        return sp.Rational(1, 2) * mass * (v.T * v)[0]

    T = (kin(C, mw) + sp.Rational(1, 2) * Jw * (xf.diff(t) / R) ** 2
         + kin(G0, m0) + sp.Rational(1, 2) * J0 * gf.diff(t) ** 2
         + kin(G, m) + sp.Rational(1, 2) * J * pf.diff(t) ** 2)
    V = -(mw * (g_vec.T * C)[0] + m0 * (g_vec.T * G0)[0] + m * (g_vec.T * G)[0])
    L = T - V

    qf = [xf, gf, pf]
    eom = [sp.diff(sp.diff(L, q.diff(t)), t) - sp.diff(L, q) for q in qf]

    # Replace functions of time by plain symbols.
    x, gam, phi, xd, gd, pd, xdd, gdd, pdd = sp.symbols("x gamma phi x_d gamma_d phi_d x_dd gamma_dd phi_dd")
    h, hd, hdd = sp.symbols("h h_d h_dd")
    subs = _time_to_symbols(t, ((xf, x, xd, xdd), (gf, gam, gd, gdd), (pf, phi, pd, pdd), (hf, h, hd, hdd)))

    def plain(e):
        return sp.expand(_substitute(e, subs))

    eom_s = [plain(e) for e in eom]
    qdd = [xdd, gdd, pdd]
    M = sp.Matrix(3, 3, lambda i, j: sp.diff(eom_s[i], qdd[j]))
    b = sp.Matrix([sp.expand(eom_s[i] - sum(M[i, j] * qdd[j] for j in range(3))) for i in range(3)])

    Gp = G.subs(subs)
    Gs = sp.Matrix([plain(Gp[0]), plain(Gp[1])])
    jac_G = Gs.jacobian([x, gam, phi])
    vel_G = sp.Matrix([plain(G.diff(t)[i]) for i in range(2)])

    pars = (m, m0, mw, Jw, J0, J, R, l0, h0)
    mass_args = (gam, phi, h) + pars
    m_entries = [M[0, 0], M[0, 1], M[0, 2], M[1, 1], M[1, 2], M[2, 2]]
    bias_args = (gam, phi, xd, gd, pd, h, hd, hdd, gx, gz) + pars
    jac_args = (gam, phi, h) + pars
    vel_args = (gam, phi, xd, gd, pd, h, hd) + pars

    jac_list = [jac_G[i, j] for i in range(2) for j in range(3)]
    return Derivation(
        mass_s=_lam(mass_args, m_entries, "math"),
        bias_s=_lam(bias_args, list(b), "math"),
        jac_g_s=_lam(jac_args, jac_list, "math"),
        vel_g_s=_lam(vel_args, list(vel_G), "math"),
        mass_v=_lam(mass_args, m_entries, "numpy"),
        bias_v=_lam(bias_args, list(b), "numpy"),
        jac_g_v=_lam(jac_args, jac_list, "numpy"),
        vel_g_v=_lam(vel_args, list(vel_G), "numpy"),
        M=M, b=b,
        syms={"q": (x, gam, phi), "qd": (xd, gd, pd), "qdd": (xdd, gdd, pdd), "h": (h, hd, hdd),
              "g": (gx, gz), "params": pars, "G": Gs},
        functions={"mass": (mass_args, m_entries), "bias": (bias_args, list(b)), "jac_g": (jac_args, jac_list),
                   "vel_g": (vel_args, list(vel_G))},
    )


def symbolic_model() -> tuple["sp.Matrix", "sp.Matrix", dict]:
    """The derived ``(M, b, symbols)`` as sympy objects (for documentation and checks).

    Returns
    -------
    M, b : sympy.Matrix
        Mass matrix (3, 3) and bias vector (3,).
    symbols : dict
        The symbols by role.
    """
    c = derive_planar()
    return c.M, c.b, c.syms


@lru_cache(maxsize=1)
def derive_floor() -> Derivation:
    """Lagrange's equations on a floor of varying slope, gravity along the mocap's vertical (level lab).

    A second geometry, written independently of :func:`derive_planar` and of the estimator: the wheel centre
    moves along a curve of the vertical plane of travel with tangent angle ``a(s)`` (positive uphill)
    at arc length ``s``: ``C_dot = s_dot (cos a, sin a)``; the EUC body and rider angles gamma, phi are
    measured from the vertical (gravity), as a level-calibrated mocap measures them::

        A  = C + l0 (-sin gamma, -cos gamma),  G0 = C + h0 (sin gamma, cos gamma),
        G  = A + h(t) (sin phi, cos phi)

    The wheel spins at ``s_dot / R`` (rolling on the floor; the floor's curvature changes the spin by
    ``R da/ds`` relative, below 1e-3 for any floor a person rides). ``a`` depends on ``s``:
    ``dT/ds = dT/da a1`` with ``a1 = da/ds``, and ``d/dt a = a1 s_dot``. Gravity ``(g_x, g_z)`` is a
    uniform field (nominally ``(0, -g)``): its force on s is ``m_tot (g_x cos a + g_z sin a)``.
    The equations are ``M(q, a) q_ddot + b(q, q_dot, h..., g, a, a1) = Q_nc`` with the same inputs as
    :func:`derive_planar` (``M_d/R`` on s, ``M_h - M_d`` on gamma, ``-M_h`` on phi).

    Returns
    -------
    Derivation
        The mass matrix (3, 3) and bias (3,) with the arguments ``a`` [rad] and ``a1`` [rad/m]; the rider
        CoG's Jacobian and velocity of :func:`derive_planar`.
    """
    import sympy as sp

    t = sp.Symbol("t")
    m, m0, mw, Jw, J0, J, R, l0, h0 = sp.symbols("m m0 mw Jw J0 J R l0 h0", positive=True)
    gx, gz = sp.symbols("g_x g_z")
    sf, gf, pf, hf, af = (sp.Function(n)(t) for n in ("s", "gamma", "phi", "h", "a"))
    vC = sf.diff(t) * sp.Matrix([sp.cos(af), sp.sin(af)])
    rho_A = l0 * sp.Matrix([-sp.sin(gf), -sp.cos(gf)])
    rho_0 = h0 * sp.Matrix([sp.sin(gf), sp.cos(gf)])
    rho_G = rho_A + hf * sp.Matrix([sp.sin(pf), sp.cos(pf)])
    g_vec = sp.Matrix([gx, gz])

    def ke(v, mass):
        return sp.Rational(1, 2) * mass * (v.T * v)[0]

    T = (ke(vC, mw) + sp.Rational(1, 2) * Jw * (sf.diff(t) / R) ** 2
         + ke(vC + rho_0.diff(t), m0) + sp.Rational(1, 2) * J0 * gf.diff(t) ** 2
         + ke(vC + rho_G.diff(t), m) + sp.Rational(1, 2) * J * pf.diff(t) ** 2)
    V_rel = -(m0 * (g_vec.T * rho_0)[0] + m * (g_vec.T * rho_G)[0])
    L = T - V_rel
    a, a1 = sp.symbols("a a1")
    x, gam, phi, xd, gd, pd, xdd, gdd, pdd = sp.symbols("x gamma phi x_d gamma_d phi_d x_dd gamma_dd phi_dd")
    h, hd, hdd = sp.symbols("h h_d h_dd")
    eom = [sp.diff(sp.diff(L, sf.diff(t)), t) - sp.diff(L, af) * a1
           - (m + m0 + mw) * (gx * sp.cos(af) + gz * sp.sin(af))]
    eom += [sp.diff(sp.diff(L, q.diff(t)), t) - sp.diff(L, q) for q in (gf, pf)]
    subs = _time_to_symbols(t, ((sf, x, xd, xdd), (gf, gam, gd, gdd), (pf, phi, pd, pdd), (hf, h, hd, hdd)))

    def plain(e):
        # the slope's rate first: da/dt = (da/ds) s_dot
        return sp.expand(_substitute(e.subs(af.diff(t), a1 * sf.diff(t)), subs).subs(af, a))

    eom_s = [plain(e) for e in eom]
    qdd = [xdd, gdd, pdd]
    M = sp.Matrix(3, 3, lambda i, j: sp.diff(eom_s[i], qdd[j]))
    b = sp.Matrix([sp.expand(eom_s[i] - sum(M[i, j] * qdd[j] for j in range(3))) for i in range(3)])
    pars = (m, m0, mw, Jw, J0, J, R, l0, h0)
    mass_args = (gam, phi, h, a) + pars
    bias_args = (gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a, a1) + pars
    m_entries = [M[0, 0], M[0, 1], M[0, 2], M[1, 1], M[1, 2], M[2, 2]]

    return _extension(M, b, mass_args, m_entries, bias_args,
                      {"q": (x, gam, phi), "qd": (xd, gd, pd), "qdd": (xdd, gdd, pdd), "h": (h, hd, hdd),
                       "g": (gx, gz), "floor": (a, a1), "params": pars})


@lru_cache(maxsize=1)
def derive_pedal() -> Derivation:
    """Lagrange's equations with pedals that flex: a fourth coordinate u along the EUC's axis.

    A third geometry, written independently of :func:`derive_planar`: the pedals (massless) carry the ankle
    hinge, which moves down the EUC's axis by ``u`` (u = 0 unloaded, u > 0 compressed)::

        A = C + (l0 + u) (-sin gamma, -cos gamma),   G = A + h(t) (sin phi, cos phi)

    C and G0 as in :func:`derive_planar`. The pedals' spring and damper are not in the Lagrangian: they enter
    as the generalized force ``Q_u = -k u - c u_dot`` (so the same M, b serve any stiffness). u moves
    only the rider: the u equation reads ``m (a_G - g_vec) . e_ax = k u + c u_dot`` with
    ``e_ax = (sin gamma, cos gamma)``, the rider's load on the pedals along the axis (quasi-static:
    ``k u = m g cos gamma`` at rest). At u = u_dot = 0 the (x, gamma, phi) block of M and b is the
    rigid model's (checked in ``test/unit/core/ridesim/test_rider_motion.py``, with the energy balance).

    Returns
    -------
    Derivation
        The mass matrix (4, 4) and bias (4,) with the arguments ``u`` [m] and ``u_d`` [m/s]; the rider CoG's
        Jacobian and velocity of :func:`derive_planar` (the unflexed geometry).
    """
    import sympy as sp

    t = sp.Symbol("t")
    m, m0, mw, Jw, J0, J, R, l0, h0 = sp.symbols("m m0 mw Jw J0 J R l0 h0", positive=True)
    gx, gz = sp.symbols("g_x g_z")
    xf, gf, pf, uf, hf = (sp.Function(n)(t) for n in ("x", "gamma", "phi", "u", "h"))
    C = sp.Matrix([xf, R])
    ax_dn = sp.Matrix([-sp.sin(gf), -sp.cos(gf)])
    A = C + (l0 + uf) * ax_dn
    G0 = C - h0 * ax_dn
    G = A + hf * sp.Matrix([sp.sin(pf), sp.cos(pf)])
    g_vec = sp.Matrix([gx, gz])

    def ke(point, mass):
        v = point.diff(t)
        return sp.Rational(1, 2) * mass * (v.T * v)[0]

    T = (ke(C, mw) + sp.Rational(1, 2) * Jw * (xf.diff(t) / R) ** 2 + ke(G0, m0)
         + sp.Rational(1, 2) * J0 * gf.diff(t) ** 2 + ke(G, m) + sp.Rational(1, 2) * J * pf.diff(t) ** 2)
    V = -(mw * (g_vec.T * C)[0] + m0 * (g_vec.T * G0)[0] + m * (g_vec.T * G)[0])
    L = T - V
    qf = [xf, gf, pf, uf]
    eom = [sp.diff(sp.diff(L, q.diff(t)), t) - sp.diff(L, q) for q in qf]
    x, gam, phi, u = sp.symbols("x gamma phi u")
    xd, gd, pd, ud = sp.symbols("x_d gamma_d phi_d u_d")
    xdd, gdd, pdd, udd = sp.symbols("x_dd gamma_dd phi_dd u_dd")
    h, hd, hdd = sp.symbols("h h_d h_dd")
    subs = _time_to_symbols(t, ((xf, x, xd, xdd), (gf, gam, gd, gdd), (pf, phi, pd, pdd), (uf, u, ud, udd),
                                (hf, h, hd, hdd)))
    eom_s = [sp.expand(_substitute(e, subs)) for e in eom]
    qdd = [xdd, gdd, pdd, udd]
    M = sp.Matrix(4, 4, lambda i, j: sp.diff(eom_s[i], qdd[j]))
    b = sp.Matrix([sp.expand(eom_s[i] - sum(M[i, j] * qdd[j] for j in range(4))) for i in range(4)])
    pars = (m, m0, mw, Jw, J0, J, R, l0, h0)
    mass_args = (gam, phi, u, h) + pars
    bias_args = (gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz) + pars
    m_entries = [M[i, j] for i in range(4) for j in range(4)]

    return _extension(M, b, mass_args, m_entries, bias_args,
                      {"q": (x, gam, phi, u), "qd": (xd, gd, pd, ud), "qdd": (xdd, gdd, pdd, udd),
                       "h": (h, hd, hdd), "g": (gx, gz), "params": pars})


__all__ = ["Derivation", "derive_floor", "derive_pedal", "derive_planar", "symbolic_model"]
