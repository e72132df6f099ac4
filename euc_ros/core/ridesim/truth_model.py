"""Truth dynamics of the ride simulator: the planar EUC + rider, derived with sympy.

This module deliberately shares no code with the model and states packages (the estimator). Instead of
transcribing the EUC paper's eqs (5)-(8), :mod:`.eom_derivation` writes down the *point kinematics* of Fig. 5
(with the geometry of ``papers/ERRATA.md``) and lets sympy form Lagrange's equations of the second kind
(eq. 4); the models here evaluate them (printed into :mod:`.eom_generated`, or lambdified in the process). The
tests then compare the result with eqs (5)-(8) written out by hand.

Geometry (longitudinal plane, axes (x forward, z up), SI units)::

    C  = (x, R)                              wheel centre (R: true rolling radius)
    A  = C + l0 (-sin gamma, -cos gamma)     ankle hinge, below C
    G0 = C + h0 ( sin gamma,  cos gamma)     EUC body CoG
    G  = A + h(t) (sin phi, cos phi)         rider CoG, h(t) may vary in time (rheonomic)

Kinetic energy: wheel (mass m_w at C, spin x_dot/R, inertia J_w), EUC body (m_0 at G0, J_0,
pitch rate gamma_dot), rider (m at G, J about G, pitch rate phi_dot). Gravity is a uniform field
``g_vec = (g_x, g_z)`` in the plane (nominally ``(0, -g)``; ground slope and tilt-gravity change it), so
its generalized force is ``Q_i = sum_k m_k g_vec . dr_k/dq_i``.

The equations of motion are assembled as::

    M(q, h) q_ddot + b(q, q_dot, h, h_dot, h_ddot, g_vec) = Q_nc

where ``b`` holds the velocity terms, the rheonomic h(t) terms and minus the gravity forces, and
``Q_nc`` the non-conservative generalized forces (inputs M_d, M_h and the effects' dQ).
"""
from __future__ import annotations

import math
import types
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from typing import Callable

import numpy as np

from euc_ros.core.ridesim.eom_derivation import derive_floor, derive_pedal, derive_planar, symbolic_model
from euc_ros.core.session import Session

#: Standard gravity [m/s^2].
G_M_PER_S2 = 9.81

#: Names of the generalized coordinates, in order (EUC paper, eq. 4).
COORDINATES = ("x", "gamma", "phi")

#: Sources of the numeric model functions: ``generated`` (the derivation printed once into
#: :mod:`.eom_generated`, no sympy at run time) or ``sympy`` (derived and lambdified in this process).
EQUATIONS = ("generated", "sympy")


@dataclass(frozen=True)
class PlanarParams:
    """Physical parameters of the planar model (EUC paper, Table 3), SI units.

    Parameters
    ----------
    m : float
        Rider mass [kg].
    m0 : float
        EUC body mass [kg].
    mw : float
        Wheel mass [kg].
    Jw : float
        Wheel spin inertia [kg m^2].
    J0 : float
        EUC body pitch inertia about G0 [kg m^2].
    J : float
        Rider pitch inertia about G [kg m^2].
    R : float
        Rolling radius of the wheel [m].
    l0 : float
        Distance C-A [m].
    h0 : float
        Distance C-G0 [m].
    g : float
        Gravitational acceleration [m/s^2].
    """

    m: float = 65.0
    m0: float = 13.0
    mw: float = 3.0
    Jw: float = 0.12
    J0: float = 0.5
    J: float = 16.6
    R: float = 0.2
    l0: float = 0.05
    h0: float = 0.075
    g: float = G_M_PER_S2

    @classmethod
    def from_session(cls, session: Session) -> "PlanarParams":
        """The parameters a session file states (nominal values).

        Parameters
        ----------
        session : Session
            The session.

        Returns
        -------
        PlanarParams
            Its parameters.
        """
        e, r = session.euc, session.rider
        return cls(m=r.mass, m0=e.body_mass, mw=e.wheel_mass, Jw=e.wheel_inertia, J0=e.body_inertia,
                   J=r.inertia_pitch, R=e.wheel_radius, l0=e.l0, h0=e.h0)

    def as_tuple(self) -> tuple[float, ...]:
        """The values in the order of :data:`_PARAM_ORDER` (the lambdified functions' order).

        Returns
        -------
        tuple of float
            The values, ``g`` excluded.
        """
        return tuple(float(getattr(self, n)) for n in _PARAM_ORDER)

    def with_changes(self, **changes: float) -> "PlanarParams":
        """A copy with some parameters replaced.

        Parameters
        ----------
        **changes : float
            New values by parameter name.

        Returns
        -------
        PlanarParams
            The copy.
        """
        return replace(self, **changes)

    @property
    def total_mass(self) -> float:
        """Total mass m + m0 + mw [kg]."""
        return self.m + self.m0 + self.mw


