"""Planar dynamics of an EUC with a rider hinged at the ankle, by Newton-Euler with constraint forces.

Three rigid bodies move in the longitudinal plane: the wheel, the EUC body and the rider. Each body
gets Newton's and Euler's equations; the joint forces at the wheel axle C, at the ankle hinge A and
the ground force at the contact point P are unknowns solved together with the accelerations. This is
a derivation of its own, in maximal form, not the Lagrangian form of the EUC paper: the two agree
(tested), which checks both.

Frame: x forward, z up; every angle is a rotation about +y (REP-103 y points left), so a positive
angle turns the body's up axis towards +x (forward lean).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

#: Gravity [m/s^2]; the value the identification assumes too (a different g biases h by itself).
GRAVITY = 9.81

#: Order of the generalized coordinates and of the unknowns of the Newton-Euler system.
COORDINATES = ("x", "gamma", "phi")
UNKNOWNS = ("x_ddot", "gamma_ddot", "phi_ddot", "F_t", "N", "F_Cx", "F_Cz", "F_Ax", "F_Az")


@dataclass(frozen=True)
class PlantParams:
    """Masses, inertias and lengths of the wheel, the EUC body and the rider (SI units).

    Parameters
    ----------
    R : float
        Wheel radius [m].
    m_w, J_w : float
        Wheel mass [kg] and its inertia about the axle [kg m^2].
    m_0, J_0 : float
        EUC body mass [kg] and its pitch inertia about its own centre of mass G0 [kg m^2].
    h_0 : float
        Distance from the axle C to G0 along the body's up axis [m] (G0 above C when positive).
    l_0 : float
        Distance from the ankle hinge A to C along the body's up axis [m] (A below C when positive).
    m, J : float
        Rider mass [kg] and pitch inertia about the rider's centre of gravity G [kg m^2].
    h : float
        Distance A-G [m].
    g : float
        Gravity [m/s^2].
    """

    R: float = 0.2
    m_w: float = 3.0
    J_w: float = 0.12
    m_0: float = 13.0
    J_0: float = 0.5
    h_0: float = 0.075
    l_0: float = 0.05
    m: float = 65.0
    J: float = 16.6
    h: float = 0.9
    g: float = GRAVITY

    def with_(self, **changes) -> "PlantParams":
        """Return a copy with some fields changed.

        Parameters
        ----------
        **changes : float
            New values by field name (SI units, as the fields).

        Returns
        -------
        PlantParams
            The copy.

        Raises
        ------
        TypeError
            A name is not a field.
        """
        return replace(self, **changes)


def _e(a):
    """Unit vector ``(sin a, cos a)`` of a body's up axis at pitch ``a``, as (x, z) components."""
    return np.sin(a), np.cos(a)


def _n(a):
    """``d e / d a = (cos a, -sin a)``: the direction a point on the up axis moves when the body pitches."""
    return np.cos(a), -np.sin(a)


