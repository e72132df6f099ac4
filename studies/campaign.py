"""The undeclared-effect campaign: simulated rides with an effect the analysis is not told about.

Shared by the tests (``test/unit/core/residual/test_undeclared_effects.py``) and by
``studies/residual_campaign.py``, which writes the table of the README. Each scenario is a family at a
plausible magnitude.
"""
from __future__ import annotations

from dataclasses import dataclass

from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.analysis import analyze
from euc_ros.core.residual.selector import ForwardSelector
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, reconstruct_states

#: Acceleration and deceleration runs (3 + 3), alternating direction.
STRAIGHT = (("acceleration", 3), ("deceleration", 3))
#: Aggressive figure-eights: up to 29 deg of tilt and 4.8 m/s (the coupling grows with 1/cos(theta) - 1).
TURNS = (("figure_eight", 2),)
#: Speed and path scale of the figure-eights of :data:`TURNS`.
TURN_SPEED_SCALE, TURN_PATH_SCALE = 2.6, 2.0

#: True rider CoG height of the simulated rides [m].
H_TRUE = 0.61


@dataclass(frozen=True)
class Scenario:
    """One undeclared effect (or none) at one magnitude, on some maneuvers."""

    effects: dict
    maneuvers: tuple = STRAIGHT
    #: False for an effect the residual cannot show (wheel radius: confounded with h; found by geometry):
    #: instead of the RMSE ratio, h must come back to the truth.
    residual_visible: bool = True

    @property
    def name(self) -> str:
        """``effect-value`` (``none`` without effects)."""
        if not self.effects:
            return "none"
        return "+".join(f"{e}-" + "-".join(f"{v:g}" for v in p.values()) for e, p in self.effects.items())

    @property
    def truth_parameters(self) -> dict:
        """All true parameters by name."""
        return {k: v for p in self.effects.values() for k, v in p.items()}


SCENARIOS = [
    Scenario({"rolling_resistance": {"c_rr": 0.015}}),
    Scenario({"rolling_resistance": {"c_rr": 0.03}}),
    Scenario({"viscous_friction": {"c_v": 10.0}}),
    Scenario({"viscous_friction": {"c_v": 25.0}}),
    Scenario({"aero_drag": {"cda_m2": 0.5}}),
    Scenario({"aero_drag": {"cda_m2": 0.8}}),
    Scenario({"ground_slope": {"alpha_deg": 2.0}}),
    Scenario({"ground_slope": {"alpha_deg": 4.0}}),
    Scenario({"wheel_radius_error": {"delta_r_m": 0.02}}, residual_visible=False),
    Scenario({"wheel_radius_error": {"delta_r_m": 0.03}}, residual_visible=False),
    Scenario({"mocap_time_offset": {"dt_ms": 16.7}}),
    Scenario({"mocap_time_offset": {"dt_ms": 33.3}}),
    Scenario({"rider_mass_error": {"delta_m_kg": 20.0}}),
    Scenario({"rider_mass_error": {"delta_m_kg": 30.0}}),
    Scenario({"rider_inertia_error": {"delta_j_kgm2": 8.0}}),
    Scenario({"rider_inertia_error": {"delta_j_kgm2": 12.0}}),
    Scenario({"tilt_gravity": {"gain": 1.0}}, TURNS),
    Scenario({"tilt_gravity": {"gain": 2.0}}, TURNS),
    Scenario({"time_varying_h": {"amplitude_m": 0.08, "period_s": 4.0}}),
    Scenario({"time_varying_h": {"amplitude_m": 0.15, "period_s": 6.0}}),
]
#: Controls: no effect, the undetectable wheel-body friction, two effects at once, no effect in turns.
CONTROLS = [
    Scenario({}),
    Scenario({"wheel_body_friction": {"c_wb": 2.0}}),
    Scenario({"ground_slope": {"alpha_deg": 3.0}, "rolling_resistance": {"c_rr": 0.02}}),
    Scenario({}, TURNS),
]


def run_scenario(scenario: Scenario, seed: int = 11) -> dict:
    """Simulate the scenario's rides and run the residual analysis on them; returns its JSON."""
    from euc_ros.core.ridesim.effects import make_effects
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    states, session = [], None
    effects = make_effects(list(scenario.effects), scenario.truth_parameters)
    for i, (maneuver, runs) in enumerate(scenario.maneuvers):
        turns = maneuver == "figure_eight"
        res = simulate_ride(RideConfig(maneuver=maneuver, runs=runs, seed=seed + 101 * i, effects=effects,
                                       speed_scale=TURN_SPEED_SCALE if turns else 1.0,
                                       path_scale=TURN_PATH_SCALE if turns else 1.0))
        session = res.session
        states += [reconstruct_states(r.mocap, session, window_s=DEFAULT_WINDOW_S, polyorder=DEFAULT_SG_POLYORDER)
                   for r in res.runs]
    return analyze(states, EucParams.from_session(session)).to_json()