_PARAM_ORDER = tuple(f.name for f in fields(PlanarParams) if f.name != "g")


@dataclass(frozen=True)
class _Numeric:
    """Numeric functions of one truth geometry: scalar (``_s``) and vectorized (``_v``) versions."""

    mass_s: Callable
    bias_s: Callable
    jac_g_s: Callable
    vel_g_s: Callable
    mass_v: Callable
    bias_v: Callable
    jac_g_v: Callable
    vel_g_v: Callable


def solve3(a00, a01, a02, a11, a12, a22, r0, r1, r2):
    """Solve a symmetric 3x3 system by Cramer's rule (scalars or broadcasting arrays).

    Parameters
    ----------
    a00, a01, a02, a11, a12, a22 : float or numpy.ndarray
        Upper triangle of the matrix.
    r0, r1, r2 : float or numpy.ndarray
        Right-hand side.

    Returns
    -------
    tuple
        The solution ``(x0, x1, x2)``.
    """
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    return ((c00 * r0 + c01 * r1 + c02 * r2) / det,
            (c01 * r0 + c11 * r1 + c12 * r2) / det,
            (c02 * r0 + c12 * r1 + c22 * r2) / det)


def _on_floats(f: Callable) -> Callable:
    """The generated function ``f`` with :mod:`math` in place of numpy (same code, faster on floats)."""
    if not all(hasattr(math, n) for n in f.__code__.co_names if n != "numpy"):
        return f
    return types.FunctionType(f.__code__, {"numpy": math, "__builtins__": __builtins__}, f.__name__)


@lru_cache(maxsize=None)
def _numeric(model: str, equations: str) -> _Numeric:
    """The numeric functions of ``model`` (``planar``, ``floor``, ``pedal``) from the source ``equations``."""
    if equations == "sympy":
        c = {"planar": derive_planar, "floor": derive_floor, "pedal": derive_pedal}[model]()
        return _Numeric(c.mass_s, c.bias_s, c.jac_g_s, c.vel_g_s, c.mass_v, c.bias_v, c.jac_g_v, c.vel_g_v)
    if equations != "generated":
        raise ValueError(f"equations must be one of {EQUATIONS}, got {equations!r}")
    from euc_ros.core.ridesim import eom_generated as g

    mass, bias = getattr(g, f"{model}_mass"), getattr(g, f"{model}_bias")
    return _Numeric(_on_floats(mass), _on_floats(bias), _on_floats(g.planar_jac_g), _on_floats(g.planar_vel_g),
                    mass, bias, g.planar_jac_g, g.planar_vel_g)


