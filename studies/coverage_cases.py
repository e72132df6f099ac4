"""Coverage study of the h interval: does the 95 % interval contain the true h?

Over seeds and maneuvers of the ride simulator (whose truth shares no code with the analysis), each
case is written as files and identified by ``euc-ros identify`` with its defaults (:func:`euc_ros.identify`:
the filter chosen from the data, the headline h corrected for the pose noise and the filter's distortion,
with its interval) and classified: identifiable and covered, identifiable and missed, or declared not
identifiable (with its reason). ``studies/coverage_study.py`` prints the README table;
``test/unit/core/identify/test_uncertainty.py`` runs a small version.
"""
from __future__ import annotations

from pathlib import Path
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
    """One simulated ride identified as ``euc-ros identify`` does with its defaults; judges the headline h.

    The ride is written as the simulator's files (:func:`~euc_ros.core.ridesim.writers.write_ride`) and
    identified by :func:`euc_ros.identify`: the filter chosen from the data, the interval with the
    errors-in-variables and sliding biases, the filter's distortion and the budget, and the headline h
    corrected for the pose noise and the filter's distortion.

    Parameters
    ----------
    maneuver : str
        The simulator's maneuver (``deceleration``, ``acceleration``, ``constant_speed``, ``figure_eight``).
    runs : int
        Number of runs.
    duration_s : float or None
        Duration of each run [s] (None: the maneuver's default).
    seed : int
        The simulator's seed.
    h_true : float
        The true h [m].

    Returns
    -------
    dict
        ``h_m`` and ``ci95_m`` (the JSON's headline ``h_m`` and ``h_ci95_m``; NaN for an end the data do
        not bound), ``identifiable``, ``reason``, ``covered`` (the interval contains ``h_true``),
        ``eiv_bias_m`` (SIMEX's bias at the chosen filter), ``h_at_chosen_filter_m`` and
        ``h_at_chosen_filter_ci95_m`` (the uncorrected fit, from ``diagnostics``; the headline's when there
        is none).
    """
    import tempfile
    import warnings

    import euc_ros
    from euc_ros.api import NotIdentifiableWarning
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    ride = simulate_ride(RideConfig(maneuver=maneuver, runs=runs, seed=seed, h=h_true, duration_s=duration_s))
    with tempfile.TemporaryDirectory(prefix="euc_coverage_") as folder:
        written = write_ride(ride, folder)
        recordings = [str(p) for p in written if p.suffix == ".csv" and p.parent == Path(folder)]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotIdentifiableWarning)
            res = euc_ros.identify(str(Path(folder) / "session.yaml"), recordings)
    lo, hi = res.interval
    data = res.data
    diag = data.get("diagnostics") or {"h_at_chosen_filter_m": data["h_m"],
                                       "h_at_chosen_filter_ci95_m": data.get("h_ci95_m")}
    return {"h_m": res.h, "ci95_m": (lo, hi), "identifiable": res.identifiable, "reason": res.reason,
            "covered": bool(lo <= h_true <= hi), "eiv_bias_m": (data.get("uncertainty") or {}).get("eiv_bias_m"),
            "h_at_chosen_filter_m": diag["h_at_chosen_filter_m"],
            "h_at_chosen_filter_ci95_m": diag["h_at_chosen_filter_ci95_m"]}


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
