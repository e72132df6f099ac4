"""Driving torque of the EUC from measured motion: M_d1 (eq (9)) and M_d2 (eq (10)), and eq (13).

Write the equations of motion (5) as ``M q_ddot + h - Q_g - Q_extra = M_d b_d + M_h b_h`` with
``b_d = [1/R, -1, 0]`` and ``b_h = [0, 1, -1]`` (see :mod:`euc_ros.core.model.terms`) and split the
accelerations as ``M q_ddot = M[:, 0] x_ddot + s`` where
``s = M[:, 1] gamma_ddot + M[:, 2] phi_ddot + h - Q_g - Q_extra``.

* Eq (9), first row only (``b_h`` has no first component)::

      M_d1 = R (m11 x_ddot + s1)

* Eq (10), all rows with ``x_ddot`` eliminated. The weights ``w = [R, 1, 1]`` annihilate ``b_d`` and
  ``b_h``, so ``w . (M[:, 0] x_ddot + s) = 0`` fixes the acceleration the model predicts,
  ``x_ddot* = -(w . s) / D`` with ``D = w . M[:, 0] = R m_eq - (m l0 - m0 h0) cos gamma + m h cos phi``,
  and the first row then gives::

      M_d2 = R (m11 x_ddot* + s1)

Hence the residual the identification minimises is

    M_d1 - M_d2 = R m11 (x_ddot - x_ddot*) = R m11 (w . (M q_ddot + h - Q_g - Q_extra)) / D,

which does not depend on M_d and M_h, and is unchanged by any extra generalized force in
``span(b_d, b_h)``.

The reduced model (Section 3.2: ``J0 = h0 = l0 = 0``) gives eq (13), implemented separately in
:func:`torques_2dof`; the tests check it against :func:`torques` with reduced parameters and both
against an independent sympy derivation from (A.1)-(A.2).

Units: torques [N m], angles [rad], rates [rad/s], accelerations [m/s^2, rad/s^2].
"""
from __future__ import annotations

import math

import numpy as np

from euc_ros.core.model.terms import EucParams, bias_terms, gravity_forces, mass_matrix


def _rows(gamma, phi, gamma_dot, phi_dot, gamma_ddot, phi_ddot, p: EucParams, extra_Q):
    """Return ``(M (...,3,3), s (...,3), R, D)`` shared by eqs (9)-(10) (see the module docstring)."""
    gamma = np.asarray(gamma, dtype=float)
    phi = np.asarray(phi, dtype=float)
    zero = np.zeros(np.broadcast_shapes(gamma.shape, phi.shape))
    q = np.stack(np.broadcast_arrays(zero, gamma + zero, phi + zero), -1)
    qd = np.stack(np.broadcast_arrays(zero, np.asarray(gamma_dot, float) + zero, np.asarray(phi_dot, float) + zero), -1)
    M = mass_matrix(q, p)
    s = (M[..., :, 1] * np.asarray(gamma_ddot, float)[..., None] + M[..., :, 2] * np.asarray(phi_ddot, float)[..., None]
         + bias_terms(q, qd, p) - gravity_forces(q, p))
    if extra_Q is not None:
        s = s - np.asarray(extra_Q, dtype=float)
    R = np.asarray(p.R, dtype=float)
    D = R * M[..., 0, 0] + M[..., 1, 0] + M[..., 2, 0]
    return M, s, R, D