class PlanarModel:
    """The planar 3-DoF truth model with numeric parameters.

    Parameters
    ----------
    params : PlanarParams
        True physical parameters (not the session's nominal ones when an effect changes them).
    equations : {"generated", "sympy"}
        Source of the numeric functions (:data:`EQUATIONS`): the same expressions either way.

    Notes
    -----
    Equivalent to the EUC paper's eqs (5)-(8) (checked in the tests against the hand-written
    equations) extended by a general in-plane gravity vector and a time-varying rider CoG height
    h(t) (rheonomic terms, see ``docs/ridesim.md``).
    """

    def __init__(self, params: PlanarParams, equations: str = "generated") -> None:
        self.params = params
        self._p = params.as_tuple()
        self._c = _numeric("planar", equations)

    # --- scalar (ODE right-hand side) -------------------------------------------------------------
    def accel_scalar(self, gam: float, phi: float, xd: float, gd: float, pd: float, h: float, hd: float,
                     hdd: float, gx: float, gz: float, Q0: float, Q1: float, Q2: float, dJ: float = 0.0):
        """``(x_ddot, gamma_ddot, phi_ddot)`` for scalar states and generalized forces Q_nc.

        ``dJ`` [kg m^2] adds to the rider's pitch inertia (a rider whose segments move: :mod:`.rider_motion`).

        Parameters
        ----------
        gam, phi, xd, gd, pd : float
            gamma, phi [rad], x_dot [m/s], gamma_dot, phi_dot [rad/s].
        h, hd, hdd : float
            Rider CoG height [m] and its rates [m/s, m/s^2].
        gx, gz : float
            In-plane gravity [m/s^2].
        Q0, Q1, Q2 : float
            Generalized forces Q_nc [N, N m, N m].
        dJ : float
            Added rider pitch inertia [kg m^2].

        Returns
        -------
        tuple of float
            The accelerations [m/s^2, rad/s^2, rad/s^2].
        """
        p = self._p
        a = self._c.mass_s(gam, phi, h, *p)
        b = self._c.bias_s(gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, *p)
        return solve3(a[0], a[1], a[2], a[3], a[4], a[5] + dJ, Q0 - b[0], Q1 - b[1], Q2 - b[2])

    def g_point_scalar(self, gam: float, phi: float, xd: float, gd: float, pd: float, h: float, hd: float):
        """The pair (dG/dq as 6 numbers row-major (2x3), v_G as 2 numbers) for scalar states.

        Parameters
        ----------
        gam, phi, xd, gd, pd, h, hd : float
            States as in :meth:`accel_scalar`.

        Returns
        -------
        tuple
            dG/dq (6) [m, m/rad] and v_G (2) [m/s].
        """
        p = self._p
        return self._c.jac_g_s(gam, phi, h, *p), self._c.vel_g_s(gam, phi, xd, gd, pd, h, hd, *p)

    # --- vectorized (samples) ---------------------------------------------------------------------
    def mass_matrix(self, gam, phi, h) -> np.ndarray:
        """Mass matrix M(q) (..., 3, 3) of eq. (5) for arrays of gamma, phi, h.

        Parameters
        ----------
        gam, phi, h : array_like
            gamma, phi [rad] and h [m] (broadcast together).

        Returns
        -------
        numpy.ndarray
            M (..., 3, 3) [kg, kg m, kg m^2].
        """
        gam, phi, h = np.broadcast_arrays(*(np.asarray(v, float) for v in (gam, phi, h)))
        e = [np.broadcast_to(np.asarray(v, float), gam.shape) for v in self._c.mass_v(gam, phi, h, *self._p)]
        return np.stack([np.stack([e[0], e[1], e[2]], -1), np.stack([e[1], e[3], e[4]], -1),
                         np.stack([e[2], e[4], e[5]], -1)], -2)

    def bias(self, gam, phi, xd, gd, pd, h, hd, hdd, gx, gz) -> np.ndarray:
        """Bias vector b (..., 3): velocity terms, rheonomic h(t) terms, minus gravity forces.

        Parameters
        ----------
        gam, phi, xd, gd, pd, h, hd, hdd, gx, gz : array_like
            States as in :meth:`accel_scalar` (broadcast together).

        Returns
        -------
        numpy.ndarray
            b (..., 3) [N, N m, N m].
        """
        args = np.broadcast_arrays(*(np.asarray(v, float) for v in (gam, phi, xd, gd, pd, h, hd, hdd, gx, gz)))
        e = self._c.bias_v(*args, *self._p)
        return np.stack([np.broadcast_to(np.asarray(v, float), args[0].shape) for v in e], -1)

    def accelerations(self, gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, Q, dJ=0.0) -> np.ndarray:
        """Generalized accelerations (..., 3) for generalized forces Q (..., 3) (``dJ``: as ``accel_scalar``).

        Parameters
        ----------
        gam, phi, xd, gd, pd, h, hd, hdd, gx, gz : array_like
            States as in :meth:`accel_scalar` (broadcast together).
        Q : array_like
            Generalized forces (..., 3) [N, N m, N m].
        dJ : float or array_like
            Added rider pitch inertia [kg m^2].

        Returns
        -------
        numpy.ndarray
            (..., 3) [m/s^2, rad/s^2, rad/s^2].
        """
        M = self.mass_matrix(gam, phi, h)
        M[..., 2, 2] += dJ
        rhs = np.asarray(Q, float) - self.bias(gam, phi, xd, gd, pd, h, hd, hdd, gx, gz)
        return np.linalg.solve(M, rhs[..., None])[..., 0]

    def rider_cog_jacobian(self, gam, phi, h) -> np.ndarray:
        """dG/dq (..., 2, 3) of the rider CoG G (in-plane x and z rows).

        Parameters
        ----------
        gam, phi, h : array_like
            gamma, phi [rad] and h [m] (broadcast together).

        Returns
        -------
        numpy.ndarray
            dG/dq (..., 2, 3).
        """
        gam, phi, h = np.broadcast_arrays(*(np.asarray(v, float) for v in (gam, phi, h)))
        e = [np.broadcast_to(np.asarray(v, float), gam.shape) for v in self._c.jac_g_v(gam, phi, h, *self._p)]
        return np.stack([np.stack(e[:3], -1), np.stack(e[3:], -1)], -2)

    def rider_cog_velocity(self, gam, phi, xd, gd, pd, h, hd) -> np.ndarray:
        """In-plane velocity of G (..., 2) including the h_dot term.

        Parameters
        ----------
        gam, phi, xd, gd, pd, h, hd : array_like
            States as in :meth:`accel_scalar` (broadcast together).

        Returns
        -------
        numpy.ndarray
            v_G (..., 2) [m/s].
        """
        args = np.broadcast_arrays(*(np.asarray(v, float) for v in (gam, phi, xd, gd, pd, h, hd)))
        e = self._c.vel_g_v(*args, *self._p)
        return np.stack([np.broadcast_to(np.asarray(v, float), args[0].shape) for v in e], -1)


