"""How far a function of the lab position can explain a lab field on the open-world study's runs.

For lab-field rides of the study (lab design, tuning seeds), per ride, on the analysis' own folds and held-out
rows (``euc_ros.core.residual.analysis.prepare_setup``), the held-out RMSE left (after / before, h refitted in
each fold) by:

* the **law**: the hidden law's own contribution to the residual (through the states' filter) as one column;
* a **position family with the law's point**: cubic B-splines of the travel (knots every ``--knots`` m) times the
  law's multiplier, through the point's response and the states' filter, fitted on each fold's training rows
  with a small ridge; the columns the training rows do not reach are left out, so a held-out pass where no
  training pass went is predicted as no effect;
* the **analysis**: ``trace_residual``'s own after / before and verdict.

Usage::

    PYTHONPATH=$PWD python studies/lab_field_oracle.py --seeds 0 1 2 --cache /tmp/lab_rides

Rides are made once into ``--cache`` (about a minute each) and reused.
"""
from __future__ import annotations

import argparse
import json
import pickle
from pathlib import Path

import numpy as np

from euc_ros.core.model.extended import Model
from euc_ros.core.openworld.study import make_ride, seen_effect
from euc_ros.core.residual.analysis import prepare_setup
from euc_ros.core.residual.pipeline import trace_residual
from euc_ros.core.residual.splines import bspline_basis
from euc_ros.core.states.contexts import analysis_rate
from euc_ros.core.worldsim import forces as F
from euc_ros.core.worldsim.dynamics import PlantParams

RATE_HZ = 120.0
#: Ridge of the position family, relative to the training rows' count (columns scaled to unit RMS).
RIDGE = 0.01
#: Training rows a column must reach (its value above 5 % of its peak) to be fitted.
MIN_ROWS = 10


def ride(seed: int, cache: Path) -> dict:
    d = cache / f"lab_field_{seed}"
    meta = d / "meta.pkl"
    if meta.exists():
        return pickle.loads(meta.read_bytes())
    r = make_ride(seed, "lab_field", d, design="lab")
    keep = {k: r[k] for k in ("session", "csvs", "law")}
    meta.write_bytes(pickle.dumps(keep))
    return keep


def splines(x: np.ndarray, lo: float, hi: float, step: float) -> np.ndarray:
    """Cubic B-splines with knots every ``step`` from ``lo`` past ``hi`` (the analysis' clamped basis)."""
    inner = np.arange(lo, hi + step, step)
    return bspline_basis(x, lo, float(inner[-1]), 3, inner[1:-1])


def held_out_ratio(setup, rows, cols=None) -> float:
    """After / before over the folds: h alone, then h with ``cols`` (per recording, None: the law's column)."""
    before, after = [], []
    for fold in setup.folds:
        A, b, At, bt = [], [], [], []
        for i, (res, ok, hc, law) in enumerate(rows):
            C = law[:, None] if cols is None else cols[i]
            for mask, AA, bb in ((fold.train[i], A, b), (fold.test[i], At, bt)):
                k = np.asarray(mask, bool) & ok
                AA.append(np.c_[hc[k], C[k]])
                bb.append(res[k])
        A, b, At, bt = map(np.concatenate, (A, b, At, bt))
        c0 = np.linalg.lstsq(A[:, :1], -b, rcond=None)[0]
        reach = np.r_[True, (np.abs(A[:, 1:]) > 0.05 * np.abs(A[:, 1:]).max(axis=0)).sum(axis=0) >= MIN_ROWS]
        A, At = A[:, reach], At[:, reach]
        sc = np.sqrt((A ** 2).mean(axis=0))
        sc[sc == 0] = 1.0
        An = A / sc
        G = An.T @ An + RIDGE * len(b) * np.diag(np.r_[0.0, np.ones(An.shape[1] - 1)])
        c = np.linalg.solve(G, An.T @ -b) / sc
        before.append(bt + At[:, :1] @ c0)
        after.append(bt + At @ c)
    return float(np.sqrt(np.mean(np.concatenate(after) ** 2) / np.mean(np.concatenate(before) ** 2)))


def study(seed: int, cache: Path, knots_m: float) -> dict:
    r = ride(seed, cache)
    run = trace_residual(str(r["session"]), [str(c) for c in r["csvs"]])
    st = run.states
    setup = prepare_setup(st, run.params, n_folds=None, use_geometry=True,
                          analysis_rate_hz=analysis_rate(st[0].window * st[0].dt, st[0].polyorder),
                          say=lambda s: None)
    x = setup.base_fit.x
    x1 = x.copy()
    x1[0] += 1e-3
    law = r["law"]
    # the law with its shape replaced by 1: the point's response times the multiplier
    unit = F.ForceLaw(law.family, law.point, 1.0, {**law.params, "kind": "modes", "weights": [1.0],
                                                   "scales_m": [1e12], "phases": [np.pi / 2]})
    rows, travel = [], []
    for rec, csv in zip(setup.recs, r["csvs"]):
        tr = json.loads(Path(str(csv).replace(".csv", "_truth.json")).read_text())
        t = np.asarray(tr["t"])
        res, ok = Model().residual(rec, x)
        hc = (Model().residual(rec, x1)[0] - res) / 1e-3
        rows.append((res, ok, hc, np.interp(rec.ctx.t, t, seen_effect(np.asarray(tr["effect"]), RATE_HZ))))
        truth = {k: np.asarray(tr[k]) for k in ("x", "x_dot", "gamma", "gamma_dot", "phi", "phi_dot")}
        x0 = tr["integrator"]["x_offset_m"]
        travel.append((t, truth["x"] + x0, F.effect_on(unit, truth, t, PlantParams(**tr["plant"]), x0)))
    lo, hi = min(s.min() for _, s, _ in travel), max(s.max() for _, s, _ in travel)
    cols = []
    for (t, s, k), rec in zip(travel, setup.recs):
        B = splines(s, lo, hi, knots_m) * k[:, None]
        B = np.column_stack([seen_effect(B[:, j], RATE_HZ) for j in range(B.shape[1])])
        cols.append(np.column_stack([np.interp(rec.ctx.t, t, B[:, j]) for j in range(B.shape[1])]))
    d = run.data
    return {"seed": seed, "law": held_out_ratio(setup, rows), "position": held_out_ratio(setup, rows, cols),
            "analysis": d["rmse_after_nm"] / d["rmse_before_nm"], "effect": d["effect"],
            "ranges_m": [(round(float(s.min()), 1), round(float(s.max()), 1)) for _, s, _ in travel]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(12)), help="tuning seeds (default 0-11)")
    ap.add_argument("--cache", type=Path, required=True, help="folder of the rides, made once and reused")
    ap.add_argument("--knots", type=float, default=0.5, help="knot spacing of the position family [m]")
    args = ap.parse_args(argv)
    args.cache.mkdir(parents=True, exist_ok=True)
    print("| seed | law | position family | analysis | verdict | travel of each run [m] |")
    print("| --- | --- | --- | --- | --- | --- |")
    for seed in args.seeds:
        o = study(seed, args.cache, args.knots)
        print(f"| {seed} | {o['law']:.2f} | {o['position']:.2f} | {o['analysis']:.2f} | `{o['effect']}` | "
              f"{', '.join(f'{a}-{b}' for a, b in o['ranges_m'])} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