def torques(gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot, p: EucParams, extra_Q=None):
    """Driving torque from the first row (eq (9)) and from all rows (eq (10)) of the 3-DoF model.

    Parameters
    ----------
    gamma, phi : array_like
        EUC body pitch and rider pitch about the ankle hinge [rad].
    gamma_dot, phi_dot : array_like
        Pitch rates [rad/s].
    x_ddot : array_like
        Longitudinal acceleration of the wheel centre [m/s^2].
    gamma_ddot, phi_ddot : array_like
        Pitch accelerations [rad/s^2].
    p : EucParams
        Model parameters; fields may be arrays broadcasting against the states.
    extra_Q : array_like (..., 3), optional
        Additional generalized force [N, N m, N m] on the right-hand side of (5) (a physical effect
        the paper's model lacks): ``M q_ddot + h = Q_g + extra_Q + M_d b_d + M_h b_h``.

    Returns
    -------
    M_d1, M_d2 : ndarray
        [N m]. ``M_d1`` uses the measured ``x_ddot``; ``M_d2`` does not depend on it.
    """
    M, s, R, D = _rows(gamma, phi, gamma_dot, phi_dot, gamma_ddot, phi_ddot, p, extra_Q)
    m11 = M[..., 0, 0]
    w_s = R * s[..., 0] + s[..., 1] + s[..., 2]
    x_ddot_model = -w_s / D
    M_d1 = R * (m11 * np.asarray(x_ddot, dtype=float) + s[..., 0])
    M_d2 = R * (m11 * x_ddot_model + s[..., 0])
    return M_d1, M_d2


def torques_one(gamma: float, phi: float, gamma_dot: float, phi_dot: float, x_ddot: float, gamma_ddot: float,
                phi_ddot: float, p: EucParams, extra_Q=None) -> tuple[float, float]:
    """:func:`torques` of one sample with scalar parameters, in scalar arithmetic (the live path).

    The rows of eqs (6)-(8) written out: equal to :func:`torques` to rounding (``test_torque.py``),
    ~20x cheaper on one sample, where numpy's per-call cost is all there is.

    Parameters
    ----------
    gamma, phi : float
        EUC body pitch and rider pitch about the ankle hinge [rad].
    gamma_dot, phi_dot : float
        Pitch rates [rad/s].
    x_ddot : float
        Longitudinal acceleration of the wheel centre [m/s^2].
    gamma_ddot, phi_ddot : float
        Pitch accelerations [rad/s^2].
    p : EucParams
        Model parameters (scalars).
    extra_Q : array_like (3,), optional
        Additional generalized force [N, N m, N m] on the right-hand side of (5).

    Returns
    -------
    M_d1, M_d2 : float
        Driving torques [N m] from the first row and from all rows.
    """
    sin, cos = math.sin, math.cos
    R, m, h, l0, m0, h0, g = float(p.R), float(p.m), float(p.h), float(p.l0), float(p.m0), float(p.h0), float(p.g)
    mh = m * h
    k = m * l0 - m0 * h0
    sg, sp, spg = sin(gamma), sin(phi), sin(phi - gamma)
    m11 = float(p.m_eq)
    m12 = -k * cos(gamma)
    m13 = mh * cos(phi)
    m22 = float(p.J0) + m0 * h0 ** 2 + m * l0 ** 2
    m23 = -mh * l0 * cos(phi - gamma)
    m33 = float(p.J) + mh * h
    gd2, pd2 = gamma_dot * gamma_dot, phi_dot * phi_dot
    e0 = e1 = e2 = 0.0
    if extra_Q is not None:
        e0, e1, e2 = (float(v) for v in np.asarray(extra_Q, dtype=float).reshape(3))
    s0 = m12 * gamma_ddot + m13 * phi_ddot + (-mh * pd2 * sp + k * gd2 * sg) - e0
    s1 = m22 * gamma_ddot + m23 * phi_ddot + mh * l0 * pd2 * spg - (-k * g * sg) - e1
    s2 = m23 * gamma_ddot + m33 * phi_ddot - mh * l0 * gd2 * spg - mh * g * sp - e2
    D = R * m11 + m12 + m13
    x_ddot_model = -(R * s0 + s1 + s2) / D
    return R * (m11 * x_ddot + s0), R * (m11 * x_ddot_model + s0)


