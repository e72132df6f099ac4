"""Independent symbolic derivations of the wheel and unicycle equations of motion.

Two routes, both from first principles (geometry, masses, inertia, forces), neither using a
transcribed equation of the paper:

* :func:`derive_kane` - Kane's method (``sympy.physics.mechanics.KanesMethod``) with the paper's
  pseudo velocities (eq (35)) as independent generalized speeds. The rolling constraint (eq (1),
  the contact point P has zero velocity) is built into the velocity of the wheel centre,
  ``v_G = omega x r_PG``, so the nonholonomic constraint forces do no work on the partial
  velocities (this is Kane's form of Appell's equations (83), used by the paper).
* :func:`derive_lagrange` - Lagrange's equations of the first kind (Routh-Voss) in the six
  generalized coordinates ``(x_G, y_G, psi, theta, phi, r)`` with two Lagrange multipliers for the
  nonholonomic constraints (eq (2)), all vectors built from plain rotation matrices (no
  ``physics.mechanics``). The constraints themselves are derived (``v_G = omega x R z2``), not
  copied.

Both return a :class:`DerivedModel` with vectorized, lambdified ``f`` and ``g`` of the control-affine
form ``x_dot = f(x) + g(x) u`` in the state of eq (37) (unicycle) or eq (7) (wheel). They are
slow to build (about 0.5 s and 3 s) and cached; they are used by the tests to check the closed
form in :mod:`euc_ros.core.unicycle.dynamics`, never by the simulator.
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from euc_ros.core.unicycle.dynamics import STATE_NAMES, WHEEL_STATE_NAMES, UnicycleParams

__all__ = ["DerivedModel", "derive_kane", "derive_lagrange"]


@dataclass(frozen=True)
class DerivedModel:
    """Lambdified equations of motion from a symbolic derivation.

    Parameters
    ----------
    method : str
        ``'kane'`` or ``'lagrange'``.
    state_names : tuple of str
        :data:`~euc_ros.core.unicycle.dynamics.STATE_NAMES` (unicycle) or
        :data:`~euc_ros.core.unicycle.dynamics.WHEEL_STATE_NAMES` (wheel).
    symbolic : dict
        The symbolic objects (mass matrix, forcing, ...) for inspection.
    """

    method: str
    state_names: tuple[str, ...]
    symbolic: dict
    _rhs: Callable

    def rhs(self, x, u, params: UnicycleParams) -> np.ndarray:
        """``x_dot`` (n, N) for states ``x`` (n, N) or (n,), input ``u`` [N].

        Parameters
        ----------
        x : array_like
            States (n, N) or (n,) in the order of ``state_names``.
        u : float or array_like
            Control force [N].
        params : UnicycleParams
            Physical parameters.

        Returns
        -------
        numpy.ndarray
            ``x_dot``, the shape of ``x``.
        """
        x = np.asarray(x, dtype=float)
        squeeze = x.ndim == 1
        X = x.reshape(x.shape[0], -1)
        U = np.broadcast_to(np.asarray(u, dtype=float), X.shape[1:])
        out = self._rhs(X, U, params)
        return out[:, 0] if squeeze else out

    def f(self, x, params: UnicycleParams) -> np.ndarray:
        """Drift ``f(x)`` (right-hand side at ``u = 0``).

        Parameters
        ----------
        x : array_like
            States (n, N) or (n,).
        params : UnicycleParams
            Physical parameters.

        Returns
        -------
        numpy.ndarray
            ``f(x)``, the shape of ``x``.
        """
        return self.rhs(x, 0.0, params)

    def g(self, x, params: UnicycleParams) -> np.ndarray:
        """Input field ``g(x) = rhs(x, 1) - rhs(x, 0)`` (exact: the forcing is affine in ``u``).

        Parameters
        ----------
        x : array_like
            States (n, N) or (n,).
        params : UnicycleParams
            Physical parameters.

        Returns
        -------
        numpy.ndarray
            ``g(x)`` per N of input, the shape of ``x``.
        """
        return self.rhs(x, 1.0, params) - self.rhs(x, 0.0, params)


def _as_array(nested, shape) -> np.ndarray:
    """Turn a lambdified nested list (scalars mixed with arrays) into an array (rows, cols, *shape)."""
    return np.array([[np.broadcast_to(np.asarray(e, dtype=float), shape) for e in row] for row in nested])


@functools.lru_cache(maxsize=2)
def derive_kane(with_mass: bool = True) -> DerivedModel:
    """Derive the equations of motion with Kane's method.

    Parameters
    ----------
    with_mass : bool
        True: the unicycle (wheel + point mass on the axle, 10 states, eq (37)); False: the bare
        rolling wheel (8 states, eq (7)).

    Returns
    -------
    DerivedModel

    Notes
    -----
    Generalized coordinates ``(psi, theta, phi[, r])``; generalized speeds: the wheel's angular
    velocity resolved in F2 ``(omega1, omega2, omega3)`` and ``sigma = r_dot`` (eq (35)). The
    wheel is a thin disc with central inertia ``m R^2/4 diag(1, 2, 1)`` (eq (81)); loads: gravity
    on G and A, the control force ``+u y2`` on the mass and ``-u y2`` on the wheel (eq (33)). The
    hidden rates ``psi_dot, phi_dot`` come from the kinematic differential equations and
    ``x_G_dot, y_G_dot`` from ``v_G = omega x r_PG`` resolved in F0.
    """
    import sympy as sm
    import sympy.physics.mechanics as me

    psi, theta, phi, r = me.dynamicsymbols("psi theta phi r")
    w1, w2, w3, sig = me.dynamicsymbols("omega1 omega2 omega3 sigma")
    m, m0, R, g, u = sm.symbols("m m0 R g u")

    N = me.ReferenceFrame("N")                       # F0, z up
    F1 = N.orientnew("F1", "Axis", [psi, N.z])       # yaw
    F2 = F1.orientnew("F2", "Axis", [theta, F1.x])   # tilt: y2 is the axle
    W = F2.orientnew("W", "Axis", [phi, F2.y])       # the spinning wheel
    W.set_ang_vel(N, w1 * F2.x + w2 * F2.y + w3 * F2.z)

    P = me.Point("P")                                # contact point (material point at rest)
    P.set_vel(N, 0)
    G = P.locatenew("G", R * F2.z)
    G.v2pt_theory(P, N, W)                           # rolling without slipping, eq (1)
    wheel = me.RigidBody("wheel", G, W, m, (me.inertia(W, m * R**2 / 4, m * R**2 / 2, m * R**2 / 4), G))

    kd = [w1 - theta.diff(), w2 - (psi.diff() * sm.sin(theta) + phi.diff()), w3 - psi.diff() * sm.cos(theta)]
    q_ind, u_ind = [psi, theta, phi], [w1, w2, w3]
    bodies = [wheel]
    if with_mass:
        A = G.locatenew("A", r * F2.y)
        A.set_vel(N, G.vel(N) + (r * F2.y).dt(N))
        bodies.append(me.Particle("mass", A, m0))
        loads = [(G, -m * g * N.z - u * F2.y), (A, -m0 * g * N.z + u * F2.y)]
        kd.append(sig - r.diff())
        q_ind.append(r)
        u_ind.append(sig)
    else:
        loads = [(G, -m * g * N.z)]

    km = me.KanesMethod(N, q_ind=q_ind, u_ind=u_ind, kd_eqs=kd)
    km.kanes_equations(bodies, loads)
    mass_matrix, forcing = km.mass_matrix, km.forcing
    qdot = km.kindiffdict()
    vG = G.vel(N).to_matrix(N)
    hidden = [qdot[psi.diff()], qdot[phi.diff()], vG[0], vG[1]]

    names = STATE_NAMES if with_mass else WHEEL_STATE_NAMES
    dyn = {"omega1": w1, "omega2": w2, "omega3": w3, "theta": theta, "sigma": sig, "r": r, "psi": psi,
           "phi": phi}
    plain = {v: sm.Symbol(k) for k, v in dyn.items()}
    state_syms = [plain[dyn[n]] if n in dyn else sm.Symbol(n) for n in names]
    args = state_syms + [m, m0, R, g, u]
    f_mass = sm.lambdify(args, me.msubs(mass_matrix, plain).tolist(), "numpy", cse=True)
    f_forcing = sm.lambdify(args, me.msubs(forcing, plain).tolist(), "numpy", cse=True)
    f_hidden = sm.lambdify(args, [me.msubs(h, plain) for h in hidden], "numpy", cse=True)

    def rhs(X, U, p: UnicycleParams):
        n = X.shape[1]
        a = list(X) + [p.m, p.m0, p.R, p.g, U]
        M = np.moveaxis(_as_array(f_mass(*a), (n,)), -1, 0)              # (n, k, k)
        F = np.moveaxis(_as_array(f_forcing(*a), (n,)), -1, 0)           # (n, k, 1)
        udot = np.linalg.solve(M, F)[..., 0].T                            # (k, n)
        hid = np.array([np.broadcast_to(np.asarray(h, float), (n,)) for h in f_hidden(*a)])
        out = np.empty_like(X)
        out[0:3] = udot[0:3]
        out[3] = X[0]                                                     # theta_dot = omega1
        if with_mass:
            out[4] = udot[3]
            out[5] = X[4]                                                 # r_dot = sigma
        out[-4:] = hid
        return out

    return DerivedModel("kane", names, {"mass_matrix": mass_matrix, "forcing": forcing, "hidden": hidden}, rhs)


def _rot(axis: str, a):
    import sympy as sm

    c, s = sm.cos(a), sm.sin(a)
    return {"x": sm.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "y": sm.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "z": sm.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


@functools.lru_cache(maxsize=2)
def derive_lagrange(with_mass: bool = True) -> DerivedModel:
    """Derive the equations of motion with Lagrange's equations and multipliers (Routh-Voss).

    Parameters
    ----------
    with_mass : bool
        True: the unicycle (10 states); False: the bare wheel (8 states).

    Returns
    -------
    DerivedModel

    Notes
    -----
    Coordinates ``q = (x_G, y_G, psi, theta, phi[, r])`` with ``z_G = R cos(theta)`` (eq (3)) built
    in. Orientation ``R_0W = Rz(psi) Rx(theta) Ry(phi)``; body angular velocity from
    ``R_0W^T dR_0W/dt``. ``T = m v_G^2/2 + omega_W . J omega_W / 2 + m0 v_A^2/2``,
    ``V = m g z_G + m0 g z_A``; the control force pair does virtual work ``u delta r``.
    Nonholonomic constraints ``a(q) q_dot = 0`` from the zero velocity of the contact point;
    at each state the linear system ``[[M, -a^T], [a, 0]] [q_ddot; lambda] =
    [Q + dT/dq - dV/dq - (d^2T/dq_dot dq) q_dot; -a_dot q_dot]`` is solved, and the pseudo
    accelerations are the time derivatives of the angular velocity resolved in F2.
    """
    import sympy as sm

    t = sm.Symbol("t")
    m, m0, R, g, u = sm.symbols("m m0 R g u")
    names = ["x_G", "y_G", "psi", "theta", "phi"] + (["r"] if with_mass else [])
    nq = len(names)
    qf = [sm.Function(n)(t) for n in names]
    x, y, psi, th, ph = qf[:5]
    r = qf[5] if with_mass else sm.Integer(0)

    R02 = _rot("z", psi) * _rot("x", th)
    R0W = R02 * _rot("y", ph)
    Om = R0W.T * R0W.diff(t)                                  # skew: body angular velocity
    w_body = sm.simplify(sm.Matrix([Om[2, 1], Om[0, 2], Om[1, 0]]))
    w_F2 = sm.simplify(_rot("y", ph) * w_body)                # resolved in F2 (pseudo velocities)
    w_world = sm.simplify(R0W * w_body)

    rG = sm.Matrix([x, y, R * sm.cos(th)])
    vG = rG.diff(t)
    J = sm.diag(m * R**2 / 4, m * R**2 / 2, m * R**2 / 4)
    T = (m * vG.dot(vG) + (w_body.T * J * w_body)[0]) / 2
    V = m * g * rG[2]
    if with_mass:
        rA = rG + r * R02[:, 1]
        vA = rA.diff(t)
        T += m0 * vA.dot(vA) / 2
        V += m0 * g * rA[2]
    # contact point P = G - R z2 has zero velocity: v_G - omega x (R z2) = 0 (x, y rows)
    cons = (vG - w_world.cross(R * R02[:, 2]))[:2, :]

    qs = sm.Matrix(sm.symbols(" ".join(names)))
    qd = sm.Matrix(sm.symbols(" ".join(n + "_d" for n in names)))
    qdd = sm.Matrix(sm.symbols(" ".join(n + "_dd" for n in names)))
    sub = {qf[i].diff(t, 2): qdd[i] for i in range(nq)}
    sub.update({qf[i].diff(t): qd[i] for i in range(nq)})
    sub.update({qf[i]: qs[i] for i in range(nq)})

    Ts, Vs = T.subs(sub), V.subs(sub)
    M = sm.hessian(Ts, qd)
    dT_dqd = sm.Matrix([Ts.diff(v) for v in qd])
    Q = sm.zeros(nq, 1)
    if with_mass:
        Q[5] = u
    rhs_q = sm.Matrix([Ts.diff(v) - Vs.diff(v) for v in qs]) - dT_dqd.jacobian(qs) * qd + Q
    Acon = cons.subs(sub).jacobian(qd)
    Adot_qd = sm.Matrix([(Acon[i, :].jacobian(qs) * qd).dot(qd) for i in range(2)])
    wF2_s = w_F2.subs(sub)
    wdot_s = w_F2.diff(t).subs(sub)

    # q_dot from the pseudo velocities: solve [omega_F2 = omega; constraints; r_dot = sigma]
    om = sm.symbols("omega1 omega2 omega3")
    sg = sm.Symbol("sigma")
    eqs = list(wF2_s - sm.Matrix(om)) + list(cons.subs(sub))
    if with_mass:
        eqs.append(qd[5] - sg)
    sol = sm.solve(eqs, list(qd), dict=True)[0]
    qd_expr = [sm.simplify(sol[v]) for v in qd]

    base = list(qs) + [m, m0, R, g, u]
    f_qd = sm.lambdify(list(qs) + list(om) + [sg, m, m0, R, g, u], qd_expr, "numpy", cse=True)
    f_M = sm.lambdify(base + list(qd), M.tolist(), "numpy", cse=True)
    f_rhs = sm.lambdify(base + list(qd), list(rhs_q), "numpy", cse=True)
    f_A = sm.lambdify(base + list(qd), Acon.tolist(), "numpy", cse=True)
    f_Ad = sm.lambdify(base + list(qd), list(Adot_qd), "numpy", cse=True)
    f_wdot = sm.lambdify(base + list(qd) + list(qdd), list(wdot_s), "numpy", cse=True)

    state_names = STATE_NAMES if with_mass else WHEEL_STATE_NAMES
    rhs = _lagrange_rhs(names, state_names, with_mass, (f_qd, f_M, f_rhs, f_A, f_Ad, f_wdot))
    return DerivedModel("lagrange", state_names,
                        {"mass_matrix": M, "forcing": rhs_q, "constraints": Acon, "qdot": qd_expr}, rhs)


def _lagrange_rhs(names: list, state_names: tuple, with_mass: bool, fns: tuple) -> Callable:
    """The numeric right-hand side of :func:`derive_lagrange` from its lambdified functions.

    ``fns``: ``(f_qd, f_M, f_rhs, f_A, f_Ad, f_wdot)``, the coordinate rates from the pseudo velocities, the
    mass matrix, the forcing, the constraint matrix, its time derivative times ``q_dot``, and the pseudo
    accelerations; each takes the coordinates ``names``, the parameters (and the rates, accelerations).
    """
    f_qd, f_M, f_rhs, f_A, f_Ad, f_wdot = fns
    nq = len(names)
    idx = {n: i for i, n in enumerate(state_names)}

    def rhs(X, U, p: UnicycleParams):
        n = X.shape[1]
        qv = [X[idx[k]] for k in names]
        pv = [p.m, p.m0, p.R, p.g, U]
        sig_v = X[idx["sigma"]] if with_mass else np.zeros(n)
        qdv = [np.broadcast_to(np.asarray(e, float), (n,))
               for e in f_qd(*qv, X[0], X[1], X[2], sig_v, *pv)]
        a = qv + pv + qdv
        Mn = np.moveaxis(_as_array(f_M(*a), (n,)), -1, 0)                     # (n, nq, nq)
        rn = np.array([np.broadcast_to(np.asarray(e, float), (n,)) for e in f_rhs(*a)]).T
        An = np.moveaxis(_as_array(f_A(*a), (n,)), -1, 0)                     # (n, 2, nq)
        adn = np.array([np.broadcast_to(np.asarray(e, float), (n,)) for e in f_Ad(*a)]).T
        K = np.zeros((n, nq + 2, nq + 2))
        K[:, :nq, :nq] = Mn
        K[:, :nq, nq:] = -np.swapaxes(An, 1, 2)
        K[:, nq:, :nq] = An
        b = np.concatenate([rn, -adn], axis=1)[..., None]
        qddv = np.linalg.solve(K, b)[:, :nq, 0].T                              # (nq, n)
        wdot = [np.broadcast_to(np.asarray(e, float), (n,)) for e in f_wdot(*a, *qddv)]
        qd_of = dict(zip(names, qdv))
        out = np.empty_like(X)
        out[0:3] = wdot
        out[3] = qd_of["theta"]
        if with_mass:
            out[4] = qddv[5]
            out[5] = qd_of["r"]
        out[-4:] = [qd_of["psi"], qd_of["phi"], qd_of["x_G"], qd_of["y_G"]]
        return out

    return rhs
