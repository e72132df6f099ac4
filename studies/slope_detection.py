#!/usr/bin/env python3
"""How fast does the live residual monitor flag a slope that starts mid-ride, per derivative filter?

Usage: python studies/slope_detection.py [--seeds 3 4 5 6 7] [--slopes 3 5] [--rmse-window 0.5]
       [--duration 8] [--ramp-x0 15] [--filters kalman split ...]

The ``split`` estimator (:mod:`euc_ros.core.states.split_lag`) has a 3.1 s memory: its first state comes
about 3.2 s into a ride (with 8 s rides, about 2 s before the ramp). Longer rides with a later ramp
(e.g. ``--duration 20 --ramp-x0 40``) give it more level riding before the onset.

A level-calibrated lab whose floor turns into a ramp at X = 15 m (5 cm blend), ridden at constant
speed; the chain of the nodes (RiderStateEstimator -> TorqueEstimator -> the monitor's consistency
rule) fed frame by frame. Per filter the monitor threshold is calibrated on a level ride (seed 11)
with :func:`euc_ros.core.online.alarm.rmse_threshold` (false-alarm probability 1e-8 per independent
window, as test/unit/core/online/test_low_lag_monitor.py). Reported per filter and slope: the threshold, the
largest sliding RMSE before the onset (false alarm if above the threshold) and the time from the
onset (the wheel reaching 5 % of the ramp's slope) to the first flag, in the newest frame's time
(the filter lag included). Prints a Markdown table.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from euc_ros.core.model.terms import EucParams  # noqa: E402
from euc_ros.core.online import monitoring as mon  # noqa: E402
from euc_ros.core.online.alarm import rmse_threshold  # noqa: E402
from euc_ros.core.online.estimators import RiderStateEstimator, TorqueEstimator, series_torques  # noqa: E402
from euc_ros.core.ridesim.floors import FloorProfile  # noqa: E402
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride  # noqa: E402
from euc_ros.core.states.settings import ReconstructionSettings  # noqa: E402

FILTERS = {
    "savgol 1.2 s (default, lag 0.6 s)": dict(estimator="savgol"),
    "savgol 0.6 s order 4, lag 0.2 s": dict(estimator="savgol", lag_s=0.2,
                                             settings=ReconstructionSettings(window_s=0.6, polyorder=4)),
    "kalman, lag 0.2 s": dict(estimator="kalman", lag_s=0.2),
    "kalman, lag 0.1 s (low-lag mode)": dict(estimator="kalman", lag_s=0.1),
    "split, lag 0.1 s": dict(estimator="split", lag_s=0.1),
}
ALPHA = 1e-8


def live(ride, settings, rmse_window_s):
    """Rows (newest frame time [s], sliding RMSE [N m], samples in the window, residual [N m])."""
    run = ride.runs[0]
    m = run.mocap
    dt = 1.0 / ride.session.rate_hz
    states = RiderStateEstimator(ride.session, dt, **settings)
    torque = TorqueEstimator(EucParams.from_session(ride.session, ride.config.h), dt, rmse_window_s=rmse_window_s)
    rows = []
    for i, _, out in series_torques(m, states, torque):
        rows.append((float(m.t[i]), out.rmse_window_nm, torque._rmse.count, out.residual_nm))
    return np.array(rows), int(round(rmse_window_s / dt))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[3, 4, 5, 6, 7])
    ap.add_argument("--slopes", type=float, nargs="+", default=[3.0, 5.0])
    ap.add_argument("--rmse-window", type=float, default=0.5, help="sliding RMSE window [s]")
    ap.add_argument("--duration", type=float, default=8.0, help="duration of every ride [s]")
    ap.add_argument("--ramp-x0", type=float, default=15.0, help="where the ramp starts [m]")
    ap.add_argument("--filters", nargs="+", default=None,
                    help="only the filters whose name contains one of these words (default: all)")
    a = ap.parse_args()
    global FILTERS
    if a.filters:
        FILTERS = {k: v for k, v in FILTERS.items() if any(w in k for w in a.filters)}
    level = simulate_ride(RideConfig(maneuver="constant_speed", runs=1, seed=11, duration_s=a.duration))
    thresholds = {}
    for name, settings in FILTERS.items():
        rows, n_full = live(level, settings, a.rmse_window)
        thresholds[name] = rmse_threshold(rows[:, 3], n_full, ALPHA)
    results = {(name, s): [] for name in FILTERS for s in a.slopes}
    for slope in a.slopes:
        floor = FloorProfile.of(("ramp_from", {"slope_deg": slope, "x0_m": a.ramp_x0, "width_m": 0.05}))
        for seed in a.seeds:
            ride = simulate_ride(RideConfig(maneuver="constant_speed", runs=1, seed=seed, floor=floor,
                                             duration_s=a.duration))
            run = ride.runs[0]
            onset = float(run.t[np.argmax(np.abs(run.signals["floor_slope"]) > 0.05 * np.radians(slope))])
            for name, settings in FILTERS.items():
                rows, n_full = live(ride, settings, a.rmse_window)
                thr = thresholds[name]
                levels = np.array([mon.consistency_health(v, thr).level for v in rows[:, 1]])
                full = rows[:, 2] >= n_full
                before = full & (rows[:, 0] < onset)
                hit = rows[(rows[:, 0] >= onset) & (levels >= mon.WARN), 0]
                results[(name, slope)].append((rows[before, 1].max(), hit[0] - onset if hit.size else np.nan))
    print(f"Rides of {a.duration:g} s, ramp from X = {a.ramp_x0:g} m. "
          f"Sliding RMSE window {a.rmse_window:g} s; seeds {a.seeds}; threshold calibrated on a level ride "
          f"(seed 11, false-alarm probability {ALPHA:g} per independent window).\n")
    print("| filter | threshold [N m] | slope [deg] | largest RMSE before onset [N m] | false alarms | "
          "delay to flag [s]: median (max) | missed |")
    print("|:---|---:|---:|---:|---:|---:|---:|")
    for (name, slope), res in results.items():
        pre = np.array([r[0] for r in res])
        delay = np.array([r[1] for r in res])
        ok = np.isfinite(delay)
        med = f"{np.median(delay[ok]):.2f} ({np.max(delay[ok]):.2f})" if ok.any() else "-"
        false = int((pre > thresholds[name]).sum())
        print(f"| {name} | {thresholds[name]:.2f} | {slope:g} | {pre.max():.2f} | {false} | {med} "
              f"| {int((~ok).sum())} of {len(res)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