def verdict(scenario: Scenario, out: dict) -> tuple[bool, list[str]]:
    """Check the criteria: named (or ``none``), parameters within 25 %, RMSE after <= 0.6 before or at its
    noise floor.

    For an effect the residual cannot show (``residual_visible=False``) the last criterion is replaced
    by: h after within 1 cm of the truth and closer to it than before.
    """
    problems = []
    expected = "+".join(scenario.effects) if scenario.effects and "wheel_body_friction" not in scenario.effects \
        else "none"
    found = out["effect"].split("+")
    if scenario.maneuvers == TURNS:
        # the planar model leaves structure in aggressive 3-D turns (no effect: held-out structure the
        # discovery step sees, section "limits" of the README): reported as discovered/unexplained, never
        # as a library effect; only the named effects are compared
        found = [n for n in found if n not in ("discovered", "unexplained")] or ["none"]
    if sorted(found) != sorted(expected.split("+")):
        problems.append(f"found {out['effect']}, expected {expected}")
    if expected != "none":
        for name, value in scenario.truth_parameters.items():
            got = out["effect_parameters"].get(name)
            if got is None or abs(got - value) > 0.25 * abs(value):
                problems.append(f"{name} = {got}, true {value}")
        if scenario.residual_visible:
            # explained: cut to 0.6 of before, or down to its noise floor (an effect barely above the pose noise
            # cannot be cut further than the noise)
            if not (out["rmse_after_nm"] <= 0.6 * out["rmse_before_nm"] or out.get("residual_significant") is False):
                problems.append(f"RMSE after {out['rmse_after_nm']:.3f} > 0.6 x before {out['rmse_before_nm']:.3f} "
                                "and above its noise floor")
        elif not (abs(out["h_after_m"] - H_TRUE) < 0.01 and abs(out["h_after_m"] - H_TRUE) < abs(out["h_m"] - H_TRUE)):
            problems.append(f"h {out['h_m']:.3f} -> {out['h_after_m']:.3f}, true {H_TRUE}")
    return not problems, problems


# --------------------------------------------------------------------------------------------
# statistical power: detection rate over seeds at magnitudes that cut the held-out RMSE by 25-40 %
# --------------------------------------------------------------------------------------------
#: Three runs of 7 s (the issue's power set-up): two accelerations and one deceleration.
POWER_MANEUVERS = (("acceleration", 2), ("deceleration", 1))
#: Per family, a magnitude whose model cuts the held-out RMSE of these rides by about a third (25-40 %),
#: calibrated with ``studies/residual_power.py --calibrate`` (the cut measured over seeds is in the README).
POWER_MAGNITUDES = {
    "rolling_resistance": {"c_rr": 0.0065},
    "viscous_friction": {"c_v": 2.1},
    "aero_drag": {"cda_m2": 0.30},
    "ground_slope": {"alpha_deg": 0.11},
    "mocap_time_offset": {"dt_ms": 0.6},
    "rider_mass_error": {"delta_m_kg": 16.0},
    "rider_inertia_error": {"delta_j_kgm2": 6.5},
    "time_varying_h": {"amplitude_m": 0.06, "period_s": 4.0},
}


def simulate_states(effects: dict, seed: int, maneuvers=POWER_MANEUVERS, *, keep_series: bool = False):
    """Simulate rides with ``effects`` (name -> parameters) and reconstruct their states.

    Returns ``(states, session, series)`` (series: the recorded mocap of each run when ``keep_series``).
    """
    from euc_ros.core.ridesim.effects import make_effects
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    eff = make_effects(list(effects), {k: v for p in effects.values() for k, v in p.items()})
    states, series, session = [], [], None
    for i, (maneuver, runs) in enumerate(maneuvers):
        res = simulate_ride(RideConfig(maneuver=maneuver, runs=runs, seed=seed + 101 * i, effects=eff))
        session = res.session
        for r in res.runs:
            states.append(reconstruct_states(r.mocap, session, window_s=DEFAULT_WINDOW_S,
                                             polyorder=DEFAULT_SG_POLYORDER))
            series.append(r.mocap)
    return states, session, (series if keep_series else None)


