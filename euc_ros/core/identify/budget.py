"""Uncertainty budget of h over the session's nominal values no residual can check.

Masses, inertias, l0, h0, the segment CoM offsets and the segments' mass fractions enter the model as
given; h moves with them while the residual stays at its floor. :func:`budget` measures dh/dp for each
(re-identifying with the value perturbed), the h range that stated tolerances imply
(:data:`DEFAULT_TOLERANCES`, overridden by :func:`parse_tolerances`), and each value's standard
uncertainty of h; :func:`with_session` puts them into the data's interval.

How the terms combine (GUM, JCGM 100:2008): a tolerance ``a`` is read as the half-width of a rectangular
distribution of the nominal value (the value is somewhere within ``+-a``, nothing more is known), so its
standard uncertainty is ``a / sqrt(3)`` (GUM 4.3.7), and h's share is ``u_i = |dh/dp_i| a_i / sqrt(3)``
(a Type B evaluation). The values are independent: ``u_B^2 = sum u_i^2`` (GUM 5.1.2). The data's own
interval (bootstrap over blocks, with the noise and sliding terms: the Type A part) has half-widths
``d_lo``, ``d_hi``; the combined 95 % interval has half-widths ``sqrt(d^2 + (k u_B)^2)`` with ``k = 1.96``
on each side, so an asymmetric data interval stays asymmetric, and an end the data do not bound stays
unbounded.

Examples
--------
>>> u = standard_uncertainty(0.5, 0.01)            # 0.5 m of h per m of offset, +-1 cm
>>> round(u * 1e3, 2)
2.89
>>> [round(v, 4) for v in widened((0.60, 0.59, 0.62), 0.01)]   # h, data interval, u_B
[0.578, 0.628]
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

#: Default tolerances of the session's nominal values (half-widths; user-overridable). The segment values are
#: of the order of the differences between anthropometric tables and of their subjects' scatter
#: (de Leva 1996; Dumas, Cheze & Verriest 2007; Durkin & Dowling 2003): a segment CoM located to about 2-3 %
#: of its length (1 cm on a 0.4 m thigh), the share of the body mass in the legs to about 2 % of the
#: body mass, and each segment's fraction to about 10 % of itself (the tables differ by that per segment; as a
#: rectangular half-width 0.17, relative). Masses: a scale's tolerance with clothes and helmet; inertias: 10 %
#: (a table or a pendulum test); the EUC's lengths: a tape measure's millimetres.
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
    "rider.segments.mass_fraction": 0.02,  # share of the body mass moved between the legs and the upper body
    "rider.segments.mass_fraction_each": 0.17,  # each segment's fraction, relative (rectangular: u = 10 %)
}

#: The lower limbs (thighs, shanks and feet) of the recording contract's rigid bodies; the rest with mass is
#: the upper body (head, trunk, arms).
LOWER_LIMBS = ("TR", "TL", "LR", "LL")

#: Coverage factor of the combined interval (95 %, normal).
K95 = 1.96


#: Budget keys -> (EucParams field, session path) for the values that enter the model only.
_PARAM_KEYS = {
    "rider.mass": "m", "rider.inertia_pitch": "J", "euc.body_mass": "m0", "euc.body_inertia": "J0",
    "euc.wheel_mass": "mw", "euc.wheel_inertia": "Jw", "euc.wheel_radius": "R", "euc.h0": "h0", "euc.l0": "l0",
}


def parse_tolerances(items: Sequence[str] | None) -> dict:
    """Tolerances ``["rider.mass=2", "euc.body_inertia=20%"]`` over :data:`DEFAULT_TOLERANCES`.

    Parameters
    ----------
    items : sequence of str or None
        ``KEY=VALUE`` items (the ``--tolerance`` option): an absolute half-width in the key's unit, or a
        percentage of the nominal value (not for the ``rider.segments.*`` keys).

    Returns
    -------
    dict
        :data:`DEFAULT_TOLERANCES` with the items' values (numbers, or ``"<p>%"`` strings).

    Raises
    ------
    ConfigError
        Naming ``--tolerance``: an item without ``=``, an unknown key, a value that is not a number, a
        percentage for a segment key, or a negative value.
    """
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
        if key.startswith("rider.segments.") and v.endswith("%"):
            unit = ("m" if "offset" in key else "relative to each fraction, e.g. 0.17" if key.endswith("_each")
                    else "share of the body mass")
            raise ConfigError(f"{key}: give the tolerance as a number ({unit}), not {v}", key="--tolerance")
        if not num >= 0:
            raise ConfigError(f"{key}: a tolerance must be >= 0, got {v}", key="--tolerance")
        tol[key] = f"{num:g}%" if v.endswith("%") else num
    return tol


def standard_uncertainty(dh_dp: float | None, tolerance: float) -> float:
    """The standard uncertainty of h from one nominal value: ``|dh/dp| a / sqrt(3)`` (rectangular, GUM 4.3.7) [m].

    Parameters
    ----------
    dh_dp : float or None
        Sensitivity of h to the value [m per unit]; None or NaN when it could not be measured (counts 0).
    tolerance : float
        Half-width ``a`` of the value's tolerance [its unit].

    Returns
    -------
    float
    """
    if dh_dp is None or not np.isfinite(dh_dp):
        return 0.0
    return float(abs(float(dh_dp)) * float(tolerance) / np.sqrt(3.0))


def widened(h_and_interval: tuple[float, float | None, float | None], u_b: float) -> tuple:
    """The data's 95 % interval combined with a Type B standard uncertainty ``u_b``, side by side.

    Parameters
    ----------
    h_and_interval : tuple
        ``(h, low, high)`` [m]; an end None or not finite is unbounded and stays so.
    u_b : float
        Combined standard uncertainty of the session's values [m].

    Returns
    -------
    tuple of (float or None)
        ``(low, high)`` [m].
    """
    h, lo, hi = h_and_interval
    k = K95 * float(u_b)

    def side(end, sign):
        if end is None or not np.isfinite(end):
            return None
        return float(h + sign * np.hypot(abs(h - end), k))

    return side(lo, -1.0), side(hi, 1.0)


def with_session(out: dict, b: dict, h: float, h_bounds: tuple[float, float]) -> None:
    """The headline interval ``out["h_ci95_m"]`` widened by the session's Type B terms of budget ``b``, in place.

    The data's own interval moves to ``out["uncertainty"]["h_ci95_data_m"]``; ``b`` gains ``u_session_m``,
    ``u_data_m`` (the data interval's half-width / 1.96, the mean of both sides; None when unbounded), each
    term's ``u_m`` and ``share`` of the combined variance, and ``dominant`` (the term with the largest share).
    The result stays inside ``h_bounds``.

    Parameters
    ----------
    out : dict
        The JSON keys of the headline h (``h_ci95_m``, ``uncertainty``).
    b : dict
        :func:`budget`'s result.
    h : float
        The headline h [m].
    h_bounds : tuple of float
        The admissible range of h [m].
    """
    lo, hi = out["h_ci95_m"]
    terms = {k: v.get("u_m", 0.0) or 0.0 for k, v in b["sensitivity"].items()}
    u_b = float(np.sqrt(sum(u * u for u in terms.values())))
    ends = [v for v in (lo, hi) if v is not None]
    u_a = float(np.mean([abs(h - v) for v in ends]) / K95) if len(ends) == 2 else None
    new_lo, new_hi = widened((h, lo, hi), u_b)
    out["uncertainty"]["h_ci95_data_m"] = [lo, hi]
    out["h_ci95_m"] = [None if new_lo is None else max(new_lo, h_bounds[0]),
                       None if new_hi is None else min(new_hi, h_bounds[1])]
    total = u_b * u_b + (u_a * u_a if u_a is not None else 0.0)
    shares = {k: (u * u / total if total > 0 else 0.0) for k, u in terms.items()}
    if u_a is not None:
        shares["data"] = u_a * u_a / total if total > 0 else 0.0
    for k, v in b["sensitivity"].items():
        v["share"] = json_float(shares[k])
    b.update(u_session_m=json_float(u_b), u_data_m=json_float(u_a), method=(
        "GUM: tolerances as rectangular half-widths (u = |dh/dp| a / sqrt 3), independent, combined in quadrature "
        "with the data's interval side by side (k = 1.96)"),
        dominant="data" if u_a is None else max(shares, key=shares.get))


def _nominal(session, key: str) -> float:
    if key.startswith("rider.") and not key.startswith("rider.segments."):
        return float(getattr(session.rider, key.split(".", 1)[1]))
    if key.startswith("euc."):
        return float(getattr(session.euc, key.split(".", 1)[1]))
    return float("nan")


def absolute_tolerance(tol, nominal: float) -> float:
    """A tolerance in the value's unit: ``"5%"`` of ``nominal``, or the number itself.

    Parameters
    ----------
    tol : float or str
        The tolerance: a number, or a percentage string such as ``"10%"``.
    nominal : float
        The nominal value a percentage is of.

    Returns
    -------
    float
    """
    return abs(nominal) * float(tol[:-1]) / 100.0 if isinstance(tol, str) else float(tol)


def budget(series_list, states, session, params, h: float, *, reconstruction: ReconstructionSettings = FIXED_DEFAULT,
           tolerances: dict | None = None) -> dict:
    """dh/dp for every nominal value and the h range for the tolerances.

    Model-only values are perturbed in :class:`EucParams` on the reconstructed states; the segment CoM
    offsets enter the geometry, so the recordings are reconstructed again with every offset moved
    along its body's z axis.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings (reconstructed again for the segment values).
    states : sequence of RiderStates
        Their reconstructed states (for the model-only values).
    session : Session
        The session the nominal values come from.
    params : EucParams
        Its model parameters.
    h : float
        The identified h [m] (the centre of ``h_range_m``).
    reconstruction : ReconstructionSettings
        How the recordings are reconstructed again.
    tolerances : dict, optional
        Half-widths by key (default :data:`DEFAULT_TOLERANCES`; :func:`parse_tolerances`).

    Returns
    -------
    dict
        ``{"sensitivity": {key: {"dh_dp": [m per unit], "unit", "nominal", "tolerance", "dh_m", "u_m"}},
        "h_range_m": [lo, hi], "tolerances": {key: tolerance}}``
    """
    tolerances = {**DEFAULT_TOLERANCES, **(tolerances or {})}     # a partial dict: the rest at their defaults

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
        tol = absolute_tolerance(tolerances[key], nominal)
        unit = {"m": "kg", "m0": "kg", "mw": "kg", "J": "kg m^2", "J0": "kg m^2", "Jw": "kg m^2"}.get(fld, "m")
        out[key] = {"dh_dp": json_float(d), "unit": f"m per {unit}", "nominal": nominal, "tolerance": tol,
                    "dh_m": json_float(abs(d) * tol), "u_m": json_float(standard_uncertainty(d, tol))}
        total += abs(d) * tol if np.isfinite(d) else 0.0
    for key, (d, unit) in _segment_sensitivities(series_list, session, params, reconstruction).items():
        tol = absolute_tolerance(tolerances[key], 0.0)
        out[key] = {"dh_dp": json_float(d), "unit": unit, "nominal": None, "tolerance": tol,
                    "dh_m": json_float(abs(d) * tol), "u_m": json_float(standard_uncertainty(d, tol))}
        total += abs(d) * tol if np.isfinite(d) else 0.0
    return {"sensitivity": out, "h_range_m": [json_float(h - total), json_float(h + total)], "tolerances": {
        k: v for k, v in tolerances.items()}}


def _segment_sensitivities(series_list, session, params, reconstruction: ReconstructionSettings) -> dict:
    """dh/dp of the segment values, which enter the geometry: the recordings reconstructed again per step.

    Two directions, each by central differences: every CoM offset moved along its body's z axis together
    (``rider.segments.com_offset``, m per m), and a share of the body mass moved from the lower limbs
    (:data:`LOWER_LIMBS`) to the upper body, each side's fractions scaled alike so that they still sum to 1
    (``rider.segments.mass_fraction``, m per unit of body mass; NaN when one side has no mass).

    Returns
    -------
    dict
        ``{key: (dh_dp, unit)}``.
    """
    segs = session.rider.segments

    def with_segments(new):
        return dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments=new))

    def offset(step):
        return with_segments({name: dataclasses.replace(seg, com_offset=tuple(np.add(seg.com_offset, (0.0, 0.0, step))))
                              for name, seg in segs.items()})

    lower = sum(seg.mass_fraction for name, seg in segs.items() if name in LOWER_LIMBS)
    upper = sum(seg.mass_fraction for name, seg in segs.items() if name not in LOWER_LIMBS)

    def fraction(step):
        return with_segments({name: dataclasses.replace(seg, mass_fraction=seg.mass_fraction * (
            1.0 - step / lower if name in LOWER_LIMBS else 1.0 + step / upper)) for name, seg in segs.items()})

    out = {"rider.segments.com_offset": (0.01, offset, "m per m (all offsets along the body z axis)")}
    if lower > 0 and upper > 0:
        out["rider.segments.mass_fraction"] = (0.01, fraction, "m per unit of body mass (legs to upper body)")
    result = {}
    for key, (step, moved, unit) in out.items():
        hs = []
        for s in (step, -step):
            s2 = moved(s)
            # each recording's states made when the fit asks for them and reduced to their coefficients at once
            hs.append(pooled_h_of_states((reconstruction.reconstruct(r, s2, lean=True) for r in series_list), params))
            release_free_memory()         # the moved reconstruction's temporaries
        result[key] = ((hs[0] - hs[1]) / (2 * step), unit)
    if "rider.segments.mass_fraction" not in result:
        result["rider.segments.mass_fraction"] = (float("nan"), "m per unit of body mass (legs to upper body)")
    return result
