"""h and the RMSE of M_d1 - M_d2 under soft-tissue artefacts, per CoG method.

The rides come from the ride simulator without noise (:func:`simulate_clean`); the artefacts are added
afterwards by the independent generator (:mod:`euc_ros.core.ridesim.artefacts`), so one simulation
serves every amplitude. Each case reconstructs the states with both CoG methods
(:func:`~euc_ros.core.states.kinematics.reconstruct_states`, ``cog_method``; the skeleton model estimated
once from all runs of the ride, as ``euc-ros identify --cog-method skeleton`` does) and identifies h
as the identify command does (:func:`~euc_ros.core.identify.fit.fit_h`, pooled 3-DoF).

The orientation slides with the pivot: ``ROT_DEG_PER_MM`` degrees per millimetre of pivot sliding
(3 mm -> 0.6 deg, 15 mm -> 3 deg: a marker cluster of ~0.3 m whose markers slide differentially).
Every rider body also gets the coloured pose noise of :class:`SoftTissueArtefacts` (0.2 mm, 0.5 deg,
first-order spectrum with a 10 Hz corner), E gets only that noise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.identify.cog_height import uncertainty_of_h
from euc_ros.core.identify.fit import fit_h
from euc_ros.core.identify.options import IntervalOptions
from euc_ros.core.model.terms import EucParams
from euc_ros.core.ridesim.artefacts import SoftTissueArtefacts, apply_artefacts, perturb_session
from euc_ros.core.ridesim.mocap_synth import MocapNoise
from euc_ros.core.ridesim.simulate import DEFAULT_H_M, RideConfig, simulate_ride
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, reconstruct_states
from euc_ros.core.states.settings import ReconstructionSettings
from euc_ros.core.states.skeleton import COG_METHODS, SkeletonModel

#: Sliding amplitudes of the campaign [m] (RMS of the 3-D pivot sliding of every rider body).
AMPLITUDES_M = (0.0, 0.003, 0.005, 0.010, 0.015)
#: Orientation sliding per pivot sliding [deg/mm].
ROT_DEG_PER_MM = 0.2
#: Corner of the coloured pose noise [Hz].
NOISE_CORNER_HZ = 10.0
#: The paper's real rides: RMSE of M_d1 - M_d2 [N m].
PAPER_RMSE_NM = 4.76
#: Goals: |h error| [m] at a sliding amplitude [m].
GOALS_M = {0.003: 0.010, 0.010: 0.020}


@dataclass(frozen=True)
class Case:
    """One artefact setting (per run of a ride, drawn from ``seed``)."""

    slide_m: float
    offsets: bool = False            # analyse with CoM offsets perturbed by 1-3 cm
    swaps: int = 0
    flips: int = 0
    accel_share: float = 0.5         # share of the sliding variance that follows the acceleration

    @property
    def label(self) -> str:
        s = f"{1e3 * self.slide_m:g} mm"
        if self.offsets:
            s += " + offsets 1-3 cm"
        if self.swaps or self.flips:
            s += f" + {self.swaps} swaps, {self.flips} flips per run"
        if self.slide_m:
            s += f", {100 * self.accel_share:g} % with the acceleration"
        return s

    def artefacts(self) -> SoftTissueArtefacts:
        return SoftTissueArtefacts(slide_rms_m=self.slide_m, slide_rot_rms_deg=ROT_DEG_PER_MM * 1e3 * self.slide_m,
                                   noise_corner_hz=NOISE_CORNER_HZ, swaps=self.swaps, flips=self.flips,
                                   accel_share=self.accel_share)


def simulate_clean(seed: int, maneuvers=("acceleration", "deceleration"), runs: int = 3, duration_s: float = 7.0):
    """Noise-free rides (true h = 0.61 m): ``(session, [clean MocapSeries...])``."""
    series, session = [], None
    for k, man in enumerate(maneuvers):
        ride = simulate_ride(RideConfig(maneuver=man, runs=runs, seed=seed + 1000 * k, duration_s=duration_s,
                                        noise=MocapNoise.none()))
        session = ride.session
        series += [r.mocap_clean for r in ride.runs]
    return session, series


def recorded(cleans, case: Case, seed: int):
    """The recordings of ``case`` (artefacts drawn per run from ``seed``) and all injected events."""
    rng = np.random.default_rng([seed, 13])
    out, events = [], []
    for s in cleans:
        r, ev = apply_artefacts(s, case.artefacts(), rng)
        out.append(r)
        events.append(ev)
    return out, events


def analysis_session(session, case: Case, seed: int):
    """The session the analysis is given (offsets perturbed for ``case.offsets``)."""
    return perturb_session(session, np.random.default_rng([seed, 29])) if case.offsets else session


def reconstruct(series, session, cog_method: str, *, window_s: float = DEFAULT_WINDOW_S,
                polyorder: int = DEFAULT_SG_POLYORDER):
    """States of every recording; the skeleton model estimated once from all of them."""
    model = SkeletonModel.estimate(list(series), session) if cog_method == "skeleton" else None
    return [reconstruct_states(s, session, window_s=window_s, polyorder=polyorder, cog_method=cog_method,
                               skeleton=model) for s in series]


def evaluate(cleans, session, case: Case, seed: int, methods=COG_METHODS, *, with_interval: bool = False) -> list[dict]:
    """h error, RMSE and fault counts of ``case`` for each CoG method (one row per method)."""
    series, events = recorded(cleans, case, seed)
    s_an = analysis_session(session, case, seed)
    params = EucParams.from_session(s_an)
    rows = []
    for method in methods:
        states = reconstruct(series, s_an, method)
        fit = fit_h(states, params, models=("3dof",)).pooled["3dof"]
        row = {"case": case.label, "slide_mm": 1e3 * case.slide_m, "offsets": case.offsets, "swaps": case.swaps,
               "flips": case.flips, "seed": seed, "method": method, "h_m": fit.h_m,
               "h_err_mm": 1e3 * (fit.h_m - DEFAULT_H_M), "rmse_nm": fit.rmse_nm,
               "faults_excluded": int(sum(st.meta.get("cog_faults", 0) for st in states)),
               "fault_frames_injected": int(sum(e.stop - e.start for ev in events for e in ev))}
        if with_interval:
            row.update(h_interval(states, series, s_an, params, fit, method))
        rows.append(row)
    return rows


def residual_verdict(cleans, session, case: Case, seed: int, method: str) -> dict:
    """Run the residual analysis (as ``euc-ros residual`` does) on an artefact-only ride."""
    from euc_ros.core.residual.analysis import analyze
    from euc_ros.core.residual.noise import make_noise_floor

    series, _ = recorded(cleans, case, seed)
    s_an = analysis_session(session, case, seed)
    params = EucParams.from_session(s_an)
    states = reconstruct(series, s_an, method)
    out = analyze(states, params, noise_floor_of=make_noise_floor(series, states, s_an, params)).to_json()
    return {"case": case.label, "seed": seed, "method": method, "effect": out["effect"],
            "effect_parameters": out.get("effect_parameters", {}), "discovered": len(out.get("discovered", [])),
            "residual_significant": out.get("residual_significant"), "rmse_before_nm": out["rmse_before_nm"],
            "noise_floor_nm": out.get("noise_floor_nm")}


def names_library_effect(effect: str) -> bool:
    """True when the analysis' ``effect`` names an effect of the candidate library."""
    return any(e not in ("none", "discovered", "unexplained") for e in effect.split("+"))


