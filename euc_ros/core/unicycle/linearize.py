"""Linearisation of the wheel and unicycle models (steering paper, eqs (18), (25), (50), (55), (60)).

Jacobians are computed numerically by complex-step differentiation of the closed-form right-hand
side (exact to rounding, no step-size trade-off); the analytic matrices of the paper for straight
rolling are provided separately (with the errata applied) so the two can be tested against each
other.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.unicycle.dynamics import STATE_NAMES, UnicycleParams, unicycle_rhs, wheel_rhs

__all__ = [
    "REDUCED_STATES", "complex_step_jacobian", "linearize", "wheel_jacobian", "straight_rolling_state",
    "wheel_straight_rolling_state", "linearize_straight_rolling", "straight_rolling_matrices",
    "wheel_straight_rolling_matrix", "reduced_matrices", "reduce_linear_system",
]

#: States of the reduced straight-rolling model (60), in order.
REDUCED_STATES: tuple[str, ...] = ("omega1", "theta", "sigma", "r", "psi", "y_G")

_H = 1e-30  # complex step


def complex_step_jacobian(fun: Callable, x, h: float = _H) -> np.ndarray:
    """Jacobian of a vectorized vector field by complex-step differentiation.

    Parameters
    ----------
    fun : callable
        ``fun(x) -> x_dot`` with ``x`` of shape (n, ...) (trailing axes broadcast); must accept
        complex input.
    x : array_like, shape (n,) or (n, N)
        Point(s) of linearisation.
    h : float
        Imaginary step; the derivative is ``Im f(x + i h e_j) / h`` (no subtraction, so no
        cancellation error).

    Returns
    -------
    numpy.ndarray, shape (n, n) or (N, n, n)
        ``J[..., i, j] = d f_i / d x_j``.
    """
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    eye = np.eye(n).reshape((n, n) + (1,) * (x.ndim - 1))
    X = x[:, None, ...] + 1j * h * eye                       # (n, n_pert, ...)
    J = np.imag(fun(X)) / h                                 # (n_out, n_pert, ...)
    return J if x.ndim == 1 else np.moveaxis(J, (0, 1), (-2, -1))


def linearize(params: UnicycleParams, x, u: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """State and input matrices ``A = df/dx``, ``B = d(f + g u)/du`` of eq (36) at ``(x, u)``.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters (``m0 > 0``).
    x : array_like, shape (10,) or (10, N)
        State(s) of eq (37).
    u : float
        Control force [N].

    Returns
    -------
    A : numpy.ndarray, shape (10, 10) or (N, 10, 10)
    B : numpy.ndarray, shape (10,) or (N, 10)
    """
    params.require_point_mass()
    A = complex_step_jacobian(lambda X: unicycle_rhs(X, u, params), x)
    x = np.asarray(x, dtype=float)
    B = np.imag(unicycle_rhs(x, u + 1j * _H, params)) / _H
    return A, (B if x.ndim == 1 else B.T)


def wheel_jacobian(params: UnicycleParams, x) -> np.ndarray:
    """State matrix of the rolling wheel, eq (6), at ``x`` (8,) or (8, N): eq (18) numerically.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    x : array_like
        Wheel state(s) (8,) or (8, N) (:data:`~euc_ros.core.unicycle.dynamics.WHEEL_STATE_NAMES`).

    Returns
    -------
    numpy.ndarray
        The Jacobian (8, 8), or (N, 8, 8) for N states.
    """
    return complex_step_jacobian(lambda X: wheel_rhs(X, params), x)


def _check_speed(speed) -> float:
    speed = float(speed)
    if not np.isfinite(speed):
        raise ConfigError(f"must be finite, got {speed!r}", key="speed")
    return speed


def straight_rolling_state(params: UnicycleParams, speed: float, t: float = 0.0) -> np.ndarray:
    """Straight rolling along +x0 at wheel-centre speed ``v = R phi_dot*`` (eq (24)), unicycle state.

    ``omega2 = phi = v/R`` (times ``t`` for ``phi``), ``x_G = v t``, every other state zero.

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    speed : float
        Wheel-centre speed [m/s].
    t : float
        Time [s].

    Returns
    -------
    numpy.ndarray
        The state (10,).
    """
    v = _check_speed(speed)
    x = np.zeros(len(STATE_NAMES))
    x[1] = v / params.R
    x[7] = v / params.R * t
    x[8] = v * t
    return x


def wheel_straight_rolling_state(params: UnicycleParams, speed: float, t: float = 0.0) -> np.ndarray:
    """Straight rolling of the bare wheel (eq (24)), wheel state of eq (7).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    speed : float
        Wheel-centre speed [m/s].
    t : float
        Time [s].

    Returns
    -------
    numpy.ndarray
        The wheel state (8,).
    """
    x = straight_rolling_state(params, speed, t)
    return np.delete(x, [4, 5])


def linearize_straight_rolling(params: UnicycleParams, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Numerical ``(A, B)`` of the unicycle about straight rolling at ``speed`` [m/s] (t = 0).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    speed : float
        Wheel-centre speed [m/s].

    Returns
    -------
    A : numpy.ndarray
        State matrix (10, 10).
    B : numpy.ndarray
        Input matrix (10,) [per N].
    """
    return linearize(params, straight_rolling_state(params, speed))


