"""Library of candidate effects: physical extensions of the EUC model that may explain M_d1 - M_d2.

Each candidate is a named object with parameters (name, unit, bounds) that modifies the 3-DoF model
(eqs (5)-(8)) in one of three ways, all derived by virtual power:

* an extra generalized force ``dQ(q, q_dot, q_ddot; theta)`` on the right-hand side of (5)
  (``M q_ddot + h = Q_g + dQ + M_d b_d + M_h b_h``);
* a change of a model parameter (wheel radius, rider mass or inertia, gravity in the plane, h(t));
* a change of timing (rider segments delayed against the EUC body in the mocap data).

A candidate acts on a :class:`ModelContext` in two phases: ``modify`` (parameters and states) then
``force`` (extra generalized force, evaluated with the final parameters), so several candidates
compose (greedy forward selection). The formulas (``docs/residual.md``):

==========================  ======================  ==========================================================
name                        parameters              change of the model
==========================  ======================  ==========================================================
rolling_resistance          c_rr [-]                dQ = [-c_rr N tanh(x_dot / 0.05), 0, 0], N = (m+m0+mw) g
viscous_friction            c_v [N s/m]             dQ = [-c_v x_dot, 0, 0]
aero_drag                   cda_m2 [m^2]            dQ = J_G^T F, F = -rho/2 cda |v_G| v_G (rho = 1.2 kg/m^3)
ground_slope                alpha_deg [deg]         gravity (g_x, g_z) = (-g sin a cos psi, -g cos a):
                                                    dQ = Q_g(g_x, g_z) - Q_g(0, -g)
wheel_radius_error          delta_r_m [m]           R -> R + delta
mocap_time_offset           dt_ms [ms]              rider CoG G(t) -> G(t + dt), phi recomputed
rider_mass_error            delta_m_kg [kg]         m -> m + delta
rider_inertia_error         delta_j_kgm2 [kg m^2]   J -> J + delta
tilt_gravity                gain [-]                g -> g + gain (g cos(theta) - a_c sin(theta) - g), a_c = psi_dot x_dot
time_varying_h              amplitude_m, period_s   h(t) = h + a sin(2 pi t / T + p0), dQ = -m J_G^T a_rh,
                                                    a_rh = h_ddot (sin phi, cos phi) + 2 h_dot phi_dot (cos phi, -sin phi)
wheel_body_friction         c_wb [N m s/rad]        dQ = -c_wb (x_dot/R - gamma_dot) [1/R, -1, 0]   (undetectable)
==========================  ======================  ==========================================================

Every reported parameter also has a plausible range for riders on lab floors (:attr:`ParamInfo.plausible`,
sources in :data:`PLAUSIBLE_SOURCES`, table in ``docs/effects.md``), which the residual analysis
requires of a name; :func:`with_plausible` replaces ranges.

Geometry (EUC paper, Appendix A): C = (x, R), A = C + l0 (-sin gamma, -cos gamma),
G = A + h (sin phi, cos phi), so ``J_G = [[1, -l0 cos gamma, h cos phi], [0, l0 sin gamma, -h sin phi]]``.
"""
from __future__ import annotations

import math

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.model.candidate import Candidate, ParamInfo, jacobian_G

#: Air density of aero_drag [kg/m^3].
AIR_DENSITY = 1.2
#: Speed scale of the tanh regularisation of sign(x_dot) [m/s].
ROLLING_SIGN_SPEED = 0.05


class RollingResistance(Candidate):
    """Coulomb-like rolling resistance at the contact: dQ = [-c_rr N tanh(x_dot / v0), 0, 0]."""

    name = "rolling_resistance"
    params = (ParamInfo("c_rr", "-", 0.0, 0.1, 0.0, 0.01, plausible=(0.001, 0.05)),)
    formula = "dQ = [-c_rr (m+m0+mw) g tanh(x_dot/0.05), 0, 0]"

    def force(self, ctx, theta):
        """Rolling resistance at the contact as a generalized force.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on.
        theta : numpy.ndarray
            ``[c_rr]``.

        Returns
        -------
        numpy.ndarray
            dQ (n, 3): ``[-c_rr (m + m0 + mw) g tanh(x_dot / v0), 0, 0]``, v0 = :data:`ROLLING_SIGN_SPEED`.
        """
        p = ctx.p()
        F = -theta[0] * (p.m + p.m0 + p.mw) * p.g * np.tanh(ctx.x_dot / ROLLING_SIGN_SPEED)
        return _x_force(F)