class FloorModel:
    """The planar truth model on a floor of slope ``a(s)`` in a level lab (:func:`.eom_derivation.derive_floor`).

    Same call pattern as :class:`PlanarModel` with the floor's slope ``a`` [rad] and its rate along the
    path ``a1 = da/ds`` [rad/m] as extra arguments; the first coordinate is the arc length s [m] of the wheel
    centre's path (``xd`` its rate [m/s]).

    Parameters
    ----------
    params : PlanarParams
        True physical parameters.
    equations : {"generated", "sympy"}
        Source of the numeric functions (:data:`EQUATIONS`).
    """

    def __init__(self, params: PlanarParams, equations: str = "generated") -> None:
        self.params = params
        self._p = params.as_tuple()
        self._c = _numeric("floor", equations)
        self._plain = PlanarModel(params, equations)

    def accel_scalar(self, gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a, a1, Q0, Q1, Q2):
        """``(s_ddot, gamma_ddot, phi_ddot)`` for scalar states and generalized forces Q_nc.

        Parameters
        ----------
        gam, phi, xd, gd, pd, h, hd, hdd, gx, gz : float
            States, h and gravity as in :meth:`PlanarModel.accel_scalar` (``xd``: s_dot [m/s]).
        a, a1 : float
            Floor slope [rad] and its rate along the path [rad/m].
        Q0, Q1, Q2 : float
            Generalized forces Q_nc [N, N m, N m].

        Returns
        -------
        tuple of float
            The accelerations [m/s^2, rad/s^2, rad/s^2].
        """
        p = self._p
        m_ = self._c.mass_s(gam, phi, h, a, *p)
        b = self._c.bias_s(gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a, a1, *p)
        return solve3(m_[0], m_[1], m_[2], m_[3], m_[4], m_[5], Q0 - b[0], Q1 - b[1], Q2 - b[2])

    def mass_matrix(self, gam, phi, h, a) -> np.ndarray:
        """The mass matrix M(q, a) for arrays of gamma, phi, h, a.

        Parameters
        ----------
        gam, phi, h, a : array_like
            gamma, phi [rad], h [m] and the floor slope [rad] (broadcast together).

        Returns
        -------
        numpy.ndarray
            M (..., 3, 3) [kg, kg m, kg m^2].
        """
        gam, phi, h, a = np.broadcast_arrays(*(np.asarray(v, float) for v in (gam, phi, h, a)))
        e = [np.broadcast_to(np.asarray(v, float), gam.shape) for v in self._c.mass_v(gam, phi, h, a, *self._p)]
        return np.stack([np.stack([e[0], e[1], e[2]], -1), np.stack([e[1], e[3], e[4]], -1),
                         np.stack([e[2], e[4], e[5]], -1)], -2)

    def bias(self, gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a, a1) -> np.ndarray:
        """The bias b (..., 3): velocity, rheonomic and floor-curvature terms minus gravity.

        Parameters
        ----------
        gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a, a1 : array_like
            As in :meth:`accel_scalar` (broadcast together).

        Returns
        -------
        numpy.ndarray
            b (..., 3) [N, N m, N m].
        """
        args = np.broadcast_arrays(*(np.asarray(v, float) for v in (gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a,
                                                                     a1)))
        e = self._c.bias_v(*args, *self._p)
        return np.stack([np.broadcast_to(np.asarray(v, float), args[0].shape) for v in e], -1)

    def accelerations(self, gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a, a1, Q) -> np.ndarray:
        """Generalized accelerations (..., 3) for generalized forces Q (..., 3).

        Parameters
        ----------
        gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a, a1 : array_like
            As in :meth:`accel_scalar` (broadcast together).
        Q : array_like
            Generalized forces (..., 3) [N, N m, N m].

        Returns
        -------
        numpy.ndarray
            (..., 3) [m/s^2, rad/s^2, rad/s^2].
        """
        M = self.mass_matrix(gam, phi, h, a)
        rhs = np.asarray(Q, float) - self.bias(gam, phi, xd, gd, pd, h, hd, hdd, gx, gz, a, a1)
        return np.linalg.solve(M, rhs[..., None])[..., 0]

    def g_point_scalar(self, *args):
        """Rider CoG Jacobian and velocity relative to C's plane of travel (as :class:`PlanarModel`).

        Parameters
        ----------
        *args : float
            ``gam, phi, xd, gd, pd, h, hd`` as in :meth:`PlanarModel.g_point_scalar`.

        Returns
        -------
        tuple
            dG/dq (6) [m, m/rad] and v_G (2) [m/s].
        """
        return self._plain.g_point_scalar(*args)

    def rider_cog_jacobian(self, *args):
        """dG/dq (..., 2, 3) of the rider CoG, as :meth:`PlanarModel.rider_cog_jacobian`.

        Parameters
        ----------
        *args
            ``gam, phi, h``.

        Returns
        -------
        numpy.ndarray
        """
        return self._plain.rider_cog_jacobian(*args)

    def rider_cog_velocity(self, *args):
        """In-plane velocity of G (..., 2), as :meth:`PlanarModel.rider_cog_velocity`.

        Parameters
        ----------
        *args
            ``gam, phi, xd, gd, pd, h, hd``.

        Returns
        -------
        numpy.ndarray
        """
        return self._plain.rider_cog_velocity(*args)


