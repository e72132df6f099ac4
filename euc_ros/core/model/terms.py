"""The planar 3-DoF model of the EUC with a human rider (EUC paper, Section 3, eqs (5)-(8)).

Generalized coordinates ``q = [x, gamma, phi]``: longitudinal position of the wheel centre C [m],
pitch of the EUC body [rad] and pitch of the rider about the ankle hinge A [rad]. Geometry
(paper Fig. 5, see ERRATA): ``C = (x, R)``; ``A = C + l0 (-sin gamma, -cos gamma)`` (below C);
EUC CoG ``G0 = C + h0 (sin gamma, cos gamma)``; rider CoG ``G = A + h (sin phi, cos phi)``.

Equations of motion (5): ``M(q) q_ddot + h(q, q_dot) = Q``, with ``Q = Q_g + M_d b_d + M_h b_h``
where the gravity part ``Q_g`` comes from (8) and the two internal torques act along

* ``b_d = [1/R, -1, 0]`` (driving torque M_d between wheel and EUC body), and
* ``b_h = [0, 1, -1]`` (rider's control torque M_h between EUC body and rider).

``w = [R, 1, 1]`` annihilates both: ``w . b_d = w . b_h = 0``. Every function broadcasts over
samples, including the parameters: any field of :class:`EucParams` may be an array (for example
``h`` of shape ``(n_grid, 1)`` against states of shape ``(n,)``).

Examples
--------
>>> import numpy as np
>>> p = EucParams(h=0.61)
>>> M = mass_matrix(np.zeros(3), p)
>>> round(float(M[0, 0]), 6)  # m + m0 + mw + Jw / R^2
84.0
>>> float(np.dot(input_directions(p)[0], [p.R, 1, 1]))
0.0
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

#: Gravitational acceleration used by default [m/s^2].
GRAVITY = 9.81


@dataclass(frozen=True)
class EucParams:
    """Parameters of the 3-DoF model (EUC paper, Table 3), SI units.

    Any field may be a numpy array; all functions of this module broadcast them against the states.

    Parameters
    ----------
    m : float
        Rider mass [kg].
    J : float
        Rider pitch moment of inertia about the rider's CoG G [kg m^2].
    m0, J0 : float
        EUC body mass [kg] and pitch moment of inertia about G0 [kg m^2].
    mw, Jw : float
        Wheel mass [kg] and moment of inertia about its axle [kg m^2].
    R : float
        Wheel radius [m].
    h0 : float
        Distance C-G0 [m].
    l0 : float
        Distance A-C [m].
    g : float
        Gravitational acceleration [m/s^2].
    h : float
        Distance A-G [m] (the rider CoG height above the ankle hinge; the identified parameter).
    """

    m: Any = 65.0
    J: Any = 16.6
    m0: Any = 13.0
    J0: Any = 0.5
    mw: Any = 3.0
    Jw: Any = 0.12
    R: Any = 0.2
    h0: Any = 0.075
    l0: Any = 0.05
    g: Any = GRAVITY
    h: Any = 0.61

    @classmethod
    def from_session(cls, session, h: Any = 0.61, *, g: Any = GRAVITY) -> "EucParams":
        """Build the nominal parameters of a :class:`~euc_ros.core.session.Session` with CoG height ``h`` [m].

        Parameters
        ----------
        session : Session
            The session (rider and EUC parameters).
        h : float or array_like
            CoG height above the ankle hinge [m].
        g : float or array_like
            Gravitational acceleration [m/s^2].

        Returns
        -------
        EucParams
            The nominal parameters.
        """
        e, r = session.euc, session.rider
        return cls(m=r.mass, J=r.inertia_pitch, m0=e.body_mass, J0=e.body_inertia, mw=e.wheel_mass,
                   Jw=e.wheel_inertia, R=e.wheel_radius, h0=e.h0, l0=e.l0, g=g, h=h)

    def with_h(self, h: Any) -> "EucParams":
        """A copy with CoG height ``h`` [m] (scalar or array).

        Parameters
        ----------
        h : float or array_like
            CoG height above the ankle hinge [m].

        Returns
        -------
        EucParams
            The copy.
        """
        return self.with_values({"h": h})

    def with_values(self, changes: dict[str, Any]) -> "EucParams":
        """A copy with the fields of ``changes`` replaced (the residual analysis' inner loop).

        The same object ``dataclasses.replace`` makes (every field not changed is the same object), without its
        per-field ``__init__``; a name that is not a field raises as ``dataclasses.replace`` does.

        Parameters
        ----------
        changes : dict of str to Any
            New values by field name (scalars or arrays) [SI].

        Returns
        -------
        EucParams
            The copy.
        """
        if not _FIELD_NAMES.issuperset(changes):
            return replace(self, **changes)
        new = object.__new__(type(self))
        state = new.__dict__
        state.update(self.__dict__)
        state.update(changes)
        return new

    def reduced(self) -> "EucParams":
        """The parameters of the reduced 2-DoF model (Section 3.2): ``J0 = h0 = l0 = 0``.

        Returns
        -------
        EucParams
            A copy with ``J0 = h0 = l0 = 0``.
        """
        return replace(self, J0=0.0, h0=0.0, l0=0.0)

    @property
    def m_eq(self) -> Any:
        """Equivalent translating mass ``m + m0 + mw + Jw / R^2`` [kg] (eq (13), ``m11`` of eq (6))."""
        return self.m + self.m0 + self.mw + self.Jw / self.R**2

    def as_dict(self) -> dict[str, Any]:
        """The fields as a plain dict (floats where scalar).

        Returns
        -------
        dict of str to Any
            Field values by name: floats, or lists for array fields.
        """
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = float(v) if np.ndim(v) == 0 else np.asarray(v).tolist()
        return out


#: The field names of :class:`EucParams` (what :meth:`EucParams.with_values` may change).
_FIELD_NAMES = frozenset(f.name for f in fields(EucParams))


def _split(q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    q = np.asarray(q, dtype=float)
    return q[..., 0], q[..., 1], q[..., 2]


def mass_matrix(q, p: EucParams) -> np.ndarray:
    """Mass matrix ``M(q)`` of eq (6).

    Parameters
    ----------
    q : array_like (..., 3)
        ``[x, gamma, phi]`` [m, rad, rad]; ``x`` is not used (cyclic coordinate).
    p : EucParams

    Returns
    -------
    ndarray (..., 3, 3)
        [kg, kg m, kg m^2 entries as in eq (6)].
    """
    _, gamma, phi = _split(q)
    m11 = p.m_eq + 0.0 * gamma
    m12 = -(p.m * p.l0 - p.m0 * p.h0) * np.cos(gamma)
    m13 = p.m * p.h * np.cos(phi)
    m22 = p.J0 + p.m0 * p.h0**2 + p.m * p.l0**2 + 0.0 * gamma
    m23 = -p.m * p.h * p.l0 * np.cos(phi - gamma)
    m33 = p.J + p.m * p.h**2 + 0.0 * phi
    m11, m12, m13, m22, m23, m33 = np.broadcast_arrays(m11, m12, m13, m22, m23, m33)
    return np.stack([np.stack([m11, m12, m13], -1), np.stack([m12, m22, m23], -1),
                     np.stack([m13, m23, m33], -1)], -2)


def bias_terms(q, qd, p: EucParams) -> np.ndarray:
    """Velocity-dependent terms ``h(q, q_dot)`` of eq (7) [N, N m, N m].

    Parameters
    ----------
    q, qd : array_like (..., 3)
        Coordinates ``[x, gamma, phi]`` and velocities ``[x_dot, gamma_dot, phi_dot]`` [m/s, rad/s].
    p : EucParams

    Returns
    -------
    numpy.ndarray
        ``[h1, h2, h3]`` (..., 3) [N, N m, N m].
    """
    _, gamma, phi = _split(q)
    _, gd, pd = _split(qd)
    h1 = -p.m * p.h * pd**2 * np.sin(phi) + (p.m * p.l0 - p.m0 * p.h0) * gd**2 * np.sin(gamma)
    h2 = p.m * p.h * p.l0 * pd**2 * np.sin(phi - gamma)
    h3 = -p.m * p.h * p.l0 * gd**2 * np.sin(phi - gamma)
    return np.stack(np.broadcast_arrays(h1, h2, h3), -1)


def gravity_forces(q, p: EucParams) -> np.ndarray:
    """Gravity part of the generalized forces of eq (8) [N, N m, N m].

    ``Q_g = [0, (m0 h0 - m l0) g sin gamma, m g h sin phi]``.

    Parameters
    ----------
    q : array_like (..., 3)
        Coordinates ``[x, gamma, phi]`` [m, rad, rad].
    p : EucParams
        Model parameters.

    Returns
    -------
    numpy.ndarray
        ``Q_g`` (..., 3) [N, N m, N m].
    """
    _, gamma, phi = _split(q)
    q1 = 0.0 * gamma + 0.0 * phi
    q2 = (p.m0 * p.h0 - p.m * p.l0) * p.g * np.sin(gamma)
    q3 = p.m * p.g * p.h * np.sin(phi)
    return np.stack(np.broadcast_arrays(q1, q2, q3), -1)


def input_directions(p: EucParams) -> tuple[np.ndarray, np.ndarray]:
    """Generalized-force directions ``(b_d, b_h)`` of the driving and the rider torques (eq (8)).

    ``Q = Q_g + M_d b_d + M_h b_h`` with ``b_d = [1/R, -1, 0]`` and ``b_h = [0, 1, -1]``.

    Parameters
    ----------
    p : EucParams
        Model parameters (``R`` used; may be an array).

    Returns
    -------
    b_d, b_h : numpy.ndarray
        Directions (..., 3) of the driving torque [1/m, 1, 1] and of the rider torque.
    """
    R = np.asarray(p.R, dtype=float)
    b_d = np.stack(np.broadcast_arrays(1.0 / R, -1.0 + 0 * R, 0.0 * R), -1)
    b_h = np.stack(np.broadcast_arrays(0.0 * R, 1.0 + 0 * R, -1.0 + 0 * R), -1)
    return b_d, b_h


def consistency_weights(p: EucParams) -> np.ndarray:
    """Row weights ``w = [R, 1, 1]`` that annihilate both input directions (``w . b_d = w . b_h = 0``).

    ``w . (M q_ddot + h - Q_g) = 0`` is the one equation of (5) free of both unknown torques: a
    trajectory that violates it cannot be produced by any M_d, M_h.

    Parameters
    ----------
    p : EucParams
        Model parameters (``R`` used; may be an array).

    Returns
    -------
    numpy.ndarray
        ``[R, 1, 1]`` (..., 3) [m, 1, 1].
    """
    R = np.asarray(p.R, dtype=float)
    return np.stack(np.broadcast_arrays(R, 1.0 + 0 * R, 1.0 + 0 * R), -1)