class ViscousFriction(Candidate):
    """Viscous friction at the contact: dQ = [-c_v x_dot, 0, 0]."""

    name = "viscous_friction"
    params = (ParamInfo("c_v", "N s/m", 0.0, 200.0, 0.0, 10.0, plausible=(0.0, 30.0)),)
    formula = "dQ = [-c_v x_dot, 0, 0]"

    def force(self, ctx, theta):
        """Viscous friction at the contact as a generalized force.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on.
        theta : numpy.ndarray
            ``[c_v]`` [N s/m].

        Returns
        -------
        numpy.ndarray
            dQ (n, 3): ``[-c_v x_dot, 0, 0]``.
        """
        return _x_force(-theta[0] * ctx.x_dot)


class AeroDrag(Candidate):
    """Aerodynamic drag on the rider at G: dQ = J_G^T F with F = -rho/2 cda |v_G| v_G."""

    name = "aero_drag"
    params = (ParamInfo("cda_m2", "m^2", 0.0, 3.0, 0.0, 0.5, plausible=(0.2, 1.0)),)
    formula = "dQ = J_G^T F, F = -0.5 rho cda |v_G| v_G"

    def force(self, ctx, theta):
        """Aerodynamic drag on the rider at G as a generalized force.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on.
        theta : numpy.ndarray
            ``[cda_m2]`` [m^2].

        Returns
        -------
        numpy.ndarray
            dQ (n, 3): ``J_G^T F`` with ``F = -0.5 rho cda |v_G| v_G``.
        """
        p = ctx.p()
        jx, jz = jacobian_G(ctx, p)
        qd = np.empty(jx.shape)
        qd[:, 0], qd[:, 1], qd[:, 2] = ctx.x_dot, ctx.gamma_dot, ctx.phi_dot
        vx, vz = np.add.reduce(jx * qd, axis=1), np.add.reduce(jz * qd, axis=1)       # np.sum's reduction
        speed = np.hypot(vx, vz)
        k = 0.5 * AIR_DENSITY * theta[0]
        return jx * (-k * speed * vx)[:, None] + jz * (-k * speed * vz)[:, None]


class GroundSlope(Candidate):
    """Ground slope alpha along world +x: gravity tilted in the plane of a run with heading psi."""

    name = "ground_slope"
    params = (ParamInfo("alpha_deg", "deg", -20.0, 20.0, 0.0, 2.0, plausible=(-5.0, 5.0)),)
    formula = "g = (-g sin(a) cos(psi), -g cos(a)); dQ = Q_g(tilted) - Q_g(vertical)"

    def force(self, ctx, theta):
        """The change of the gravity forces when gravity tilts by the slope along the run's heading.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on.
        theta : numpy.ndarray
            ``[alpha_deg]`` [deg].

        Returns
        -------
        numpy.ndarray
            dQ (n, 3): ``Q_g(tilted) - Q_g(vertical)``.
        """
        p = ctx.p()
        a = np.deg2rad(theta[0])
        g = np.asarray(p.g, float)
        gx = -g * np.sin(a) * np.cos(ctx.psi)
        gz_mag = g * np.cos(a)                      # downward component magnitude
        k_gamma = p.m0 * p.h0 - p.m * p.l0
        dq_x = (p.m + p.m0 + p.mw) * gx
        dq_g = k_gamma * (gx * np.cos(ctx.gamma) + (gz_mag - g) * np.sin(ctx.gamma))
        dq_p = p.m * np.asarray(p.h, float) * (gx * np.cos(ctx.phi) + (gz_mag - g) * np.sin(ctx.phi))
        n = ctx.gamma.shape[0]
        return np.stack([np.broadcast_to(dq_x, (n,)), dq_g, np.broadcast_to(dq_p, (n,))], axis=1)


