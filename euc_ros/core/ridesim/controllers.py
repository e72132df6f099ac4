"""Controllers of the ride simulator's truth: the EUC's balance loop (M_d) and the rider's lean (M_h).

Both are plausible stand-ins for what the EUC paper calls unknown (Section 3: "the embedded control
law is likely based on the pitch angle gamma and pitch rate gamma_dot"), tuned so that the closed
loop reproduces the magnitudes of the paper's Figs 6-7. They only generate the truth; nothing in the
analysis may assume them. Functions take scalars or numpy arrays (one code path for the ODE
right-hand side and for the sampled truth).

EUC balance controller (PD on the body pitch plus a speed term, which pitches the body back at
speed like a real EUC's tilt-back)::

    M_d = k_p gamma + k_d gamma_dot + k_v x_dot

Rider (a person leaning to follow a speed profile)::

    phi_des = atan(c_ff a_ref) + k_sp (v_ref - x_dot) + k_i z + sway(t),   z_dot = v_ref - x_dot
    M_h     = m g h sin(phi) + k_p (phi - phi_des) + k_d phi_dot

with the feed-forward ``c_ff = (m h + R m_eq) / (m g h)`` (the steady lean ``tan(phi) = c_ff a`` of the
reduced model at constant acceleration a), gravity compensation and a PD ankle torque. The integral
of the speed error ``z`` lets the rider hold the profile against slopes and resistances as a person
would.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class EucBalanceController:
    """``M_d = k_p gamma + k_d gamma_dot + k_v x_dot`` [N m].

    Parameters
    ----------
    k_p : float
        Pitch stiffness [N m/rad].
    k_d : float
        Pitch damping [N m s/rad].
    k_v : float
        Speed term [N m s/m] (tilt-back: at constant speed the body settles at gamma = -k_v x_dot / k_p).
    """

    k_p: float = 1500.0
    k_d: float = 60.0
    k_v: float = 6.0

    def torque(self, gamma, gamma_dot, x_dot):
        """Driving torque M_d [N m].

        Parameters
        ----------
        gamma : float or array_like
            EUC body pitch [rad].
        gamma_dot : float or array_like
            Its rate [rad/s].
        x_dot : float or array_like
            Speed [m/s].

        Returns
        -------
        float or numpy.ndarray
            M_d [N m].
        """
        return self.k_p * gamma + self.k_d * gamma_dot + self.k_v * x_dot


@dataclass(frozen=True)
class RiderLeanController:
    """Rider's ankle torque M_h [N m] leaning to follow a speed reference.

    Parameters
    ----------
    k_p : float
        Lean stiffness [N m/rad].
    k_d : float
        Lean damping [N m s/rad].
    k_speed : float
        Lean per speed error [rad s/m].
    k_int : float
        Lean per integrated speed error [rad/m].
    c_ff : float
        Lean feed-forward [s^2/m] (tan(phi) per m/s^2).
    mgh : float
        Gravity-compensation gain m g h [N m] (the rider knows his own weight and posture).
    """

    k_p: float
    k_d: float
    k_speed: float
    k_int: float
    c_ff: float
    mgh: float

    @classmethod
    def for_rider(cls, m: float, h: float, g: float, R: float, m_eq: float, *, k_p: float = 800.0,
                  k_d: float = 150.0, k_speed: float = 0.12, k_int: float = 0.05) -> "RiderLeanController":
        """Build the controller for a rider of mass m [kg] and CoG height h [m] on a wheel of radius R.

        Parameters
        ----------
        m : float
            Rider mass [kg].
        h : float
            Rider CoG height above the hinge [m].
        g : float
            Gravitational acceleration [m/s^2].
        R : float
            Wheel radius [m].
        m_eq : float
            Equivalent translating mass of the vehicle and rider [kg].
        k_p, k_d, k_speed, k_int : float
            Gains (see the class parameters).

        Returns
        -------
        RiderLeanController
            The controller, feed-forward and gravity compensation from the rider.
        """
        return cls(k_p=k_p, k_d=k_d, k_speed=k_speed, k_int=k_int, c_ff=(m * h + R * m_eq) / (m * g * h),
                   mgh=m * g * h)

    def desired_lean(self, v_ref, a_ref, x_dot, z, sway):
        """phi_des [rad] for the speed reference, the speed, the integrated speed error z [m] and sway.

        Parameters
        ----------
        v_ref : float or array_like
            Speed reference [m/s].
        a_ref : float or array_like
            Acceleration reference [m/s^2].
        x_dot : float or array_like
            Speed [m/s].
        z : float or array_like
            Integrated speed error [m].
        sway : float or array_like
            Sway added to the lean [rad].

        Returns
        -------
        float or numpy.ndarray
            phi_des [rad].
        """
        return np.arctan(self.c_ff * a_ref) + self.k_speed * (v_ref - x_dot) + self.k_int * z + sway

    def torque(self, phi, phi_dot, phi_des):
        """M_h [N m].

        Parameters
        ----------
        phi : float or array_like
            Rider pitch [rad].
        phi_dot : float or array_like
            Its rate [rad/s].
        phi_des : float or array_like
            Desired pitch [rad].

        Returns
        -------
        float or numpy.ndarray
            M_h [N m].
        """
        return self.mgh * np.sin(phi) + self.k_p * (phi - phi_des) + self.k_d * phi_dot
