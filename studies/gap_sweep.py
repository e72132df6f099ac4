#!/usr/bin/env python3
"""Gap sweep of the README: samples used and h against single-frame flicker and vrpn-style message loss.

Usage: python studies/gap_sweep.py [--runs 3] [--seed 5]

The same simulated ride (deceleration, seed 5) with, per body independently, single-frame flicker
(a Motive CSV whose cells go blank) or message loss (one PoseStamped topic per body, written to a
real MCAP bag and read back) at 0-5 %. Prints a Markdown table: samples used (of the gap-free
count), frames with a body bridged, and the pooled 3-DoF h.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from euc_ros.core.identify.fit import fit_h  # noqa: E402
from euc_ros.core.io.bags import read_mocap_bag, write_mocap_bag  # noqa: E402
from euc_ros.core.model.terms import EucParams  # noqa: E402
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride  # noqa: E402
from euc_ros.core.states.kinematics import reconstruct_states  # noqa: E402


def damaged(series, kind: str, rate: float, rng):
    lost = rng.random(series.tracked.shape) < rate
    if kind == "flicker":
        lost[:, 1:] &= ~lost[:, :-1]
    tracked = series.tracked & ~lost
    return dataclasses.replace(series, tracked=tracked, position=np.where(tracked[..., None], series.position, np.nan))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=5)
    a = ap.parse_args()
    ride = simulate_ride(RideConfig(runs=a.runs, seed=a.seed))
    params = EucParams.from_session(ride.session)
    print("| damage | rate | samples used | frames bridged | h [m] |")
    print("|:---|---:|---:|---:|---:|")
    base = None
    for kind in ("flicker", "vrpn loss"):
        for rate in (0.0, 0.01, 0.02, 0.03, 0.05):
            if kind == "vrpn loss" and rate == 0.0:
                continue
            rng = np.random.default_rng(1)
            states = []
            with tempfile.TemporaryDirectory() as tmp:
                for k, run in enumerate(ride.runs):
                    s = damaged(run.mocap, kind, rate, rng)
                    if kind == "vrpn loss":
                        write_mocap_bag(s, Path(tmp) / f"b{k}", frame_topic=None)
                        s = read_mocap_bag(Path(tmp) / f"b{k}")
                    states.append(reconstruct_states(s, ride.session))
            used = sum(int(st.valid.sum()) for st in states)
            bridged = sum(st.meta["bridged_frames"] for st in states)
            frames = sum(st.n for st in states)
            h = fit_h(states, params, models=("3dof",)).pooled["3dof"].h_m
            base = used if base is None else base
            print(f"| {kind if rate else 'none'} | {100 * rate:.0f} % | {used} of {base} | {bridged} of {frames} "
                  f"| {h:.4f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