class WheelRadiusError(Candidate):
    """Rolling radius different from nominal: R -> R + delta."""

    name = "wheel_radius_error"
    params = (ParamInfo("delta_r_m", "m", -0.08, 0.08, 0.0, 0.01, plausible=(-0.03, 0.03)),)
    formula = "R -> R + delta_r"

    def modify(self, ctx, theta):
        """Override the rolling radius: R -> R + delta_r.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on (changed in place: ``overrides["R"]``).
        theta : numpy.ndarray
            ``[delta_r_m]`` [m].
        """
        ctx.overrides["R"] = ctx.params.R + theta[0]


class RiderMassError(Candidate):
    """Rider mass different from nominal: m -> m + delta."""

    name = "rider_mass_error"
    params = (ParamInfo("delta_m_kg", "kg", -45.0, 80.0, 0.0, 5.0, plausible=(-30.0, 40.0)),)
    formula = "m -> m + delta_m"

    def modify(self, ctx, theta):
        """Override the rider mass: m -> m + delta_m.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on (changed in place: ``overrides["m"]``).
        theta : numpy.ndarray
            ``[delta_m_kg]`` [kg].
        """
        ctx.overrides["m"] = ctx.params.m + theta[0]


class RiderInertiaError(Candidate):
    """Rider pitch inertia different from nominal: J -> J + delta."""

    name = "rider_inertia_error"
    params = (ParamInfo("delta_j_kgm2", "kg m^2", -15.0, 40.0, 0.0, 3.0, plausible=(-10.0, 14.0)),)
    formula = "J -> J + delta_J"

    def modify(self, ctx, theta):
        """Override the rider pitch inertia: J -> J + delta_J.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on (changed in place: ``overrides["J"]``).
        theta : numpy.ndarray
            ``[delta_j_kgm2]`` [kg m^2].
        """
        ctx.overrides["J"] = ctx.params.J + theta[0]


class TiltGravity(Candidate):
    """Tilt-gravity coupling in turns: the in-plane gravity of a tilted, turning rider."""

    name = "tilt_gravity"
    params = (ParamInfo("gain", "-", 0.0, 10.0, 0.0, 1.0, plausible=(0.0, 2.5)),)
    formula = "g -> g + gain (g cos(theta) - a_c sin(theta) - g), a_c = psi_dot x_dot"

    def modify(self, ctx, theta):
        """Override gravity with the in-plane gravity of a tilted, turning rider.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on (changed in place: ``overrides["g"]``).
        theta : numpy.ndarray
            ``[gain]``: ``g -> g + gain (g cos(theta) - a_c sin(theta) - g)``, ``a_c = psi_dot x_dot``.
        """
        g = ctx.params.g
        a_c = ctx.psi_dot * ctx.x_dot
        ctx.overrides["g"] = g + theta[0] * (g * np.cos(ctx.theta) - a_c * np.sin(ctx.theta) - g)