def _trial_row(family: str | None, seed: int, out: dict) -> dict:
    """The outcome of one analysed power ride (see :func:`power_trial`)."""
    named = [n for n in out["effect"].split("+") if n not in ("none", "discovered", "unexplained")]
    tied = set(out.get("ambiguous_with", []))
    steps = [s for s in out["selection_steps"] if "tried" in s]
    first = {t["effect"]: t for t in steps[0]["tried"]} if steps else {}
    truth = first.get(family, {}) if family else {}
    return {"family": family or "none", "seed": seed, "effect": out["effect"],
            "detected": family is not None and family in named,
            "detected_or_tied": family is not None and (family in named or (bool(named) and family in tied)),
            "false_named": [n for n in named if n != family and family not in tied],
            "twin_named": [n for n in named if n != family and family in tied],
            "ambiguous_with": sorted(tied),
            "cut": 1.0 - out["rmse_after_nm"] / out["rmse_before_nm"],
            "rmse_before": out["rmse_before_nm"], "rmse_after": out["rmse_after_nm"], "h_after": out["h_after_m"],
            "h_range": out["h_range_m"], "parameters": out["effect_parameters"],
            "residual_significant": out["residual_significant"], "unexplained": out["unexplained"],
            "discovered": bool(out.get("discovered")), "block_s": out["held_out"]["block_s"],
            # the first selection step's test of every candidate against the base model
            "first_step": {k: {"p": v["p_value"], "p_adjusted": v.get("p_adjusted"), "rmse_after": v["rmse_after_nm"],
                               "admissible": "inadmissible" not in v} for k, v in first.items()},
            "p_truth": truth.get("p_value", float("nan")), "p_adjusted_truth": truth.get("p_adjusted", float("nan")),
            "truth_cut_first_step": (1.0 - truth["rmse_after_nm"] / out["rmse_before_nm"]) if truth else float("nan"),
            "alpha": out["significance_level"]}


def null_calibration_trial(seed: int, alphas=(0.01, 0.05, 0.1, 0.2)) -> list[dict]:
    """One no-effect ride of :data:`POWER_MANEUVERS`, simulated once and analysed (whole analysis: candidates,
    discovery, noise floor) at every level of ``alphas``: one :func:`power_trial`-like row per level."""
    from euc_ros.core.residual.noise import make_noise_floor

    states, session, series = simulate_states({}, seed, keep_series=True)
    params = EucParams.from_session(session)
    nf = make_noise_floor(series, states, session, params)
    return [_trial_row(None, seed, analyze(states, params, noise_floor_of=nf,
                                           selector=ForwardSelector(alpha=a)).to_json()) for a in alphas]


def power_trial(family: str | None, seed: int, magnitude: dict | None = None, *, noise_floor: bool = True) -> dict:
    """One ride of :data:`POWER_MANEUVERS` with ``family`` at its power magnitude (None: no effect), analysed.

    Returns ``{"family", "seed", "effect", "detected", "detected_or_tied", "false_named", "twin_named", "cut",
    ...}``: ``detected`` when the family is named (alone or with others), ``detected_or_tied`` also when a
    statistical twin is named with the family reported as tied to it (``ambiguous_with``), ``false_named``
    the absent library effects named without the truth among their ties, ``cut`` 1 - after/before of the
    analysis' result.
    """
    from euc_ros.core.residual.noise import make_noise_floor

    effects = {} if family is None else {family: dict(magnitude or POWER_MAGNITUDES[family])}
    states, session, series = simulate_states(effects, seed, keep_series=noise_floor)
    params = EucParams.from_session(session)
    nf = make_noise_floor(series, states, session, params) if noise_floor else None
    out = analyze(states, params, noise_floor_of=nf).to_json()
    return _trial_row(family, seed, out)


def family_cut(family: str, seed: int, magnitude: dict) -> float:
    """Held-out RMSE cut of the family's own model on a power ride (the analysis told only that candidate)."""
    from euc_ros.core.model.effects import make_candidates

    states, session, _ = simulate_states({family: magnitude}, seed)
    out = analyze(states, EucParams.from_session(session), candidates=make_candidates([family]),
                  discovery=False, selector=ForwardSelector(alpha=0.5, min_gain=0.0)).to_json()
    row = next(c for c in out["candidates"] if c["effect"] == family)
    return 1.0 - row["rmse_after_nm"] / out["rmse_before_nm"]
