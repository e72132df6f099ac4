"""Closed-form equations of motion of the rolling wheel and of the autonomous unicycle.

Model (steering paper, Sections II-III, Figs 2 and 4): a thin disc of mass ``m`` and radius ``R``
rolls without slipping on the horizontal plane; the unicycle adds a point mass ``m0`` that slides
along the axle at ``r`` (eq (32)), pushed by the internal control force ``u`` (eq (33), +u on the
mass along the axle ``y2``, -u on the wheel).

Frames (eq (73)): ground F0 (REP-103: x forward, y left, z up); F1 = yaw ``psi`` about z0; F2 = tilt
``theta`` about x1, so y2 is the axle. Positive ``theta`` leans the top of the wheel towards -y1
(to the right when rolling along +x); a positive pitch rate rolls the wheel forward along x1.

State, eq (37) (unicycle, 10 states) and eq (7) (wheel, 8 states)::

    unicycle: [omega1, omega2, omega3, theta, sigma, r, psi, phi, x_G, y_G]
    wheel:    [omega1, omega2, omega3, theta, psi, phi, x_G, y_G]

with the pseudo velocities of eq (35): ``omega1 = theta_dot``, ``omega2 = psi_dot sin(theta) +
phi_dot``, ``omega3 = psi_dot cos(theta)`` (angular velocity of the wheel resolved in F2, rad/s) and
``sigma = r_dot`` (m/s).

The right-hand sides are written by hand (eq (6) and eq (36) with the corrections listed in the
paper's errata: the ``sigma_dot`` line and the ``y_G`` line). They are *not* trusted as
transcribed: ``test/unit/core/unicycle/test_derivation.py`` checks them against two independent
symbolic derivations (:mod:`euc_ros.core.unicycle.derivation`: Kane's method and Lagrange's
equations with multipliers) and against the power balance ``dE/dt = u sigma``.

Every function is vectorized: a state has shape ``(n_states, ...)`` and the trailing axes
broadcast with ``u``. Only ``+ - * /``, ``sin``, ``cos`` and ``tan`` are used, so complex-step
differentiation works (see :mod:`euc_ros.core.unicycle.linearize`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError

__all__ = [
    "STATE_NAMES", "WHEEL_STATE_NAMES", "ESSENTIAL_STATES", "WHEEL_ESSENTIAL_STATES", "STATE_UNITS",
    "UnicycleParams", "unicycle_rhs", "drift", "input_field", "updfcn", "wheel_rhs",
    "energy", "wheel_energy", "mass_height", "state_index",
]

#: State of the unicycle, eq (37).
STATE_NAMES: tuple[str, ...] = ("omega1", "omega2", "omega3", "theta", "sigma", "r", "psi", "phi", "x_G", "y_G")
#: SI unit of each state of :data:`STATE_NAMES`.
STATE_UNITS: tuple[str, ...] = ("rad/s", "rad/s", "rad/s", "rad", "m/s", "m", "rad", "rad", "m", "m")
#: State of the rolling wheel, eq (7).
WHEEL_STATE_NAMES: tuple[str, ...] = ("omega1", "omega2", "omega3", "theta", "psi", "phi", "x_G", "y_G")
#: Number of essential states (the rest, psi, phi, x_G, y_G, is the hidden dynamics).
ESSENTIAL_STATES = 6
WHEEL_ESSENTIAL_STATES = 4


def state_index(name: str) -> int:
    """The index of a unicycle state by name (``'theta'`` -> 3).

    Parameters
    ----------
    name : str
        A name of :data:`STATE_NAMES`.

    Returns
    -------
    int
        Its index.
    """
    return STATE_NAMES.index(name)


@dataclass(frozen=True)
class UnicycleParams:
    """Physical parameters of the wheel and the unicycle (Table I of the steering paper).

    Parameters
    ----------
    m : float
        Wheel mass [kg] (thin disc, ``J = m R^2 / 4 diag(1, 2, 1)`` about its centre, eq (81)).
    m0 : float
        Point mass moving along the axle [kg]; 0 gives the bare rolling wheel.
    R : float
        Wheel radius [m].
    g : float
        Gravitational acceleration [m/s^2].

    Raises
    ------
    ConfigError
        When ``m``, ``R`` or ``g`` is not positive and finite, or ``m0`` is negative or not finite.
    """

    m: float = 10.0
    m0: float = 5.0
    R: float = 0.3
    g: float = 9.81

    def __post_init__(self) -> None:
        for key in ("m", "R", "g"):
            value = getattr(self, key)
            if not (np.isfinite(value) and value > 0):
                raise ConfigError(f"must be a positive finite number, got {value!r}", key=key)
        if not (np.isfinite(self.m0) and self.m0 >= 0):
            raise ConfigError(f"must be a non-negative finite number, got {self.m0!r}", key="m0")

    def require_point_mass(self) -> None:
        """Raise :class:`ConfigError` if ``m0`` is zero (the unicycle model needs it, eq (36)).

        Raises
        ------
        ConfigError
            When ``m0`` is 0 (key ``m0``).
        """
        if not self.m0 > 0:
            raise ConfigError("the unicycle model needs a positive point mass m0 (m0 = 0 is the bare wheel, "
                              "use the wheel model)", key="m0")


def _unicycle_rates(w1, w2, w3, th, sg, r, u, p: UnicycleParams, sin, cos, tan):
    """Pseudo accelerations ``(omega1_dot, omega2_dot, omega3_dot, sigma_dot)`` of eq (36).

    ``sin``/``cos``/``tan`` are passed in so the same formula serves numpy arrays (vectorized,
    complex step) and plain floats (``math``, fast fixed-step simulation).
    """
    m, m0, R, g = p.m, p.m0, p.R, p.g
    s, c, t = sin(th), cos(th), tan(th)
    D1 = 5 * m * R**2 + 4 * m0 * r**2
    D2 = 3 * m * R**2 + 2 * m0 * R**2 + 12 * m0 * r**2
    dw1 = (4 * m0 * R * r * w1**2 - (m * R**2 + 4 * m0 * r**2) * w3**2 * t - 8 * m0 * r * w1 * sg
           + 2 * R * w2 * w3 * (3 * m * R + 2 * m0 * r * t) - 4 * m0 * g * r * c + 4 * m * g * R * s
           + 4 * R * u) / D1
    dw2 = 2 * (-2 * m0 * R * r * w1 * w2 - (m * R**2 + m0 * R**2 + 4 * m0 * r**2) * w1 * w3
               + 2 * m0 * R * w3 * sg) / D2
    dw3 = (-2 * (3 * m + 2 * m0) * R**2 * w1 * w2
           + w1 * w3 * (3 * m * R**2 * t + 2 * m0 * (R**2 * t + 2 * R * r + 6 * r**2 * t))
           - 24 * m0 * r * w3 * sg) / D2
    # sigma_dot: eq (36) with the errata (prefactor 1, omega3^2, Coriolis term m0 R)
    dsg = (w1**2 * r * (5 * m * R**2 + 4 * m0 * (R**2 + r**2))
           + w3**2 * (5 * m * R**2 * r + 4 * m0 * r**3 - (m * R**3 + 4 * m0 * R * r**2) * t)
           + w2 * w3 * R * (m * R**2 + 4 * m0 * (R * r * t - r**2))
           - 8 * m0 * R * r * w1 * sg
           - (m * R**2 + 4 * m0 * r**2) * g * s - 4 * m0 * g * R * r * c
           + (5 * m / m0 * R**2 + 4 * R**2 + 4 * r**2) * u) / D1
    return dw1, dw2, dw3, dsg


def _hidden_rates(w1, w2, w3, th, psi, p: UnicycleParams, sin, cos, tan):
    """Hidden dynamics (eq (79)): ``(psi_dot, phi_dot, x_G_dot, y_G_dot)``."""
    R = p.R
    c = cos(th)
    sp, cp = sin(psi), cos(psi)
    return (w3 / c, w2 - w3 * tan(th), R * (w1 * sp * c + w2 * cp), R * (-w1 * cp * c + w2 * sp))


def unicycle_rhs(x, u, params: UnicycleParams) -> np.ndarray:
    """Right-hand side ``x_dot = f(x) + g(x) u`` of the unicycle, eq (36).

    Parameters
    ----------
    x : array_like, shape (10, ...)
        State of eq (37) (:data:`STATE_NAMES`), SI units.
    u : float or array_like
        Control force on the point mass along the axle [N] (eq (33)); broadcasts with ``x[0]``.
    params : UnicycleParams
        Physical parameters; ``m0`` must be positive.

    Returns
    -------
    numpy.ndarray, shape (10, ...)
        Time derivative of the state.

    Notes
    -----
    Eq (36) with the errata's ``sigma_dot`` and ``y_G`` lines; verified against Kane's method and
    Lagrange's equations (see module docstring). Singular at ``|theta| = 90 deg`` (eq (78)).
    """
    x = np.asarray(x)
    w1, w2, w3, th, sg, r, psi = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
    rates = _unicycle_rates(w1, w2, w3, th, sg, r, np.asarray(u), params, np.sin, np.cos, np.tan)
    hidden = _hidden_rates(w1, w2, w3, th, psi, params, np.sin, np.cos, np.tan)
    dw1, dw2, dw3, dsg = rates
    out = (dw1, dw2, dw3, w1, dsg, sg) + hidden
    shape = np.broadcast_shapes(*(np.shape(v) for v in out))
    return np.stack([np.broadcast_to(v, shape) for v in out])


def drift(x, params: UnicycleParams) -> np.ndarray:
    """Drift vector field ``f(x)`` of eq (36) (the right-hand side with ``u = 0``), shape (10, ...).

    Parameters
    ----------
    x : array_like
        States (10, ...) (:data:`STATE_NAMES`).
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    numpy.ndarray
        ``f(x)`` (10, ...).
    """
    return unicycle_rhs(x, 0.0, params)


def input_field(x, params: UnicycleParams) -> np.ndarray:
    """Input vector field ``g(x)`` of eq (36), shape (10, ...), unit (state unit)/s per N.

    Only ``omega1_dot`` (``4 R / D1``) and ``sigma_dot`` (``(5 m R^2 / m0 + 4 R^2 + 4 r^2) / D1``)
    depend on ``u``, with ``D1 = 5 m R^2 + 4 m0 r^2``.

    Parameters
    ----------
    x : array_like
        States (10, ...) (:data:`STATE_NAMES`).
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    numpy.ndarray
        ``g(x)`` (10, ...).
    """
    x = np.asarray(x)
    p = params
    r = x[5]
    D1 = 5 * p.m * p.R**2 + 4 * p.m0 * r**2
    out = np.zeros(np.shape(x), dtype=np.result_type(x, float))
    out[0] = 4 * p.R / D1
    out[4] = (5 * p.m / p.m0 * p.R**2 + 4 * p.R**2 + 4 * r**2) / D1
    return out


def updfcn(t, x, u, params: UnicycleParams) -> np.ndarray:
    """python-control style update function ``updfcn(t, x, u, params) -> x_dot`` (time-invariant).

    Parameters
    ----------
    t : float
        Time [s] (unused: the model is autonomous).
    x : array_like, shape (10,)
        State (:data:`STATE_NAMES`).
    u : float or array_like, shape (1,)
        Control force [N].
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    numpy.ndarray
        ``x_dot`` (10,).

    Raises
    ------
    ValueError
        When ``u`` is neither a scalar nor of shape (1,).
    """
    u = np.asarray(u, dtype=float).reshape(-1)
    if u.size != 1:
        raise ValueError(f"u must be a scalar or shape (1,), got shape {u.shape}")
    return unicycle_rhs(np.asarray(x, dtype=float), u[0], params)


def wheel_rhs(x, params: UnicycleParams) -> np.ndarray:
    """Right-hand side of the rolling wheel, eq (6) (errata: the fifth line is ``psi_dot``).

    Parameters
    ----------
    x : array_like, shape (8, ...)
        State of eq (7) (:data:`WHEEL_STATE_NAMES`).
    params : UnicycleParams
        Only ``R`` and ``g`` enter (the wheel's mass cancels).

    Returns
    -------
    numpy.ndarray, shape (8, ...)
    """
    x = np.asarray(x)
    w1, w2, w3, th, psi = x[0], x[1], x[2], x[3], x[4]
    R, g = params.R, params.g
    dw1 = 6 / 5 * w2 * w3 - 1 / 5 * w3**2 * np.tan(th) + 4 * g / (5 * R) * np.sin(th)
    dw2 = -2 / 3 * w1 * w3
    dw3 = -2 * w1 * w2 + w1 * w3 * np.tan(th)
    hidden = _hidden_rates(w1, w2, w3, th, psi, params, np.sin, np.cos, np.tan)
    out = (dw1, dw2, dw3, w1) + hidden
    shape = np.broadcast_shapes(*(np.shape(v) for v in out))
    return np.stack([np.broadcast_to(v, shape) for v in out])


def mass_height(x, params: UnicycleParams):
    """Height of the point mass above the ground, ``z_A = R cos(theta) + r sin(theta)`` [m], eq (47).

    Parameters
    ----------
    x : array_like
        States (10, ...) (:data:`STATE_NAMES`).
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    float or numpy.ndarray
        ``z_A`` [m].
    """
    x = np.asarray(x)
    return params.R * np.cos(x[3]) + x[5] * np.sin(x[3])


def energy(x, params: UnicycleParams):
    """Total mechanical energy of the unicycle [J] (kinetic + gravitational, ground at z = 0).

    Uses the rolling kinematics resolved in F2: ``v_G = [R omega2, -R omega1, 0]`` and
    ``v_A = v_G + [-r omega3, sigma, r omega1]``. Along solutions ``dE/dt = u sigma`` (the power of
    the internal force pair), which the tests use as an independent check of eq (36).

    Parameters
    ----------
    x : array_like
        States (10, ...) (:data:`STATE_NAMES`).
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    float or numpy.ndarray
        The energy [J].
    """
    x = np.asarray(x)
    p = params
    w1, w2, w3, th, sg, r = x[0], x[1], x[2], x[3], x[4], x[5]
    vG2 = p.R**2 * (w1**2 + w2**2)
    vA2 = (p.R * w2 - r * w3) ** 2 + (sg - p.R * w1) ** 2 + (r * w1) ** 2
    rot = p.m * p.R**2 / 8 * (w1**2 + 2 * w2**2 + w3**2)
    kinetic = 0.5 * p.m * vG2 + rot + 0.5 * p.m0 * vA2
    potential = p.m * p.g * p.R * np.cos(th) + p.m0 * p.g * (p.R * np.cos(th) + r * np.sin(th))
    return kinetic + potential


def wheel_energy(x, params: UnicycleParams):
    """Total mechanical energy of the rolling wheel [J] (conserved by eq (6)).

    Parameters
    ----------
    x : array_like
        Wheel states (8, ...) (:data:`WHEEL_STATE_NAMES`).
    params : UnicycleParams
        Physical parameters.

    Returns
    -------
    float or numpy.ndarray
        The energy [J].
    """
    x = np.asarray(x)
    p = params
    w1, w2, w3, th = x[0], x[1], x[2], x[3]
    return (0.5 * p.m * p.R**2 * (w1**2 + w2**2) + p.m * p.R**2 / 8 * (w1**2 + 2 * w2**2 + w3**2)
            + p.m * p.g * p.R * np.cos(th))


def scalar_rhs(x: list[float], u: float, p: UnicycleParams) -> list[float]:
    """Unicycle right-hand side on plain floats (``math``), used by the fixed-step simulator.

    Same formula as :func:`unicycle_rhs` (shared :func:`_unicycle_rates`), about 20x faster than
    numpy on scalars.

    Parameters
    ----------
    x : list of float
        State (10) (:data:`STATE_NAMES`).
    u : float
        Control force [N].
    p : UnicycleParams
        Physical parameters.

    Returns
    -------
    list of float
        ``x_dot`` (10).
    """
    w1, w2, w3, th, sg, r, psi = x[0], x[1], x[2], x[3], x[4], x[5], x[6]
    dw1, dw2, dw3, dsg = _unicycle_rates(w1, w2, w3, th, sg, r, u, p, math.sin, math.cos, math.tan)
    hp, hf, hx, hy = _hidden_rates(w1, w2, w3, th, psi, p, math.sin, math.cos, math.tan)
    return [dw1, dw2, dw3, w1, dsg, sg, hp, hf, hx, hy]