class TimeVaryingH(Candidate):
    """Slowly varying rider CoG height h(t) = h + a sin(w t) + b cos(w t), with its rheonomic terms."""

    name = "time_varying_h"
    params = (ParamInfo("a_sin", "m", -0.4, 0.4, 0.0, 0.05, reported=False),
              ParamInfo("a_cos", "m", -0.4, 0.4, 0.0, 0.05, reported=False),
              ParamInfo("period_s", "s", 1.0, 60.0, 5.0, 1.0, plausible=(1.0, 60.0)))
    formula = "h(t) = h + a sin(2 pi t / T + p0); dQ = -m J_G^T [h_dd (sin phi, cos phi) + 2 h_d phi_d (cos phi, -sin phi)]"
    #: Periods tried as starting points [s] (the fit is multi-modal in the period).
    PERIOD_STARTS = (1.5, 2.0, 3.0, 4.5, 6.5, 9.0, 13.0, 20.0, 30.0)

    #: The amplitude as reported (hypot of a_sin, a_cos), for its plausible range.
    AMPLITUDE = ParamInfo("amplitude_m", "m", 0.0, 0.4 * math.sqrt(2.0), plausible=(0.0, 0.2))

    @property
    def checked(self):
        """The reported parameters whose range is checked: the amplitude (:attr:`AMPLITUDE`) and the period."""
        return (self.AMPLITUDE, self.params[2])

    def starts(self):
        """Initial guesses: zero amplitude at each period of :attr:`PERIOD_STARTS`.

        Returns
        -------
        list of numpy.ndarray
            ``[a_sin, a_cos, period_s]`` per start.
        """
        return [np.array([0.0, 0.0, T]) for T in self.PERIOD_STARTS]

    def __getstate__(self):
        state = dict(self.__dict__)
        state.pop("_last_profile", None)          # a cache of arrays: not part of the candidate
        return state

    def _profile(self, t, theta):
        # modify and force of one evaluation ask for the same profile: the last one is kept (with its t)
        key = tuple(float(v) for v in theta)
        last = getattr(self, "_last_profile", None)
        if last is not None and last[0] is t and last[1] == key:
            return last[2]
        a, b, T = key
        w = 2 * np.pi / T
        s, c = np.sin(w * t), np.cos(w * t)
        out = (a * s + b * c, w * (a * c - b * s), -w * w * (a * s + b * c))
        self._last_profile = (t, key, out)
        return out

    def modify(self, ctx, theta):
        """Override h with the varying height ``h + a sin(w t) + b cos(w t)``, ``w = 2 pi / T``.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on (changed in place: ``overrides["h"]``).
        theta : numpy.ndarray
            ``[a_sin, a_cos, period_s]``.
        """
        dh, _, _ = self._profile(ctx.t, theta)
        ctx.overrides["h"] = ctx.params.h + dh

    def force(self, ctx, theta):
        """The rheonomic force of the varying height on the rider's CoG.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on.
        theta : numpy.ndarray
            ``[a_sin, a_cos, period_s]``.

        Returns
        -------
        numpy.ndarray
            dQ (n, 3): ``-m J_G^T [h_dd (sin phi, cos phi) + 2 h_d phi_d (cos phi, -sin phi)]``.
        """
        p = ctx.p()
        _, hd, hdd = self._profile(ctx.t, theta)
        sphi, cphi = np.sin(ctx.phi), np.cos(ctx.phi)
        ax = hdd * sphi + 2 * hd * ctx.phi_dot * cphi
        az = hdd * cphi - 2 * hd * ctx.phi_dot * sphi
        jx, jz = jacobian_G(ctx, p)
        return -p.m * (jx * ax[:, None] + jz * az[:, None])

    def report(self, theta):
        """The parameters as reported: the amplitude, period and phase of the sinusoid.

        Parameters
        ----------
        theta : numpy.ndarray
            ``[a_sin, a_cos, period_s]``.

        Returns
        -------
        dict
            ``amplitude_m`` (the hypot of a_sin and a_cos), ``period_s`` and ``phase_rad``.
        """
        return {"amplitude_m": float(np.hypot(theta[0], theta[1])), "period_s": float(theta[2]),
                "phase_rad": float(np.arctan2(theta[1], theta[0]))}


class MocapTimeOffset(Candidate):
    """Rider segments delayed by dt against the EUC body in the mocap: G(t) -> G(t + dt), phi recomputed.

    Needs ``ctx.extras['phi_shift']``: a callable ``dt_s -> (dphi, dphi_dot, dphi_ddot)`` giving the
    change of phi and its derivatives when the rider CoG is shifted by ``dt_s`` (built by the analysis
    from the recording's geometry, so that ``dt = 0`` changes nothing).
    """

    name = "mocap_time_offset"
    params = (ParamInfo("dt_ms", "ms", -200.0, 200.0, 0.0, 2.0, plausible=(-50.0, 50.0)),)
    formula = "G(t) -> G(t + dt); phi, phi_dot, phi_ddot recomputed"

    def starts(self):
        """Initial guesses of the offset: -40, 0 and 40 ms.

        Returns
        -------
        list of numpy.ndarray
            ``[dt_ms]`` per start.
        """
        return [np.array([v]) for v in (-40.0, 0.0, 40.0)]

    def modify(self, ctx, theta):
        """Shift the rider's pitch phi and its rates as if the rider CoG were delayed by dt.

        Nothing changes without ``ctx.extras['phi_shift']`` or at dt = 0.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on (changed in place: ``phi``, ``phi_dot``,
            ``phi_ddot`` and ``mask``, the samples where the shift is finite).
        theta : numpy.ndarray
            ``[dt_ms]`` [ms].
        """
        shift = ctx.extras.get("phi_shift")
        if shift is None or theta[0] == 0.0:
            return
        d0, d1, d2 = shift(theta[0] * 1e-3)
        ctx.phi, ctx.phi_dot, ctx.phi_ddot = ctx.phi + d0, ctx.phi_dot + d1, ctx.phi_ddot + d2
        ctx.mask = np.isfinite(d0) & np.isfinite(d1) & np.isfinite(d2)


