"""Forces outside the residual analysis' library, for tests the analysis was not designed around.

Each force is written here from its own physics (no code shared with :mod:`euc_ros.core.residual`),
as a generalized force on (x, gamma, phi) by virtual power on the points it acts on. The in-plane
geometry is the simulator's (:mod:`.truth_model`): ``A = C + l0 (-sin gamma, -cos gamma)``, a point
at distance d from A along the rider ``P = A + d (sin phi, cos phi)``, so
``dP/dq = [[1, -l0 cos gamma, d cos phi], [0, l0 sin gamma, -d sin phi]]``.

==================  =====================================================================================
``rope``            a rope or rail held in the hand (``hand_m`` above the hinge) pulling towards an anchor at
                    lab ``x = anchor_x_m`` with stiffness ``k_n_per_m`` (horizontal, lab x): a force that
                    changes with position
``headwind``        steady wind of ``wind_m_per_s`` blowing along lab -x on the rider at G (drag area
                    ``cda_m2``): ``F = -rho/2 cda |v_rel| v_rel``, ``v_rel = v_G - w``
``contact_drag``    a drag growing with the square of speed at the tyre contact (a soft floor mat, a tyre that
                    scrubs): ``F = -c x_dot |x_dot|`` along x at the contact (``c`` = ``c_n_s2_per_m2``)
``wheel_harmonics``  an out-of-round tyre: radius ``R + e_2 cos(2 x/R) + e_3 cos(3 x/R + phase3_rad)`` under the
                    normal force N: the centre's path has slope ``dr/dx``, so the floor pushes along travel
                    with ``F = -N dr/dx = amp2_n sin(2 x/R) + amp3_n sin(3 x/R + phase3_rad)`` at the
                    contact (``amp_k = N k e_k / R``: 8 N for e_2 = 0.8 mm under 1000 N on R = 0.2 m)
``lab_bump``        a draught across one stretch of the lab (a door, a fan): a horizontal force along lab x on
                    the rider at G, ``amp_n exp(-((X - x0_m) / width_m)^2 / 2)`` with X the wheel's lab x (a
                    force that changes with lab position, neither constant nor linear in it)
``torque_ripple``   motor torque ripple ``amp_nm sin(n x / R)`` (``n`` = ``per_turn``): internal, along
                    the input direction b_d = (1/R, -1, 0): it cannot show in M_d1 - M_d2
==================  =====================================================================================
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError

AIR_DENSITY = 1.2
KINDS = {"rope": ("k_n_per_m", "anchor_x_m", "hand_m"), "headwind": ("wind_m_per_s", "cda_m2"),
         "torque_ripple": ("amp_nm", "per_turn"), "contact_drag": ("c_n_s2_per_m2",),
         "wheel_harmonics": ("amp2_n", "amp3_n", "phase3_rad"), "lab_bump": ("amp_n", "x0_m", "width_m")}


@dataclass(frozen=True)
class ExternalForce:
    """One force of :data:`KINDS` with its parameters.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    params : dict
        Its parameters by name (SI, units in the names).

    Raises
    ------
    ConfigError
        For an unknown kind or a missing parameter.
    """

    kind: str
    params: dict

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ConfigError(f"unknown external force {self.kind!r} (known: {', '.join(KINDS)})", key="external")
        missing = [k for k in KINDS[self.kind] if k not in self.params]
        if missing:
            raise ConfigError(f"{self.kind} needs {missing[0]!r}", key=f"external.{missing[0]}")

    @property
    def lab_fixed(self) -> bool:
        """True when the force depends on lab position (the rope's anchor).

        The simulator then records every run in the same lab frame (no re-centring of the track), so the
        anchor is one point of the recordings.
        """
        return self.kind in ("rope", "lab_bump")

    def generalized(self, *, x, gamma, phi, x_dot, gamma_dot, phi_dot, h, X, psi, R, l0):
        """(dQ_x, dQ_gamma, dQ_phi) at the given states (scalars or arrays).

        Parameters
        ----------
        x : float or array_like
            Distance travelled [m].
        gamma, phi : float or array_like
            EUC body pitch and rider pitch [rad].
        x_dot : float or array_like
            Speed [m/s].
        gamma_dot, phi_dot : float or array_like
            Pitch rates [rad/s].
        h : float or array_like
            Rider CoG height above the hinge [m].
        X : float or array_like
            Lab x of the wheel centre [m].
        psi : float or array_like
            Heading [rad].
        R : float
            Wheel radius [m].
        l0 : float
            Distance from the ankle hinge to the wheel centre [m].

        Returns
        -------
        tuple
            ``(dQ_x [N], dQ_gamma [N m], dQ_phi [N m])``.
        """
        p = self.params
        if self.kind == "torque_ripple":
            tau = p["amp_nm"] * np.sin(p["per_turn"] * x / R)
            return tau / R, -tau, 0.0 * tau
        if self.kind == "lab_bump":
            # along lab x at G; its in-plane component along the heading is F cos(psi)
            F = p["amp_n"] * np.exp(-0.5 * ((X - p["x0_m"]) / p["width_m"]) ** 2) * np.cos(psi)
            return F, -l0 * np.cos(gamma) * F, h * np.cos(phi) * F
        if self.kind == "wheel_harmonics":
            # the floor's reaction along travel at the contact, which moves with x_dot only
            F = p["amp2_n"] * np.sin(2.0 * x / R) + p["amp3_n"] * np.sin(3.0 * x / R + p["phase3_rad"])
            return F, 0.0 * F, 0.0 * F
        if self.kind == "contact_drag":
            # the contact point moves with x_dot and does no virtual work through gamma or phi
            F = -p["c_n_s2_per_m2"] * x_dot * np.abs(x_dot)
            return F, 0.0 * F, 0.0 * F
        if self.kind == "rope":
            d = p["hand_m"]
            # the hand's lab x (C's x plus its offset along the heading); the pull is along lab x, its in-plane
            # component along the heading is F cos(psi)
            off = -l0 * np.sin(gamma) + d * np.sin(phi)
            hand_x = X + off * np.cos(psi)
            F = -p["k_n_per_m"] * (hand_x - p["anchor_x_m"]) * np.cos(psi)
            return F, -l0 * np.cos(gamma) * F, d * np.cos(phi) * F
        # headwind at G
        w = -p["wind_m_per_s"] * np.cos(psi)           # wind along the heading (in-plane x)
        vx = x_dot - l0 * np.cos(gamma) * gamma_dot + h * np.cos(phi) * phi_dot - w
        vz = l0 * np.sin(gamma) * gamma_dot - h * np.sin(phi) * phi_dot
        k = 0.5 * AIR_DENSITY * p["cda_m2"]
        speed = np.sqrt(vx * vx + vz * vz)
        Fx, Fz = -k * speed * vx, -k * speed * vz
        return (Fx, -l0 * np.cos(gamma) * Fx + l0 * np.sin(gamma) * Fz,
                h * np.cos(phi) * Fx - h * np.sin(phi) * Fz)

    def to_dict(self) -> dict:
        """The force as a plain mapping, for ``truth.json``.

        Returns
        -------
        dict
            ``kind`` and the force's parameters.
        """
        return {"kind": self.kind, **self.params}