def straight_rolling_matrices(params: UnicycleParams, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Analytic ``A`` (eq (50)) and ``B`` (eq (55)) about straight rolling, with the errata.

    Errata applied: ``A[4, 3] = -g/5`` (text: ``-R/5``); ``A[8, 1] = R``; ``A[9, 0] = -R``;
    ``A[9, 6] = R phi_dot*``; ``B[4] = (5 m + 4 m0) / (5 m m0)`` (text drops an ``m``).
    Indices are 0-based in the state order of eq (37).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters (``m0 > 0``).
    speed : float
        Wheel-centre speed ``v = R phi_dot*`` [m/s].

    Returns
    -------
    A : numpy.ndarray
        State matrix (10, 10).
    B : numpy.ndarray
        Input matrix (10,) [per N].
    """
    params.require_point_mass()
    m, m0, R, g = params.m, params.m0, params.R, params.g
    p = _check_speed(speed) / R
    A = np.zeros((10, 10))
    A[0, 2], A[0, 3], A[0, 5] = 6 / 5 * p, 4 * g / (5 * R), -4 * m0 * g / (5 * m * R**2)
    A[2, 0] = -2 * p
    A[3, 0] = 1.0
    A[4, 2], A[4, 3], A[4, 5] = R / 5 * p, -g / 5, -4 * m0 * g / (5 * m * R)
    A[5, 4] = 1.0
    A[6, 2] = 1.0
    A[7, 1] = 1.0
    A[8, 1] = R
    A[9, 0], A[9, 6] = -R, R * p
    B = np.zeros(10)
    B[0] = 4 / (5 * m * R)
    B[4] = (5 * m + 4 * m0) / (5 * m * m0)
    return A, B


def wheel_straight_rolling_matrix(params: UnicycleParams, speed: float) -> np.ndarray:
    """Analytic state matrix of the bare wheel about straight rolling, eq (25).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters.
    speed : float
        Wheel-centre speed [m/s].

    Returns
    -------
    numpy.ndarray
        State matrix (8, 8).
    """
    R, g = params.R, params.g
    p = _check_speed(speed) / R
    A = np.zeros((8, 8))
    A[0, 2], A[0, 3] = 6 / 5 * p, 4 * g / (5 * R)
    A[2, 0] = -2 * p
    A[3, 0] = 1.0
    A[4, 2] = 1.0
    A[5, 1] = 1.0
    A[6, 1] = R
    A[7, 0], A[7, 4] = -R, R * p
    return A


def reduced_matrices(params: UnicycleParams, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Analytic reduced straight-rolling model, eq (60), on :data:`REDUCED_STATES`.

    The reduction drops the unreachable ``omega2, phi, x_G`` and eliminates ``omega3`` with the
    linear invariant ``omega3 = -2 phi_dot* theta`` (eq (59)).

    Parameters
    ----------
    params : UnicycleParams
        Physical parameters (``m0 > 0``).
    speed : float
        Wheel-centre speed [m/s].

    Returns
    -------
    A_r : numpy.ndarray, shape (6, 6)
    B_r : numpy.ndarray, shape (6,)
    """
    params.require_point_mass()
    m, m0, R, g = params.m, params.m0, params.R, params.g
    p = _check_speed(speed) / R
    A = np.zeros((6, 6))
    B = np.zeros(6)
    A[0, 1], A[0, 3], B[0] = 4 * g / (5 * R) - 12 / 5 * p**2, -4 * m0 * g / (5 * m * R**2), 4 / (5 * m * R)
    A[1, 0] = 1.0
    A[2, 1], A[2, 3], B[2] = -(g / 5 + 2 * R / 5 * p**2), -4 * m0 * g / (5 * m * R), (5 * m + 4 * m0) / (5 * m * m0)
    A[3, 2] = 1.0
    A[4, 1] = -2 * p
    A[5, 0], A[5, 4] = -R, R * p
    return A, B


def reduce_linear_system(A, B, pitch_rate: float) -> tuple[np.ndarray, np.ndarray]:
    """Reduce a full straight-rolling linearisation (10 states) to the 6 states of eq (60).

    Restricts ``x_dot = A x + B u`` to the invariant subspace ``omega2 = phi = x_G = 0``,
    ``omega3 = -2 phi_dot* theta`` (eq (59)): ``A_r = P A S``, ``B_r = P B`` with ``S`` the
    embedding of the reduced state and ``P`` the selection of :data:`REDUCED_STATES`.

    Parameters
    ----------
    A : array_like
        State matrix (10, 10).
    B : array_like
        Input matrix (10,).
    pitch_rate : float
        Steady pitch rate ``phi_dot*`` [rad/s].

    Returns
    -------
    A_r : numpy.ndarray
        Reduced state matrix (6, 6).
    B_r : numpy.ndarray
        Reduced input matrix (6,).
    """
    A = np.asarray(A, float)
    B = np.asarray(B, float)
    sel = [STATE_NAMES.index(n) for n in REDUCED_STATES]
    S = np.zeros((10, 6))
    for j, i in enumerate(sel):
        S[i, j] = 1.0
    S[STATE_NAMES.index("omega3"), REDUCED_STATES.index("theta")] = -2.0 * pitch_rate
    return A[sel] @ S, B[sel]