class WheelBodyFriction(Candidate):
    """Friction torque between wheel and body; acts along the M_d direction (undetectable)."""

    name = "wheel_body_friction"
    params = (ParamInfo("c_wb", "N m s/rad", 0.0, 10.0, 0.0, 0.5, plausible=(0.0, 3.0)),)
    formula = "dQ = -c_wb (x_dot/R - gamma_dot) [1/R, -1, 0]"

    def force(self, ctx, theta):
        """Friction torque between wheel and body as a generalized force.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on.
        theta : numpy.ndarray
            ``[c_wb]`` [N m s/rad].

        Returns
        -------
        numpy.ndarray
            dQ (n, 3): ``-c_wb (x_dot/R - gamma_dot) [1/R, -1, 0]``.
        """
        p = ctx.p()
        tau = -theta[0] * (ctx.x_dot / p.R - ctx.gamma_dot)
        return np.stack([tau / p.R, -tau, np.zeros_like(tau)], axis=1)


class FloorGeometry(Candidate):
    """The floor measured from the contact path, in a lab whose vertical is gravity's.

    A floor tilted in the mocap frame (a ramp or a bump in a level-calibrated lab) is known without
    dynamics: the wheel centre C moves along it with slope ``a(t)`` along travel (measured) and vertical
    acceleration ``C_zdd`` (measured), while gamma and phi are angles from gravity's vertical. Newton's
    law projected on the path's tangent (s: arc length, ``s_ddot = cos a x_ddot + sin a C_zdd`` with
    x_ddot the horizontal acceleration the states carry) and on gamma, phi in the frame translating with
    C give, against the level model:

    * gamma, phi rows: gravity ``g -> g + C_zdd`` (the frame of C accelerates vertically);
    * x row: ``dQ_x = m_eq (x_ddot - s_ddot) + (1 - cos a) P_x - sin a P_z - m_tot g sin a``, with
      ``P = d2/dt2 (m0 rho_0 + m rho_G)`` the rate of the body and rider's momentum relative to C
      (``P_x = k (cos g g_dd - sin g g_d^2) + m h (cos p p_dd - sin p p_d^2)``, ``P_z = -k (sin g g_dd +
      cos g g_d^2) - m h (sin p p_dd + cos p p_d^2)``, ``k = m0 h0 - m l0``).

    No parameter is fitted: the signals come from the recording (``ctx.extras['floor_a']``,
    ``ctx.extras['c_zdd']``). A mocap frame tilted against gravity (ground plane set on a sloped floor)
    leaves the floor flat in the data: that stays :class:`GroundSlope`, a dynamic candidate.

    Parameters
    ----------
    alpha_x_deg, alpha_y_deg : float
        The floor's mean slopes along x and y [deg], for the report only (NaN: unknown).
    """

    name = "ground_slope"
    params = ()
    formula = "floor measured: g -> g + C_zdd (gamma, phi); dQ_x = m_eq (x_dd - s_dd) + (1 - cos a) P_x - sin a P_z - m_tot g sin a"
    geometric = True

    def __init__(self, alpha_x_deg: float = float("nan"), alpha_y_deg: float = float("nan")):
        self.alpha_x_deg, self.alpha_y_deg = float(alpha_x_deg), float(alpha_y_deg)

    def _signals(self, ctx):
        """Slope along travel and C_zdd.

        Measured (extras), or of the plane ``alpha`` (a configured model:
        ``tan a = tan(alpha_x) cos psi + tan(alpha_y) sin psi``, ``C_zdd = x_ddot tan a``).
        """
        a, czz = ctx.extras.get("floor_a"), ctx.extras.get("c_zdd")
        if a is None:
            tx, ty = (math.tan(math.radians(v)) if math.isfinite(v) else 0.0 for v in (self.alpha_x_deg,
                                                                                       self.alpha_y_deg))
            a = np.arctan(tx * np.cos(ctx.psi) + ty * np.sin(ctx.psi)) + 0.0 * ctx.x_dot
        if czz is None:
            czz = ctx.x_ddot * np.tan(a)
        return a, czz

    def modify(self, ctx, theta):
        """Gravity in the gamma and phi rows: ``g -> g + C_zdd`` (the frame of C accelerates vertically).

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on (changed in place: ``overrides["g"]``).
        theta : numpy.ndarray
            Unused (no parameter is fitted).
        """
        _, czz = self._signals(ctx)
        ctx.overrides["g"] = ctx.params.g + czz

    def force(self, ctx, theta):
        """The x row's force of the measured floor against the level model (class docstring).

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on.
        theta : numpy.ndarray
            Unused (no parameter is fitted).

        Returns
        -------
        numpy.ndarray
            dQ (n, 3): ``[m_eq (x_dd - s_dd) + (1 - cos a) P_x - sin a P_z - m_tot g sin a, 0, 0]``.
        """
        a, czz = self._signals(ctx)
        p = ctx.p()
        g0 = float(ctx.params.g)
        h = np.asarray(p.h, float)
        k = p.m0 * p.h0 - p.m * p.l0
        cg, sg, cp, sp_ = np.cos(ctx.gamma), np.sin(ctx.gamma), np.cos(ctx.phi), np.sin(ctx.phi)
        gd2, pd2 = ctx.gamma_dot ** 2, ctx.phi_dot ** 2
        Px = k * (cg * ctx.gamma_ddot - sg * gd2) + p.m * h * (cp * ctx.phi_ddot - sp_ * pd2)
        Pz = -k * (sg * ctx.gamma_ddot + cg * gd2) - p.m * h * (sp_ * ctx.phi_ddot + cp * pd2)
        ca, sa = np.cos(a), np.sin(a)
        m_tot = p.m + p.m0 + p.mw
        m_eq = m_tot + p.Jw / np.asarray(p.R, float) ** 2
        s_dd = ca * ctx.x_ddot + sa * czz
        return _x_force(m_eq * (ctx.x_ddot - s_dd) + (1 - ca) * Px - sa * Pz - m_tot * g0 * sa)

    def report(self, theta):
        """The floor as reported (no parameter is fitted).

        Parameters
        ----------
        theta : numpy.ndarray
            Unused.

        Returns
        -------
        dict
            ``alpha_deg``, ``alpha_y_deg`` (the configured plane; NaN when the floor is measured) and ``level_lab`` 1.
        """
        return {"alpha_deg": self.alpha_x_deg, "alpha_y_deg": self.alpha_y_deg, "level_lab": 1.0}


