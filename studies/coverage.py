"""Coverage study of the h interval: does the 95 % interval contain the true h?

Over seeds and maneuvers of the ride simulator (whose truth shares no code with the analysis), each
case is identified exactly as ``euc-ros identify`` does (states, pooled 3-DoF fit, block bootstrap,
errors-in-variables bias) and classified: identifiable and covered, identifiable and missed, or
declared not identifiable (with its reason). ``studies/coverage_study.py`` prints the README table;
``test/unit/euc/test_uncertainty.py`` runs a small version.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

#: (label, maneuver, runs, duration_s) of the README study.
CASES = (
    ("deceleration, 3 x 7 s", "deceleration", 3, None),
    ("acceleration, 3 x 7 s", "acceleration", 3, None),
    ("constant speed, 3 runs", "constant_speed", 3, None),
    ("figure-eight, 1 run", "figure_eight", 1, None),
    ("deceleration, 2 s", "deceleration", 1, 2.0),
    ("deceleration, 25 min", "deceleration", 1, 1500.0),
)


def run_case(maneuver: str, runs: int, duration_s, seed: int, h_true: float = 0.61) -> dict:
    """One ride identified with its interval; returns h, interval, identifiable, reason, covered."""
    from euc_ros.core.identify.fit import coefficients_for, fit_h
    from euc_ros.core.identify.interval import interval, turning_rms
    from euc_ros.core.identify.simex import eiv_bias
    from euc_ros.core.model.terms import EucParams
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.states.kinematics import reconstruct_states

    ride = simulate_ride(RideConfig(maneuver=maneuver, runs=runs, seed=seed, h=h_true, duration_s=duration_s))
    params = EucParams.from_session(ride.session)
    series = [r.mocap for r in ride.runs]
    states = [reconstruct_states(s, ride.session) for s in series]
    fit = fit_h(states, params, models=("3dof",)).pooled["3dof"]
    bias, err = eiv_bias(series, ride.session, params, fit.h_m, window_s=states[0].window * states[0].dt,
                           polyorder=states[0].polyorder, with_error=True) if np.isfinite(fit.h_m) else (np.nan, np.nan)
    iv = interval(coefficients_for(states, params, "3dof", None), fit, window=states[0].window, dt=states[0].dt,
                    eiv_bias_m=bias, eiv_bias_err_m=err, turning_ms2=turning_rms(states))
    lo, hi = iv.ci95_m
    return {"h_m": fit.h_m, "ci95_m": (lo, hi), "identifiable": iv.identifiable, "reason": iv.reason,
            "covered": bool(lo <= h_true <= hi), "eiv_bias_m": bias}


def study(cases: Sequence = CASES, seeds: Sequence[int] = range(10), progress=None) -> list[dict]:
    """One row per case: counts of identifiable, covered among them, and the reasons given."""
    rows = []
    for label, maneuver, runs, duration in (progress(cases) if progress else cases):
        n_seeds = 2 if duration and duration > 600 else len(seeds)
        res = [run_case(maneuver, runs, duration, s) for s in list(seeds)[:n_seeds]]
        ident = [r for r in res if r["identifiable"]]
        reasons = sorted({r["reason"].split(":")[0].split(" (")[0] for r in res if not r["identifiable"]})
        rows.append({"case": label, "rides": len(res), "identifiable": len(ident),
                     "covered": sum(r["covered"] for r in ident),
                     "median_width_mm": float(np.median([1e3 * (r["ci95_m"][1] - r["ci95_m"][0]) for r in ident]))
                     if ident else float("nan"),
                     "median_h_m": float(np.median([r["h_m"] for r in res])),
                     "reasons": reasons})
    return rows
