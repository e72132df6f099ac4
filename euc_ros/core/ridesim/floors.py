"""Floors that are not level, for the ride simulator: ramps, bumps and steps in a level lab.

A floor is a height profile ``z_f(X)`` along the lab's X axis (Z up, gravity along -Z: Motive's
ground plane calibrated on a level part of the floor), the sum of smooth components:

==================  =======================================  =========================================
kind                parameters                               profile
==================  =======================================  =========================================
``ramp``            slope_deg                                ``tan(a) X`` (the whole floor tilted)
``ramp_from``       slope_deg, x0_m, width_m                 level, then a ramp from x0 (a logistic
                                                             blend of the slope over ``width_m``)
``bump``            height_m, x0_m, width_m                  ``H exp(-(X - x0)^2 / (2 w^2))``
``step``            height_m, x0_m, width_m                  ``H / (1 + exp(-(X - x0) / w))``
==================  =======================================  =========================================

Each component gives ``z``, ``dz/dX`` and ``d2z/dX2`` in closed form (vectorized).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.errors import ConfigError

KINDS = {"ramp": ("slope_deg",), "ramp_from": ("slope_deg", "x0_m", "width_m"),
         "bump": ("height_m", "x0_m", "width_m"), "step": ("height_m", "x0_m", "width_m")}


def _sigmoid(u):
    return 0.5 * (1.0 + np.tanh(0.5 * u))


@dataclass(frozen=True)
class FloorComponent:
    """One component of a floor profile (see the module table).

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`.
    params : dict
        Its parameters by name (SI, units in the names).

    Raises
    ------
    ConfigError
        For an unknown kind, a missing parameter or a width that is not positive.
    """

    kind: str
    params: dict

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ConfigError(f"unknown floor kind {self.kind!r} (known: {', '.join(KINDS)})", key="floor.kind")
        missing = [k for k in KINDS[self.kind] if k not in self.params]
        if missing:
            raise ConfigError(f"floor {self.kind} needs {missing[0]!r}", key=f"floor.{missing[0]}")
        if "width_m" in self.params and not self.params["width_m"] > 0:
            raise ConfigError(f"must be > 0, got {self.params['width_m']}", key="floor.width_m")

    def evaluate(self, X):
        """``(z, dz/dX, d2z/dX2)`` at lab X [m].

        Parameters
        ----------
        X : float or array_like
            Lab x [m].

        Returns
        -------
        tuple
            ``(z [m], dz/dX, d2z/dX2 [1/m])``.
        """
        X = np.asarray(X, float)
        p = self.params
        if self.kind == "ramp":
            k = math.tan(math.radians(p["slope_deg"]))
            return k * X, k + 0.0 * X, 0.0 * X
        if self.kind == "ramp_from":
            k, w = math.tan(math.radians(p["slope_deg"])), p["width_m"]
            u = (X - p["x0_m"]) / w
            s = _sigmoid(u)
            return k * w * np.logaddexp(0.0, u), k * s, k * s * (1 - s) / w
        H, w = p["height_m"], p["width_m"]
        u = (X - p["x0_m"]) / w
        if self.kind == "bump":
            e = np.exp(-0.5 * u * u)
            return H * e, -H * u * e / w, H * (u * u - 1) * e / (w * w)
        s = _sigmoid(u)
        return H * s, H * s * (1 - s) / w, H * s * (1 - s) * (1 - 2 * s) / (w * w)


@dataclass(frozen=True)
class FloorProfile:
    """A floor in a level lab: the sum of components, and where the runs start.

    Straight runs with heading 0 start at ``X = -run_start_m`` and those with heading pi at
    ``+run_start_m``, so every run crosses the same floor (the recorded positions are not re-centred).

    Parameters
    ----------
    components : tuple of FloorComponent
        The components, summed.
    run_start_m : float
        Distance of the runs' start from X = 0 [m].
    """

    components: tuple[FloorComponent, ...] = field(default_factory=tuple)
    run_start_m: float = 5.0

    @classmethod
    def of(cls, *items: tuple[str, dict], run_start_m: float = 5.0) -> "FloorProfile":
        """``FloorProfile.of(("ramp", {"slope_deg": 2.5}), ("bump", {...}))``.

        Parameters
        ----------
        *items : tuple of (str, dict)
            ``(kind, params)`` of each component.
        run_start_m : float
            Distance of the runs' start from X = 0 [m].

        Returns
        -------
        FloorProfile
            The floor.
        """
        return cls(tuple(FloorComponent(k, dict(p)) for k, p in items), run_start_m)

    def evaluate(self, X):
        """``(z, dz/dX, d2z/dX2)`` of the whole floor at lab X [m].

        Parameters
        ----------
        X : float or array_like
            Lab x [m].

        Returns
        -------
        tuple
            ``(z [m], dz/dX, d2z/dX2 [1/m])``.
        """
        X = np.asarray(X, float)
        z = dz = ddz = 0.0 * X
        for c in self.components:
            a, b, d = c.evaluate(X)
            z, dz, ddz = z + a, dz + b, ddz + d
        return z, dz, ddz

    def slope_along(self, X, psi, kappa):
        """Slope angle along travel ``a`` [rad] (positive uphill) and ``da/ds`` [rad/m] for heading psi.

        ``tan a = z'(X) cos psi``; along the path ``dX/ds = cos a cos psi`` and ``dpsi/ds = kappa``.

        Parameters
        ----------
        X : float or array_like
            Lab x [m].
        psi : float or array_like
            Heading [rad].
        kappa : float or array_like
            Path curvature [1/m].

        Returns
        -------
        a : float or numpy.ndarray
            Slope along travel [rad].
        a1 : float or numpy.ndarray
            ``da/ds`` [rad/m].
        """
        _, dz, ddz = self.evaluate(X)
        c, s = np.cos(psi), np.sin(psi)
        a = np.arctan(dz * c)
        ca = np.cos(a)
        a1 = ca * ca * (ddz * c * c * ca - dz * s * kappa)
        return a, a1

    def to_dict(self) -> dict:
        """The floor as a plain mapping, for ``truth.json``.

        Returns
        -------
        dict
            ``components`` (each ``kind`` and its parameters), ``run_start_m`` and the ``frame``.
        """
        return {"components": [{"kind": c.kind, **c.params} for c in self.components],
                "run_start_m": self.run_start_m, "frame": "level lab (gravity along -Z)"}