def _x_force(F: np.ndarray) -> np.ndarray:
    F = np.asarray(F)
    out = np.zeros(F.shape[:1] + (3,) + F.shape[1:], F.dtype)
    out[:, 0] = F
    return out


#: The library, by spec name (docs/residual.md, JSON).
LIBRARY: dict[str, type[Candidate]] = {c.name: c for c in (
    RollingResistance, ViscousFriction, AeroDrag, GroundSlope, WheelRadiusError, MocapTimeOffset,
    RiderMassError, RiderInertiaError, TiltGravity, TimeVaryingH, WheelBodyFriction)}


def make_candidates(names=None, plausible: dict[str, tuple[float, float]] | None = None) -> list[Candidate]:
    """Instantiate library candidates (all by default) in library order.

    Parameters
    ----------
    names : iterable of str, optional
        Effect names of :data:`LIBRARY` (default: all).
    plausible : dict, optional
        Plausible ranges that replace the library's, by ``"effect.parameter"`` (:func:`with_plausible`).

    Returns
    -------
    list of Candidate

    Raises
    ------
    ConfigError
        For an unknown effect (key ``effect``).
    """
    names = list(LIBRARY) if names is None else list(names)
    unknown = [n for n in names if n not in LIBRARY]
    if unknown:
        raise ConfigError(f"unknown effect {unknown[0]!r} (known: {', '.join(LIBRARY)})", key="effect")
    return with_plausible([LIBRARY[n]() for n in names], plausible or {})