class PedalModel:
    """The truth model with pedals that flex (:func:`.eom_derivation.derive_pedal`): coordinates (x, gamma, phi, u).

    ``accel_scalar`` and ``accelerations`` take the pedal state (u, u_dot) and the generalized force on u
    (``-k u - c u_dot``) and return the four accelerations.

    Parameters
    ----------
    params : PlanarParams
        True physical parameters.
    equations : {"generated", "sympy"}
        Source of the numeric functions (:data:`EQUATIONS`).
    """

    def __init__(self, params: PlanarParams, equations: str = "generated") -> None:
        self.params = params
        self._p = params.as_tuple()
        self._c = _numeric("pedal", equations)
        self._equations = equations

    def mass_matrix(self, gam, phi, u, h) -> np.ndarray:
        """The mass matrix M (..., 4, 4) for arrays of gamma, phi, u, h.

        Parameters
        ----------
        gam, phi, u, h : array_like
            gamma, phi [rad], the pedals' deflection u [m] and h [m] (broadcast together).

        Returns
        -------
        numpy.ndarray
            M (..., 4, 4) [kg, kg m, kg m^2].
        """
        gam, phi, u, h = np.broadcast_arrays(*(np.asarray(v, float) for v in (gam, phi, u, h)))
        e = [np.broadcast_to(np.asarray(v, float), gam.shape) for v in self._c.mass_v(gam, phi, u, h, *self._p)]
        return np.stack(e, -1).reshape(gam.shape + (4, 4))

    def bias(self, gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz) -> np.ndarray:
        """The bias b (..., 4): velocity and rheonomic terms minus gravity.

        Parameters
        ----------
        gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz : array_like
            As in :meth:`accel_scalar` (broadcast together).

        Returns
        -------
        numpy.ndarray
            b (..., 4) [N, N m, N m, N].
        """
        args = np.broadcast_arrays(*(np.asarray(v, float) for v in (gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz)))
        e = self._c.bias_v(*args, *self._p)
        return np.stack([np.broadcast_to(np.asarray(v, float), args[0].shape) for v in e], -1)

    def accel_scalar(self, gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz, Q):
        """(x_ddot, gamma_ddot, phi_ddot, u_ddot) for scalar states and generalized forces Q (4,).

        Parameters
        ----------
        gam, phi, u : float
            gamma, phi [rad] and the pedals' deflection [m].
        xd, gd, pd, ud : float
            x_dot [m/s], gamma_dot, phi_dot [rad/s] and u_dot [m/s].
        h, hd, hdd, gx, gz : float
            Rider CoG height, its rates and in-plane gravity as in :meth:`PlanarModel.accel_scalar`.
        Q : array_like
            Generalized forces (4,) [N, N m, N m, N].

        Returns
        -------
        numpy.ndarray
            (4,) [m/s^2, rad/s^2, rad/s^2, m/s^2].
        """
        a = np.array(self._c.mass_s(gam, phi, u, h, *self._p), float).reshape(4, 4)
        b = np.array(self._c.bias_s(gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz, *self._p), float)
        return np.linalg.solve(a, np.asarray(Q, float) - b)

    def accelerations(self, gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz, Q) -> np.ndarray:
        """Generalized accelerations (..., 4) for generalized forces Q (..., 4).

        Parameters
        ----------
        gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz : array_like
            As in :meth:`accel_scalar` (broadcast together).
        Q : array_like
            Generalized forces (..., 4) [N, N m, N m, N].

        Returns
        -------
        numpy.ndarray
            (..., 4) [m/s^2, rad/s^2, rad/s^2, m/s^2].
        """
        M = self.mass_matrix(gam, phi, u, h)
        rhs = np.asarray(Q, float) - self.bias(gam, phi, u, xd, gd, pd, ud, h, hd, hdd, gx, gz)
        return np.linalg.solve(M, rhs[..., None])[..., 0]

    def rider_cog_jacobian(self, *args):
        """dG/d(x, gamma, phi) of the unflexed geometry (u = 0).

        The simulator uses it only for forces at G, which it does not combine with pedals.

        Parameters
        ----------
        *args : array_like
            ``gam, phi, h`` as in :meth:`PlanarModel.rider_cog_jacobian`.

        Returns
        -------
        numpy.ndarray
            dG/dq (..., 2, 3).
        """
        return PlanarModel(self.params, self._equations).rider_cog_jacobian(*args)

    def rider_cog_velocity(self, *args):
        """v_G of the unflexed geometry (see :meth:`rider_cog_jacobian`).

        Parameters
        ----------
        *args : array_like
            ``gam, phi, xd, gd, pd, h, hd`` as in :meth:`PlanarModel.rider_cog_velocity`.

        Returns
        -------
        numpy.ndarray
            v_G (..., 2) [m/s].
        """
        return PlanarModel(self.params, self._equations).rider_cog_velocity(*args)


