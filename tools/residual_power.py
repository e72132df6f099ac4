"""Statistical power of the residual analysis: detection rate per family over seeds, false discoveries.

Each trial simulates 3 runs of 7 s (two accelerations, one deceleration; the paper's pose noise) with
one library effect at a magnitude that cuts the held-out RMSE by 25-40 % (``POWER_MAGNITUDES``), runs the
full analysis (all candidates, discovery, noise floor) and records whether the family is named, any
absent library effect is named, and the cut. No-effect rides measure the false discoveries.

Usage:
  .venv/bin/python tools/residual_power.py --seeds 10 --null-seeds 30 [--json OUT]
  .venv/bin/python tools/residual_power.py --calibrate          # the cut of each family's own model
"""
import argparse
import json
import sys

import numpy as np

from euc_ros.core.residual.campaign import POWER_MAGNITUDES, family_cut, power_trial

parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
parser.add_argument("--seeds", type=int, default=10, help="trials per family")
parser.add_argument("--null-seeds", type=int, default=30, help="no-effect trials")
parser.add_argument("--first-seed", type=int, default=100)
parser.add_argument("--families", nargs="*", default=list(POWER_MAGNITUDES))
parser.add_argument("--calibrate", action="store_true", help="only measure each family's own RMSE cut")
parser.add_argument("--json", help="write every trial here")
args = parser.parse_args()
seeds = range(args.first_seed, args.first_seed + args.seeds)

if args.calibrate:
    for fam in args.families:
        cuts = [family_cut(fam, s, POWER_MAGNITUDES[fam]) for s in seeds]
        print(f"{fam} {POWER_MAGNITUDES[fam]}: cut {np.mean(cuts):.2f} (min {np.min(cuts):.2f}, max {np.max(cuts):.2f})",
              flush=True)
    sys.exit(0)

trials = []
print("| family (magnitude) | trials | named | named or tied | other effect named (untied) | RMSE cut (mean, range) | "
      "h after (median, worst) [m] |")
print("|---|---|---|---|---|---|---|")
for fam in args.families:
    rows = [power_trial(fam, s) for s in seeds]
    trials += rows
    for r in rows:
        print(f"  {fam} seed {r['seed']}: {r['effect']} cut {r['cut']:.2f} h {r['h_after']:.3f}", file=sys.stderr,
              flush=True)
    det = sum(r["detected"] for r in rows)
    det_t = sum(r["detected_or_tied"] for r in rows)
    wrong = sum(bool(r["false_named"]) for r in rows)
    cuts = np.array([r["cut"] for r in rows])
    hs = np.array([r["h_after"] for r in rows])
    mag = ", ".join(f"{k}={v:g}" for k, v in POWER_MAGNITUDES[fam].items())
    print(f"| {fam} ({mag}) | {len(rows)} | {det}/{len(rows)} | {det_t}/{len(rows)} | {wrong} | {cuts.mean():.2f} "
          f"({cuts.min():.2f}-{cuts.max():.2f}) | {np.median(hs):.3f}, {hs[np.argmax(np.abs(hs - 0.61))]:.3f} |",
          flush=True)
if args.null_seeds:
    rows = [power_trial(None, s) for s in range(args.first_seed, args.first_seed + args.null_seeds)]
    trials += rows
    for r in rows:
        print(f"  none seed {r['seed']}: {r['effect']}", file=sys.stderr, flush=True)
    wrong = sum(bool(r["false_named"]) for r in rows)
    unexpl = sum(r["unexplained"] or "discovered" in r["effect"] for r in rows)
    print(f"| none (no effect) | {len(rows)} | - | - | {wrong} named; {unexpl} discovered/unexplained | "
          f"{np.mean([r['cut'] for r in rows]):.2f} | {np.median([r['h_after'] for r in rows]):.3f} |", flush=True)
if args.json:
    with open(args.json, "w") as fh:
        json.dump(trials, fh, indent=1, default=float)