def points(q, p: PlantParams) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Positions (x, z) of the contact P, axle C, EUC centre G0, hinge A and rider centre G [m].

    Parameters
    ----------
    q : array_like (..., 3)
        Generalized coordinates ``(x, gamma, phi)`` [m, rad, rad].
    p : PlantParams

    Returns
    -------
    dict
        ``{"P", "C", "G0", "A", "G"}`` -> ``(x, z)`` arrays of shape (...).

    Notes
    -----
    ``C = (x, R)``, ``G0 = C + h_0 e(gamma)``, ``A = C - l_0 e(gamma)``, ``G = A + h e(phi)`` with
    ``e(a) = (sin a, cos a)``; the ground is ``z = 0`` and ``P = (x, 0)``.
    """
    q = np.asarray(q, dtype=float)
    x, gam, phi = q[..., 0], q[..., 1], q[..., 2]
    eg, ep = _e(gam), _e(phi)
    C = (x, np.full_like(x, p.R))
    G0 = (C[0] + p.h_0 * eg[0], C[1] + p.h_0 * eg[1])
    A = (C[0] - p.l_0 * eg[0], C[1] - p.l_0 * eg[1])
    G = (A[0] + p.h * ep[0], A[1] + p.h * ep[1])
    return {"P": (x, np.zeros_like(x)), "C": C, "G0": G0, "A": A, "G": G}


def newton_euler_system(q, qd, M_d, M_h, p: PlantParams, Q=None):
    r"""Matrix and right-hand side of the Newton-Euler equations of the three bodies.

    Parameters
    ----------
    q, qd : array_like (..., 3)
        Coordinates ``(x, gamma, phi)`` and their rates.
    M_d : array_like (...)
        Motor torque [N m]: on the wheel about +y, its reaction on the EUC body.
    M_h : array_like (...)
        Ankle torque [N m]: on the EUC body about +y, its reaction on the rider.
    p : PlantParams
    Q : array_like (..., 3), optional
        External generalized force ``(Q_x, Q_gamma, Q_phi)`` [N, N m, N m] (an external force's virtual
        power ``Q . q_dot``, :mod:`euc_ros.core.worldsim.forces`). It is applied as the loads with that
        virtual power: a horizontal force ``Q_x`` on the wheel at its axle C (C moves at ``x_dot``), an
        external couple ``Q_gamma`` on the EUC body and a couple ``Q_phi`` on the rider.

    Returns
    -------
    K : ndarray (..., 9, 9)
    b : ndarray (..., 9)
        ``K u = b`` for the unknowns ``u`` of :data:`UNKNOWNS`.

    Notes
    -----
    Planar kinematics about +y: a point at ``r`` (from a body's reference point) of a body turning
    at rate ``w`` moves at ``w (r_z, -r_x)``; a force ``F`` applied at lever ``r`` has the moment
    ``r_z F_x - r_x F_z`` about +y. With ``e(a) = (sin a, cos a)`` and ``n(a) = e'(a) =
    (cos a, -sin a)``, rolling without slip (``v_P = 0``) fixes the wheel's rate at ``x_dot / R`` and

    .. math::

        a_C &= (\ddot x, 0),\\
        a_{G0} &= a_C + h_0 (\ddot\gamma\, n(\gamma) - \dot\gamma^2 e(\gamma)),\\
        a_A &= a_C - l_0 (\ddot\gamma\, n(\gamma) - \dot\gamma^2 e(\gamma)),\\
        a_G &= a_A + h (\ddot\phi\, n(\phi) - \dot\phi^2 e(\phi)).

    Forces: ground on wheel ``F_P = (F_t, N)`` at ``P = C - (0, R)``; body on wheel ``F_C`` at C
    (``-F_C`` on the body); body on rider ``F_A`` at A (``-F_A`` on the body); gravity on each centre
    of mass. Torques: ``M_d`` on the wheel and ``-M_d`` on the body; ``M_h`` on the body and ``-M_h``
    on the rider. The nine equations are

    .. math::

        m_w a_C &= F_P + F_C + m_w g_v, &\quad J_w \ddot x / R &= -R F_t + M_d,\\
        m_0 a_{G0} &= -F_C - F_A + m_0 g_v, &\quad J_0 \ddot\gamma &= \tau(C - G_0, -F_C)
            + \tau(A - G_0, -F_A) - M_d + M_h,\\
        m a_G &= F_A + m g_v, &\quad J \ddot\phi &= \tau(A - G, F_A) - M_h,

    with ``g_v = (0, -g)`` and ``tau(r, F) = r_z F_x - r_x F_z``. They are linear in the unknowns
    ``(x_ddot, gamma_ddot, phi_ddot, F_t, N, F_C, F_A)``; terms without unknowns (gravity, the
    centripetal ``-w^2 e`` parts, the torques) go to ``b``.
    """
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    shape = np.broadcast_shapes(q.shape[:-1], qd.shape[:-1], np.shape(M_d), np.shape(M_h))
    if Q is not None:
        Q = np.asarray(Q, dtype=float)
        if Q.shape[-1:] != (3,):
            raise ValueError(f"Q must have a last axis of 3 (Q_x, Q_gamma, Q_phi), got shape {Q.shape}")
        shape = np.broadcast_shapes(shape, Q.shape[:-1])
        Q = (Q[..., 0], Q[..., 1], Q[..., 2])
    rows, rhs = _system_rows(np.sin(q[..., 1]), np.cos(q[..., 1]), np.sin(q[..., 2]), np.cos(q[..., 2]),
                             qd[..., 1], qd[..., 2], M_d, M_h, p, Q)
    K = np.empty(shape + (9, 9))
    b = np.empty(shape + (9,))
    for i in range(9):
        b[..., i] = rhs[i]
        for j in range(9):
            K[..., i, j] = rows[i][j]
    return K, b


def _system_rows(sg, cg, sp, cp, gd, pd, M_d, M_h, p: PlantParams, Q=None):
    """Entries of :func:`newton_euler_system` as nested lists (scalars or arrays), written once.

    Unknown order: ``x_ddot, gamma_ddot, phi_ddot, F_t, N, F_Cx, F_Cz, F_Ax, F_Az``. Rows: wheel
    Newton x, z and Euler; body Newton x, z and Euler about G0; rider Newton x, z and Euler about G.
    The lever arms are ``C - G0 = -h_0 e(gamma)``, ``A - G0 = -(h_0 + l_0) e(gamma)``,
    ``A - G = -h e(phi)``, with ``tau(r, -F) = -r_z F_x + r_x F_z``. ``Q = (Q_x, Q_gamma, Q_phi)`` (or
    None) adds the external loads of :func:`newton_euler_system` to the wheel's Newton x row, the body's
    and the rider's Euler rows.
    """
    m_w, m_0, m, g = p.m_w, p.m_0, p.m, p.g
    h0, l0, h = p.h_0, p.l_0, p.h
    hl = h0 + l0
    gd2, pd2 = gd * gd, pd * pd
    rows = [
        # wheel: m_w x_dd - F_t - F_Cx = 0 ; -N - F_Cz = -m_w g ; J_w x_dd / R + R F_t = M_d
        [m_w, 0.0, 0.0, -1.0, 0.0, -1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0, -1.0, 0.0, -1.0, 0.0, 0.0],
        [p.J_w / p.R, 0.0, 0.0, p.R, 0.0, 0.0, 0.0, 0.0, 0.0],
        # EUC body: m_0 (a_C + h_0 (g_dd n - g_d^2 e)) + F_C + F_A = (0, -m_0 g)
        [m_0, m_0 * h0 * cg, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0],
        [0.0, -m_0 * h0 * sg, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0],
        # J_0 g_dd - tau(C - G0, -F_C) - tau(A - G0, -F_A) = M_h - M_d
        [0.0, p.J_0, 0.0, 0.0, 0.0, -h0 * cg, h0 * sg, -hl * cg, hl * sg],
        # rider: m (a_C - l_0 (g_dd n_g - g_d^2 e_g) + h (p_dd n_p - p_d^2 e_p)) - F_A = (0, -m g)
        [m, -m * l0 * cg, m * h * cp, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0],
        [0.0, m * l0 * sg, -m * h * sp, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0],
        # J p_dd - tau(A - G, F_A) = -M_h
        [0.0, 0.0, p.J, 0.0, 0.0, 0.0, 0.0, h * cp, -h * sp],
    ]
    rhs = [0.0, -m_w * g, M_d,
           m_0 * h0 * gd2 * sg, m_0 * h0 * gd2 * cg - m_0 * g,
           M_h - M_d,
           m * (-l0 * gd2 * sg + h * pd2 * sp), m * (-l0 * gd2 * cg + h * pd2 * cp) - m * g,
           -M_h]
    if Q is not None:
        rhs[0] = rhs[0] + Q[0]
        rhs[5] = rhs[5] + Q[1]
        rhs[8] = rhs[8] + Q[2]
    return rows, rhs


def solve_one(q, qd, M_d: float, M_h: float, p: PlantParams, Q=None) -> np.ndarray:
    """:func:`solve` for one state, in scalar arithmetic (the integrator's right-hand side).

    Same entries as :func:`newton_euler_system` (:func:`_system_rows`); building the matrix from
    floats costs a third of the broadcasting path on a single state.

    Parameters
    ----------
    q, qd : sequence of float (3,)
        Coordinates ``(x, gamma, phi)`` [m, rad, rad] and their rates [m/s, rad/s, rad/s].
    M_d, M_h : float
        Motor and ankle torques [N m].
    p : PlantParams
        The plant.
    Q : sequence of float (3,), optional
        External generalized force ``(Q_x, Q_gamma, Q_phi)`` [N, N m, N m]; None for none.

    Returns
    -------
    numpy.ndarray (9,)
        As :func:`solve`: :data:`UNKNOWNS` [m/s^2, rad/s^2, N].
    """
    rows, rhs = _system_rows(math.sin(q[1]), math.cos(q[1]), math.sin(q[2]), math.cos(q[2]),
                             float(qd[1]), float(qd[2]), float(M_d), float(M_h), p, Q)
    return np.linalg.solve(np.array(rows), np.array(rhs))


def solve(q, qd, M_d, M_h, p: PlantParams, Q=None) -> np.ndarray:
    """Accelerations and constraint forces for given states and torques.

    Parameters
    ----------
    q, qd : array_like (..., 3)
    M_d, M_h : array_like (...)
    p : PlantParams
    Q : array_like (..., 3), optional
        External generalized force (:func:`newton_euler_system`).

    Returns
    -------
    ndarray (..., 9)
        ``(x_ddot, gamma_ddot, phi_ddot, F_t, N, F_Cx, F_Cz, F_Ax, F_Az)`` [m/s^2, rad/s^2, N].
        ``F_t`` and ``N`` are the ground's tangential and normal force on the wheel.
    """
    K, b = newton_euler_system(q, qd, M_d, M_h, p, Q)
    return np.linalg.solve(K, b[..., None])[..., 0]


def accelerations(q, qd, M_d, M_h, p: PlantParams, Q=None) -> np.ndarray:
    """Generalized accelerations ``(x_ddot, gamma_ddot, phi_ddot)`` (..., 3); see :func:`solve`.

    Parameters
    ----------
    q, qd : array_like (..., 3)
        Coordinates ``(x, gamma, phi)`` [m, rad, rad] and their rates [m/s, rad/s, rad/s].
    M_d, M_h : array_like (...)
        Motor and ankle torques [N m].
    p : PlantParams
        The plant.
    Q : array_like (..., 3), optional
        External generalized force [N, N m, N m] (:func:`newton_euler_system`).

    Returns
    -------
    numpy.ndarray (..., 3)
        ``(x_ddot, gamma_ddot, phi_ddot)`` [m/s^2, rad/s^2, rad/s^2].
    """
    return solve(q, qd, M_d, M_h, p, Q)[..., :3]


def energy(q, qd, p: PlantParams) -> np.ndarray:
    """Kinetic plus potential energy [J] of the three bodies (ground level z = 0).

    Parameters
    ----------
    q, qd : array_like (..., 3)
        Coordinates ``(x, gamma, phi)`` [m, rad, rad] and their rates [m/s, rad/s, rad/s].
    p : PlantParams
        The plant.

    Returns
    -------
    numpy.ndarray (...)
        ``T + V`` [J].

    Notes
    -----
    ``T = 1/2 (m_w + J_w / R^2) x_dot^2 + 1/2 m_0 |v_G0|^2 + 1/2 J_0 gamma_dot^2
    + 1/2 m |v_G|^2 + 1/2 J phi_dot^2`` with the velocities of :func:`newton_euler_system`, and
    ``V = g (m_w R + m_0 z_G0 + m z_G)``.
    """
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    xd, gd, pd = qd[..., 0], qd[..., 1], qd[..., 2]
    ngx, ngz = _n(q[..., 1])
    npx, npz = _n(q[..., 2])
    v0x, v0z = xd + p.h_0 * gd * ngx, p.h_0 * gd * ngz
    vAx, vAz = xd - p.l_0 * gd * ngx, -p.l_0 * gd * ngz
    vGx, vGz = vAx + p.h * pd * npx, vAz + p.h * pd * npz
    T = (0.5 * (p.m_w + p.J_w / p.R**2) * xd**2 + 0.5 * p.m_0 * (v0x**2 + v0z**2) + 0.5 * p.J_0 * gd**2
         + 0.5 * p.m * (vGx**2 + vGz**2) + 0.5 * p.J * pd**2)
    pts = points(q, p)
    V = p.g * (p.m_w * p.R + p.m_0 * pts["G0"][1] + p.m * pts["G"][1])
    return T + V


def torque_power(qd, M_d, M_h, p: PlantParams) -> np.ndarray:
    """Power [W] of the motor and ankle torques: ``M_d (x_dot / R - gamma_dot) + M_h (gamma_dot - phi_dot)``.

    Parameters
    ----------
    qd : array_like (..., 3)
        Rates ``(x_dot, gamma_dot, phi_dot)`` [m/s, rad/s, rad/s].
    M_d, M_h : array_like (...)
        Motor and ankle torques [N m].
    p : PlantParams
        The plant (its wheel radius).

    Returns
    -------
    numpy.ndarray (...)
        The power [W].

    Notes
    -----
    Each torque acts on two bodies with opposite signs, so its power is the torque times the relative
    rate; the joint forces do no net work (equal and opposite at one point) and the ground force none
    (``v_P = 0``). Hence ``dE/dt`` equals this power (:func:`energy`), plus ``Q . q_dot`` with an external
    generalized force.
    """
    qd = np.asarray(qd, dtype=float)
    return M_d * (qd[..., 0] / p.R - qd[..., 1]) + M_h * (qd[..., 1] - qd[..., 2])