def input_directions(R: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Generalized-force directions of the internal torques: ``b_d = (1/R, -1, 0)``, ``b_h = (0, 1, -1)``.

    Derived by virtual power: M_d acts on the wheel (spin rate x_dot/R) and -M_d on the body (pitch
    rate gamma_dot), so ``delta P = M_d (delta x_dot / R - delta gamma_dot)``; M_h acts on the body and
    -M_h on the rider, ``delta P = M_h (delta gamma_dot - delta phi_dot)`` (EUC paper, eq. A.2).

    Parameters
    ----------
    R : float
        Wheel radius [m].

    Returns
    -------
    b_d, b_h : tuple of float
        The directions.
    """
    return (1.0 / R, -1.0, 0.0), (0.0, 1.0, -1.0)


def wheel_rate(x_dot, R):
    """Wheel spin rate [rad/s] for rolling without slip at radius R.

    Parameters
    ----------
    x_dot : float or array_like
        Speed [m/s].
    R : float
        Rolling radius [m].

    Returns
    -------
    float or numpy.ndarray
        The spin rate [rad/s].
    """
    return x_dot / R


__all__ = ["COORDINATES", "EQUATIONS", "FloorModel", "G_M_PER_S2", "PedalModel", "PlanarModel", "PlanarParams",
           "input_directions", "solve3", "symbolic_model", "wheel_rate"]