def torque_difference(gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot, p: EucParams, extra_Q=None):
    """``M_d1 - M_d2`` [N m] without forming the two torques (the residual analysis' inner loop).

    ``M_d1 - M_d2 = R m11 (w . (M q_ddot + h - Q_g - Q_extra)) / D`` with ``w = [R, 1, 1]`` (module
    docstring), written out row by row on flat arrays: equal to ``torques(...)[0] - torques(...)[1]`` to
    rounding (``test_torque.py``), at a fraction of the cost.

    Parameters
    ----------
    gamma, phi : array_like
        EUC body pitch and rider pitch about the ankle hinge [rad].
    gamma_dot, phi_dot : array_like
        Pitch rates [rad/s].
    x_ddot : array_like
        Longitudinal acceleration of the wheel centre [m/s^2].
    gamma_ddot, phi_ddot : array_like
        Pitch accelerations [rad/s^2].
    p : EucParams
        Model parameters; fields may be arrays broadcasting against the states.
    extra_Q : array_like (..., 3), optional
        Additional generalized force [N, N m, N m] on the right-hand side of (5).

    Returns
    -------
    numpy.ndarray
        ``M_d1 - M_d2`` [N m], broadcast shape of the states.
    """
    g, ph = np.asarray(gamma, dtype=float), np.asarray(phi, dtype=float)
    gd, pd = np.asarray(gamma_dot, dtype=float), np.asarray(phi_dot, dtype=float)
    xdd = np.asarray(x_ddot, dtype=float)
    gdd, pdd = np.asarray(gamma_ddot, dtype=float), np.asarray(phi_ddot, dtype=float)
    fast = _compiled_difference(g, ph, gd, pd, xdd, gdd, pdd, p, extra_Q)
    if fast is not None:
        return fast
    R, mh, k, m11, m22, m33 = _difference_constants(p)
    cg, sg = np.cos(g), np.sin(g)
    cp, sp = np.cos(ph), np.sin(ph)
    cpg, spg = np.cos(ph - g), np.sin(ph - g)
    m12 = -k * cg
    m13 = mh * cp
    m23 = -mh * p.l0 * cpg
    D = R * m11 + m12 + m13
    w_s = (gdd * (R * m12 + m22 + m23) + pdd * (R * m13 + m23 + m33)
           + R * (-mh * pd ** 2 * sp + k * gd ** 2 * sg) + mh * p.l0 * (pd ** 2 - gd ** 2) * spg
           + k * p.g * sg - mh * p.g * sp)
    if extra_Q is not None:
        e = np.asarray(extra_Q, dtype=float)
        w_s = w_s - (R * e[..., 0] + e[..., 1] + e[..., 2])
    return R * m11 * (xdd * D + w_s) / D


def _difference_constants(p: EucParams) -> tuple:
    """``(R, m h, k = m l0 - m0 h0, m11, m22, m33)`` of :func:`torque_difference` (scalars or per-sample arrays).

    Formed once for its numpy and its compiled path alike (the same roundings).
    """
    mh = p.m * p.h
    return (np.asarray(p.R, dtype=float), mh, p.m * p.l0 - p.m0 * p.h0, p.m_eq,
            p.J0 + p.m0 * p.h0 ** 2 + p.m * p.l0 ** 2, p.J + mh * p.h)


#: Fewest samples for the compiled loop (below, numpy's few calls cost less than the call into it).
_COMPILED_MIN = 64