def with_plausible(candidates: list[Candidate], ranges: dict[str, tuple[float, float]]) -> list[Candidate]:
    """Set plausible ranges other than the library's on ``candidates`` (in place; returns them).

    Parameters
    ----------
    candidates : list of Candidate
    ranges : dict
        ``"effect.parameter" -> (low, high)`` in the parameter's reported unit; an effect not among
        ``candidates`` is ignored (it is not tried), an unknown parameter of a library effect is an error.

    Returns
    -------
    list of Candidate

    Raises
    ------
    ConfigError
        For an unknown effect or parameter, or a range with ``low > high``.
    """
    by_name = {c.name: c for c in candidates}
    for key, (lo, hi) in ranges.items():
        effect, _, param = key.partition(".")
        if effect not in LIBRARY:
            raise ConfigError(f"unknown effect {effect!r} in plausible range {key!r} (known: {', '.join(LIBRARY)})",
                              key=key)
        known = [q.name for q in LIBRARY[effect]().checked]
        if param not in known:
            raise ConfigError(f"{effect} has no parameter {param!r} (known: {', '.join(known)})", key=key)
        if not lo <= hi:
            raise ConfigError(f"plausible range of {key} has low {lo:g} > high {hi:g}", key=key)
        c = by_name.get(effect)
        if c is not None:
            c.plausible_overrides = {**getattr(c, "plausible_overrides", {}), param: (float(lo), float(hi))}
    return candidates


def parse_plausible(items) -> dict[str, tuple[float, float]]:
    """Plausible ranges from ``EFFECT.PARAM=LOW:HIGH`` strings (the ``--plausible`` option).

    Parameters
    ----------
    items : iterable of str

    Returns
    -------
    dict
        ``"effect.parameter" -> (low, high)``, checked by :func:`with_plausible` when applied.

    Raises
    ------
    ConfigError
        For an item not of that form.
    """
    out = {}
    for item in items:
        key, sep, rng = item.partition("=")
        lo, sep2, hi = rng.partition(":")
        try:
            if not (sep and sep2 and "." in key):
                raise ValueError(item)
            out[key.strip()] = (float(lo), float(hi))
        except ValueError:
            raise ConfigError(f"plausible range {item!r} is not EFFECT.PARAM=LOW:HIGH (e.g. aero_drag.cda_m2=0.2:1.2)",
                              key="--plausible") from None
    return out


def theta_from_report(candidate: Candidate, values: dict[str, float]) -> np.ndarray:
    """Inverse of :meth:`Candidate.report`: parameters from reported values (for configured models).

    Parameters
    ----------
    candidate : Candidate
        The effect.
    values : dict of str to float
        Its reported parameter values by name.

    Returns
    -------
    numpy.ndarray
        The effect's parameter vector (n_params,).

    Raises
    ------
    ConfigError
        When a parameter of the effect is missing from ``values``.
    """
    if isinstance(candidate, FloorGeometry):
        return np.zeros(0)
    if isinstance(candidate, TimeVaryingH):
        a = float(values.get("amplitude_m", 0.0))
        T = float(values.get("period_s", 5.0))
        phase = float(values.get("phase_rad", 0.0))
        return np.array([a * np.cos(phase), a * np.sin(phase), T])
    out = []
    for q in candidate.params:
        if q.name not in values:
            raise ConfigError(f"missing parameter {q.name!r} of effect {candidate.name!r}",
                              key=f"{candidate.name}.{q.name}")
        out.append(float(values[q.name]))
    return np.array(out, float)