def h_interval(states, series, session, params, fit, method: str) -> dict:
    """Identify's 95 % interval of h, computed as ``euc-ros identify`` reports it (block bootstrap, white-noise
    and sliding SIMEX biases)."""
    for st, s in zip(states, series):
        st.meta["series"] = s
    unc = uncertainty_of_h(states, session, params, fit,
                           reconstruction=ReconstructionSettings(window_s=DEFAULT_WINDOW_S,
                                                                 polyorder=DEFAULT_SG_POLYORDER, cog_method=method),
                           options=IntervalOptions(h_bounds=(0.1, 1.2), tolerances={}, with_budget=False))
    lo, hi = unc["h_ci95_m"]
    u = unc["uncertainty"]
    inside = lo is not None and hi is not None and lo <= DEFAULT_H_M <= hi
    return {"h_ci95_m": [lo, hi], "ci_contains_truth": bool(inside),
            "identifiable": unc["identifiable"], "identifiability_reason": unc["identifiability_reason"],
            "eiv_bias_m": u.get("eiv_bias_m"), "sliding_bias_m": u.get("sliding_bias_m"),
            "sliding_rms_max_m": u.get("sliding_rms_max_m")}

def summarize(rows: list[dict]) -> list[dict]:
    """Mean and spread over seeds per (case, method): h error mean, max |h error|, RMSE mean."""
    out = []
    keys = []
    for r in rows:
        k = (r["case"], r["method"])
        if k not in keys:
            keys.append(k)
    for case, method in keys:
        rs = [r for r in rows if r["case"] == case and r["method"] == method]
        he = np.array([r["h_err_mm"] for r in rs])
        d = {"case": case, "method": method, "seeds": len(rs), "slide_mm": rs[0]["slide_mm"],
             "h_err_mean_mm": float(he.mean()), "h_err_max_abs_mm": float(np.abs(he).max()),
             "rmse_mean_nm": float(np.mean([r["rmse_nm"] for r in rs])),
             "faults_excluded": int(sum(r["faults_excluded"] for r in rs)),
             "fault_frames_injected": int(sum(r["fault_frames_injected"] for r in rs))}
        if "ci_contains_truth" in rs[0]:
            d["ci_contains_truth"] = f"{sum(r['ci_contains_truth'] for r in rs)}/{len(rs)}"
        out.append(d)
    return out

