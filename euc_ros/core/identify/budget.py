"""Uncertainty budget of h over the session's nominal values no residual can check.

Masses, inertias, l0, h0 and the segment CoM offsets enter the model as given; h moves with them
while the residual stays at its floor. :func:`budget` measures dh/dp for each (re-identifying with
the value perturbed) and the h range that stated tolerances imply (:data:`DEFAULT_TOLERANCES`,
overridden by :func:`parse_tolerances`).
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.fit import fit_h, pooled_h_of_states
from euc_ros.core.identify.interval import json_float
from euc_ros.core.memory import release_free_memory
from euc_ros.core.states.settings import FIXED_DEFAULT, ReconstructionSettings

#: Default tolerances of the session's nominal values for the h range (user-overridable).
DEFAULT_TOLERANCES = {
    "rider.mass": 1.0,                 # kg
    "rider.inertia_pitch": "10%",
    "euc.body_mass": 1.0,              # kg
    "euc.body_inertia": "10%",
    "euc.wheel_mass": 0.2,             # kg
    "euc.wheel_inertia": "10%",
    "euc.wheel_radius": 0.002,         # m
    "euc.h0": 0.005,                   # m
    "euc.l0": 0.005,                   # m
    "rider.segments.com_offset": 0.01,  # m, every segment's CoM offset along its body z axis
}


#: Budget keys -> (EucParams field, session path) for the values that enter the model only.
_PARAM_KEYS = {
    "rider.mass": "m", "rider.inertia_pitch": "J", "euc.body_mass": "m0", "euc.body_inertia": "J0",
    "euc.wheel_mass": "mw", "euc.wheel_inertia": "Jw", "euc.wheel_radius": "R", "euc.h0": "h0", "euc.l0": "l0",
}


def parse_tolerances(items: Sequence[str] | None) -> dict:
    """``["rider.mass=2", "euc.body_inertia=20%"]`` over :data:`DEFAULT_TOLERANCES`; ConfigError naming the key."""
    tol = dict(DEFAULT_TOLERANCES)
    for item in items or ():
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in DEFAULT_TOLERANCES:
            raise ConfigError(f"expected KEY=VALUE with KEY one of {', '.join(DEFAULT_TOLERANCES)}, got {item!r}",
                              key="--tolerance")
        v = value.strip()
        try:
            num = float(v[:-1]) if v.endswith("%") else float(v)
        except ValueError:
            raise ConfigError(f"{key}: {v!r} is not a number (give e.g. {key}=0.01 or {key}=5%)",
                              key="--tolerance") from None
        if not num >= 0:
            raise ConfigError(f"{key}: a tolerance must be >= 0, got {v}", key="--tolerance")
        tol[key] = f"{num:g}%" if v.endswith("%") else num
    return tol


def _nominal(session, key: str) -> float:
    if key.startswith("rider.") and key != "rider.segments.com_offset":
        return float(getattr(session.rider, key.split(".", 1)[1]))
    if key.startswith("euc."):
        return float(getattr(session.euc, key.split(".", 1)[1]))
    return float("nan")


def _absolute(tol, nominal: float) -> float:
    return abs(nominal) * float(tol[:-1]) / 100.0 if isinstance(tol, str) else float(tol)


def budget(series_list, states, session, params, h: float, *, reconstruction: ReconstructionSettings = FIXED_DEFAULT,
           tolerances: dict | None = None) -> dict:
    """dh/dp for every nominal value and the h range for the tolerances.

    Model-only values are perturbed in :class:`EucParams` on the reconstructed states; the segment CoM
    offsets enter the geometry, so the recordings are reconstructed again with every offset moved
    along its body's z axis.

    Returns
    -------
    dict
        ``{"sensitivity": {key: {"dh_dp": [m per unit], "unit", "tolerance", "dh_m"}}, "h_range_m": [lo, hi]}``
    """
    tolerances = tolerances or dict(DEFAULT_TOLERANCES)

    def h_of(st, p):
        return fit_h(st, p, models=("3dof",)).pooled["3dof"].h_m

    out = {}
    total = 0.0
    for key, fld in _PARAM_KEYS.items():
        nominal = float(getattr(params, fld))
        step = max(abs(nominal) * 0.02, 1e-4)
        hp = h_of(states, dataclasses.replace(params, **{fld: nominal + step}))
        hm = h_of(states, dataclasses.replace(params, **{fld: nominal - step}))
        d = (hp - hm) / (2 * step)
        tol = _absolute(tolerances[key], nominal)
        unit = {"m": "kg", "m0": "kg", "mw": "kg", "J": "kg m^2", "J0": "kg m^2", "Jw": "kg m^2"}.get(fld, "m")
        out[key] = {"dh_dp": json_float(d), "unit": f"m per {unit}", "nominal": nominal, "tolerance": tol,
                    "dh_m": json_float(abs(d) * tol)}
        total += abs(d) * tol if np.isfinite(d) else 0.0
    step = 0.01
    segs = session.rider.segments

    def shifted(dz):
        new = {name: dataclasses.replace(seg, com_offset=tuple(np.add(seg.com_offset, (0.0, 0.0, dz))))
               for name, seg in segs.items()}
        return dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments=new))

    hs = []
    for dz in (step, -step):
        s2 = shifted(dz)
        # each recording's states made when the fit asks for them and reduced to their coefficients at once
        hs.append(pooled_h_of_states((reconstruction.reconstruct(s, s2, lean=True) for s in series_list), params))
        release_free_memory()         # the shifted reconstruction's temporaries
    d = (hs[0] - hs[1]) / (2 * step)
    tol = _absolute(tolerances["rider.segments.com_offset"], 0.0)
    out["rider.segments.com_offset"] = {"dh_dp": json_float(d), "unit": "m per m (all offsets along the body z axis)",
                                        "nominal": None, "tolerance": tol, "dh_m": json_float(abs(d) * tol)}
    total += abs(d) * tol if np.isfinite(d) else 0.0
    return {"sensitivity": out, "h_range_m": [json_float(h - total), json_float(h + total)], "tolerances": {
        k: v for k, v in tolerances.items()}}
