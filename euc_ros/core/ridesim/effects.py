"""Physical effects the EUC paper's model lacks, added to the ride simulator's truth or measurement.

Every effect is off by default and has named parameters (the names are fixed project-wide; the
residual analysis reports the same names). The generalized force each one adds to the planar model
(q = [x, gamma, phi]) is derived by virtual power in ``docs/ridesim.md``; the formulas are repeated in
the docstrings below. Notation: ``N = (m + m0 + mw) g`` static normal force, ``R`` true rolling
radius, ``G`` rider CoG, ``v_G`` its in-plane velocity, ``J_G = dG/dq``.

======================  =======================  ====================================================
effect                  parameters               change of the truth (generalized force dQ or other)
======================  =======================  ====================================================
rolling_resistance      c_rr [-]                 dQ = [-c_rr N tanh(x_dot / 0.05), 0, 0]
viscous_friction        c_v [N s/m]              dQ = [-c_v x_dot, 0, 0]
aero_drag               cda_m2 [m^2]             dQ = J_G^T F,  F = -0.5 rho cda |v_G| v_G, rho = 1.2
ground_slope            alpha_deg [deg]          in-plane gravity (-g sin(alpha) cos(psi), -g cos(alpha))
wheel_radius_error      delta_r_m [m]            true R = R_nom + delta (rolling, C height, J_w/R^2, M_d/R)
mocap_time_offset       dt_ms [ms]               measurement: rider segments at t - dt (E on time)
rider_mass_error        delta_m_kg [kg]          true m = m_nom + delta
rider_inertia_error     delta_j_kgm2 [kg m^2]    true J = J_nom + delta
tilt_gravity            gain [-]                 g_n -> g_n + gain (g_n cos(theta) - a_c sin(theta) - g_n)
time_varying_h          amplitude_m, period_s    h(t) = h + a sin(2 pi t / T) with its rheonomic terms
wheel_body_friction     c_wb [N m s/rad]         dQ = -c_wb (x_dot/R - gamma_dot) [1/R, -1, 0]
======================  =======================  ====================================================
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable, Mapping

from euc_ros.core.errors import ConfigError

#: Air density for aero_drag [kg/m^3] (still air).
AIR_DENSITY = 1.2
#: Speed scale of the tanh regularisation of sign(x_dot) in rolling_resistance [m/s].
ROLLING_SIGN_SPEED = 0.05


@dataclass(frozen=True)
class ParamDef:
    """One effect parameter: name (with unit suffix where not SI), default, unit, meaning.

    Parameters
    ----------
    name : str
        Parameter name.
    default : float
        Default value.
    unit : str
        Unit, as printed.
    description : str
        Meaning.
    """

    name: str
    default: float
    unit: str
    description: str


@dataclass(frozen=True)
class EffectDef:
    """An effect of the catalogue: name, parameters, where it acts and a one-line formula.

    Parameters
    ----------
    name : str
        Effect name.
    params : tuple of ParamDef
        Its parameters.
    acts_on : str
        ``"dynamics"``, ``"parameters"`` or ``"measurement"``.
    formula : str
        One-line formula.
    """

    name: str
    params: tuple[ParamDef, ...]
    acts_on: str  # "dynamics", "parameters", "measurement"
    formula: str


EFFECTS: dict[str, EffectDef] = {e.name: e for e in (
    EffectDef("rolling_resistance", (ParamDef("c_rr", 0.015, "-", "rolling-resistance coefficient"),),
              "dynamics", "dQ = [-c_rr N tanh(x_dot/0.05), 0, 0], N = (m+m0+mw) g"),
    EffectDef("viscous_friction", (ParamDef("c_v", 5.0, "N s/m", "viscous contact friction"),),
              "dynamics", "dQ = [-c_v x_dot, 0, 0]"),
    EffectDef("aero_drag", (ParamDef("cda_m2", 0.6, "m^2", "drag area C_d A of the rider"),),
              "dynamics", "dQ = J_G^T F, F = -0.5 rho cda |v_G| v_G at G, rho = 1.2 kg/m^3"),
    EffectDef("ground_slope", (ParamDef("alpha_deg", 2.0, "deg", "floor rises along world +x by alpha"),),
              "dynamics", "g_vec = (-g sin(alpha) cos(psi), -g cos(alpha)) in the longitudinal plane"),
    EffectDef("wheel_radius_error", (ParamDef("delta_r_m", 0.01, "m", "true rolling radius minus nominal"),),
              "parameters", "R_true = R + delta_r (C height, rolling, J_w/R^2, M_d/R)"),
    EffectDef("mocap_time_offset", (ParamDef("dt_ms", 20.0, "ms", "rider segments lag the EUC body by dt"),),
              "measurement", "rider segment poses at frame t are those of time t - dt"),
    EffectDef("rider_mass_error", (ParamDef("delta_m_kg", 10.0, "kg", "true rider mass minus nominal"),),
              "parameters", "m_true = m + delta_m"),
    EffectDef("rider_inertia_error",
              (ParamDef("delta_j_kgm2", 5.0, "kg m^2", "true rider pitch inertia minus nominal"),),
              "parameters", "J_true = J + delta_J"),
    EffectDef("tilt_gravity", (ParamDef("gain", 1.0, "-", "1 = physical projection of apparent gravity"),),
              "dynamics", "g_n -> g_n + gain (g_n cos(theta) - x_dot psi_dot sin(theta) - g_n)"),
    EffectDef("time_varying_h", (ParamDef("amplitude_m", 0.05, "m", "amplitude of h(t)"),
                                 ParamDef("period_s", 3.0, "s", "period of h(t)")),
              "dynamics", "h(t) = h + a sin(2 pi t / T) (rheonomic terms in the kinetics)"),
    EffectDef("wheel_body_friction", (ParamDef("c_wb", 0.2, "N m s/rad", "viscous friction wheel-body"),),
              "dynamics", "dQ = -c_wb (x_dot/R - gamma_dot) [1/R, -1, 0] (in span(b_d): invisible)"),
)}

#: Parameter name -> effect name (parameter names are unique across effects).
PARAM_OWNER: dict[str, str] = {p.name: e.name for e in EFFECTS.values() for p in e.params}


@dataclass(frozen=True)
class EffectSet:
    """The active effects and their parameters (name -> {param: value}), in the order given.

    Parameters
    ----------
    active : Mapping of str to Mapping of str to float
        Parameter values by effect.
    """

    active: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    def __contains__(self, name: str) -> bool:
        return name in self.active

    def get(self, effect: str, param: str) -> float:
        """A parameter of an active effect (0 for an inactive effect's parameter).

        Parameters
        ----------
        effect : str
            Effect name.
        param : str
            Parameter name.

        Returns
        -------
        float
            The value.
        """
        if effect not in self.active:
            return 0.0
        return float(self.active[effect][param])

    @property
    def names(self) -> tuple[str, ...]:
        """Active effect names in order."""
        return tuple(self.active)

    @property
    def label(self) -> str:
        """Effect names joined with '+' (``none`` when empty), as the residual report spells them."""
        return "+".join(self.active) if self.active else "none"

    def parameters(self) -> dict[str, float]:
        """All active parameters in one flat mapping (names are unique).

        Returns
        -------
        dict of str to float
            Values by parameter name.
        """
        return {k: float(v) for e in self.active.values() for k, v in e.items()}

    def to_list(self) -> list[dict]:
        """JSON-friendly list ``[{"effect": name, "parameters": {...}}, ...]``.

        Returns
        -------
        list of dict
            One entry per active effect.
        """
        return [{"effect": n, "parameters": {k: float(v) for k, v in p.items()}} for n, p in self.active.items()]


def make_effects(names: Iterable[str] = (), params: Mapping[str, float] | None = None) -> EffectSet:
    """Validate effect names and parameters and return an :class:`EffectSet`.

    Parameters
    ----------
    names : iterable of str
        Effect names (see :data:`EFFECTS`); duplicates are an error.
    params : mapping, optional
        Parameter values by parameter name; each must belong to one of ``names``. Missing ones take
        the defaults of :data:`EFFECTS`.

    Returns
    -------
    EffectSet
        The effects with every parameter's value.

    Raises
    ------
    ConfigError
        Unknown effect (key ``effect``), duplicate effect, unknown parameter or a parameter of an
        effect that is not active (key = the parameter name), non-finite values or values out of range.
    """
    params = dict(params or {})
    active: dict[str, dict[str, float]] = {}
    for n in names:
        if n not in EFFECTS:
            raise ConfigError(f"unknown effect {n!r} (known: {', '.join(EFFECTS)})", key="effect")
        if n in active:
            raise ConfigError(f"effect {n!r} given twice", key="effect")
        active[n] = {p.name: p.default for p in EFFECTS[n].params}
    for k, v in params.items():
        owner = PARAM_OWNER.get(k)
        if owner is None:
            raise ConfigError(f"unknown effect parameter (known: {', '.join(PARAM_OWNER)})", key=k)
        if owner not in active:
            raise ConfigError(f"parameter of effect {owner!r}, which is not active (add --effect {owner})", key=k)
        try:
            val = float(v)
        except (TypeError, ValueError):
            raise ConfigError(f"expected a number, got {v!r}", key=k) from None
        if not math.isfinite(val):
            raise ConfigError(f"expected a finite number, got {v!r}", key=k)
        active[owner][k] = val
    _check_ranges(active)
    return EffectSet(active)


def _check_ranges(active: Mapping[str, Mapping[str, float]]) -> None:
    nonneg = ("c_rr", "c_v", "cda_m2", "c_wb", "amplitude_m", "gain")
    for e, ps in active.items():
        for k, v in ps.items():
            if k in nonneg and v < 0:
                raise ConfigError(f"must be >= 0, got {v}", key=k)
        if e == "time_varying_h" and ps["period_s"] <= 0:
            raise ConfigError(f"must be > 0, got {ps['period_s']}", key="period_s")
        if e == "ground_slope" and not abs(ps["alpha_deg"]) < 30:
            raise ConfigError(f"|alpha_deg| must be < 30, got {ps['alpha_deg']}", key="alpha_deg")
        if e == "mocap_time_offset" and not abs(ps["dt_ms"]) <= 1000:
            raise ConfigError(f"|dt_ms| must be <= 1000, got {ps['dt_ms']}", key="dt_ms")


def parse_param_assignments(items: Iterable[str]) -> dict[str, float]:
    """Parse ``["alpha_deg=3", "c_rr=0.02"]`` (the CLI's ``--param``) into a mapping.

    Parameters
    ----------
    items : iterable of str
        ``NAME=VALUE`` items.

    Returns
    -------
    dict of str to float
        Values by name.

    Raises
    ------
    ConfigError
        For items without ``=`` or with a non-numeric value (key = the parameter name).
    """
    out: dict[str, float] = {}
    for it in items:
        if "=" not in it:
            raise ConfigError(f"expected NAME=VALUE, got {it!r}", key="param")
        k, v = (s.strip() for s in it.split("=", 1))
        try:
            out[k] = float(v)
        except ValueError:
            raise ConfigError(f"expected a number, got {v!r}", key=k) from None
    return out