def _compiled_difference(g, ph, gd, pd, xdd, gdd, pdd, p: EucParams, extra_Q):
    """:func:`torque_difference` by the compiled loop (:mod:`~euc_ros.core.model.torque_compiled`), or None.

    For flat arrays of one length and parameters that are scalars or per-sample arrays of that length (an
    effect that moves h or g sample by sample); None otherwise (numpy's broadcasting then does it).
    """
    args = (g, ph, gd, pd, xdd, gdd, pdd)
    n = g.shape[0] if g.ndim == 1 else -1
    if n < _COMPILED_MIN or any(a.shape != (n,) for a in args):
        return None
    values = (p.R, p.m, p.h, p.l0, p.m0, p.h0, p.J0, p.J, p.g, p.m_eq)
    scalar = all(isinstance(v, float) for v in values)          # floats and numpy float64: shape ()
    if not scalar:
        shapes = [v.shape if isinstance(v, np.ndarray) else np.shape(v) for v in values]
        if not all(sh in ((), (n,)) for sh in shapes):
            return None
        scalar = all(sh == () for sh in shapes)
    extra = _NO_EXTRA
    if extra_Q is not None:
        extra = np.asarray(extra_Q, dtype=float)
        if extra.shape != (n, 3):
            return None
    from euc_ros.core.model.torque_compiled import torque_difference_loop  # numba: on first use only

    # the constants formed as the numpy expression forms them (the same roundings, sample by sample when a
    # parameter is per sample): one column, or one per sample
    R, mh, k, m11, m22, m33 = _difference_constants(p)
    consts = (R, R * m11, -k, mh, m22, -mh * p.l0, m33, -mh, mh * p.l0, k * p.g, mh * p.g, k)
    if scalar:
        S = np.array(consts, dtype=float).reshape(len(consts), 1)
    else:
        S = np.empty((len(consts), n))
        for i, c in enumerate(consts):
            S[i] = c
    return torque_difference_loop(*(np.ascontiguousarray(a) for a in args), S, np.ascontiguousarray(extra), np.empty(n))


#: No extra generalized force: the compiled loop's empty (0, 3) input.
_NO_EXTRA = np.zeros((0, 3))


def rider_torque(gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot, p: EucParams, extra_Q=None):
    """Rider's control torque M_h [N m] from the third row of (5), given the motion.

    ``M_h = -(m31 x_ddot + m32 gamma_ddot + m33 phi_ddot + h3 - Q_g3 - Q_extra3)``.

    Parameters
    ----------
    gamma, phi : array_like
        EUC body pitch and rider pitch about the ankle hinge [rad].
    gamma_dot, phi_dot : array_like
        Pitch rates [rad/s].
    x_ddot : array_like
        Longitudinal acceleration of the wheel centre [m/s^2].
    gamma_ddot, phi_ddot : array_like
        Pitch accelerations [rad/s^2].
    p : EucParams
        Model parameters; fields may be arrays broadcasting against the states.
    extra_Q : array_like (..., 3), optional
        Additional generalized force [N, N m, N m] on the right-hand side of (5).

    Returns
    -------
    numpy.ndarray
        ``M_h`` [N m], broadcast shape of the states.
    """
    M, s, _, _ = _rows(gamma, phi, gamma_dot, phi_dot, gamma_ddot, phi_ddot, p, extra_Q)
    return -(M[..., 2, 0] * np.asarray(x_ddot, dtype=float) + s[..., 2])


def torques_2dof(phi, phi_dot, x_ddot, phi_ddot, p: EucParams):
    """Driving torque of the reduced 2-DoF model, eq (13) (``J0 = h0 = l0 = 0``, so ``M_d = M_h``).

    Parameters
    ----------
    phi, phi_dot, phi_ddot : array_like
        Rider pitch [rad], its rate [rad/s] and acceleration [rad/s^2].
    x_ddot : array_like
        Longitudinal acceleration of the wheel centre [m/s^2].
    p : EucParams
        Only ``m, J, m0, mw, Jw, R, g, h`` are used.

    Returns
    -------
    M_d1, M_d2 : ndarray
        [N m], eq (13).
    """
    phi = np.asarray(phi, dtype=float)
    pd2 = np.asarray(phi_dot, dtype=float) ** 2
    pdd = np.asarray(phi_ddot, dtype=float)
    m, h, R, J, g = p.m, p.h, p.R, p.J, p.g
    m_eq = p.m_eq
    s, c = np.sin(phi), np.cos(phi)
    M_d1 = -m * h * R * s * pd2 + m_eq * R * np.asarray(x_ddot, dtype=float) + m * h * R * c * pdd
    den = m * h * c + m_eq * R
    M_d2 = (m_eq * m * g * h * R * s - m**2 * h**2 * R * s * c * pd2
            + (m**2 * h**2 * R * c**2 - m_eq * R * (J + m * h**2)) * pdd) / den
    return M_d1, M_d2
