"""Statistical power of the residual analysis: detection rate per family over seeds, false discoveries.

Each trial simulates 3 runs of 7 s (two accelerations, one deceleration; the paper's pose noise) with
one library effect at a magnitude that cuts the held-out RMSE by 25-40 % (``POWER_MAGNITUDES``), runs the
full analysis (all candidates, discovery, noise floor) and records whether the family is named, any
absent library effect is named, and the cut. Per seed it prints the block length and the truth's p-value
of the first selection step (raw and family-wise adjusted), to see what limits.

``--fdr`` measures the false discoveries on no-effect rides as a calibration curve: every ride is simulated
once and analysed at every level of ``--alphas``; the rate of rides with a library effect named, with its
Clopper-Pearson 95 % interval, against alpha (the figure ``--figure``). The decision is checked to be
monotone in alpha (a ride that names something at one level names something at every larger one).

Usage:
  .venv/bin/python studies/residual_power.py --seeds 10 --null-seeds 0 [--json OUT]
  .venv/bin/python studies/residual_power.py --seeds 0 --fdr --null-seeds 100 --figure docs/figures/residual/fdr_calibration.png
  .venv/bin/python studies/residual_power.py --calibrate          # the cut of each family's own model
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the repository: euc_ros and studies

from studies.campaign import POWER_MAGNITUDES, family_cut, null_calibration_trial, power_trial  # noqa: E402


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Exact binomial interval of a rate k / n."""
    a = 1.0 - level
    lo = 0.0 if k == 0 else float(stats.beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(stats.beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def fdr_figure(path: str, alphas, named, n, min_adj, other=None) -> None:
    """Rate of rides with a library effect named against alpha (95 % intervals; ``other``: rides reported as
    discovered or unexplained), and the empirical CDF of the first selection step's smallest family-wise
    p-value over the rides."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 4.2))
    rates = np.array(named) / n
    ci = np.array([clopper_pearson(k, n) for k in named])
    ax[0].errorbar(alphas, rates, yerr=[rates - ci[:, 0], ci[:, 1] - rates], fmt="o", capsize=4,
                   label=f"library effect named ({n} no-effect rides, 95 % interval)")
    if other is not None:
        r2 = np.array(other) / n
        ci2 = np.array([clopper_pearson(k, n) for k in other])
        ax[0].errorbar(np.array(alphas) * 1.03, r2, yerr=[r2 - ci2[:, 0], ci2[:, 1] - r2], fmt="s", capsize=4,
                       color="tab:orange", label="discovered or unexplained")
    a = np.linspace(0, max(alphas) * 1.05, 50)
    ax[0].plot(a, a, "k--", lw=1, label="rate = alpha")
    ax[0].set_xlabel("alpha (family-wise level of each selection step)")
    ax[0].set_ylabel("false-discovery rate (rides)")
    ax[0].set_title("whole analysis, per alpha")
    ax[0].legend(fontsize=8)
    q = np.sort(np.asarray(min_adj, float))
    ax[1].step(q, np.arange(1, q.size + 1) / q.size, where="post", label="smallest adjusted p of step 1")
    ax[1].plot([0, 1], [0, 1], "k--", lw=1, label="uniform")
    ax[1].set_xlim(0, 1)
    ax[1].set_ylim(0, 1)
    ax[1].set_xlabel("p")
    ax[1].set_ylabel("fraction of rides with p at or below")
    ax[1].set_title("selection test alone (no gain/admissibility filter)")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10, help="trials per family")
    parser.add_argument("--null-seeds", type=int, default=30, help="no-effect trials")
    parser.add_argument("--first-seed", type=int, default=100)
    parser.add_argument("--null-first-seed", type=int, default=200)
    parser.add_argument("--families", nargs="*", default=list(POWER_MAGNITUDES))
    parser.add_argument("--calibrate", action="store_true", help="only measure each family's own RMSE cut")
    parser.add_argument("--fdr", action="store_true", help="no-effect rides at every level of --alphas")
    parser.add_argument("--alphas", type=float, nargs="*", default=[0.01, 0.05, 0.1, 0.2])
    parser.add_argument("--figure", help="with --fdr: write the calibration figure here")
    parser.add_argument("--json", help="write every trial here")
    parser.add_argument("--replot", metavar="JSON", help="with --figure: redraw the --fdr figure from a --json of --fdr")
    args = parser.parse_args()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    cpu0 = time.process_time()
    if args.replot:
        rows = json.load(open(args.replot))
        alphas = sorted({r["alpha"] for r in rows})
        rides = sorted({r["seed"] for r in rows})
        at = {(r["seed"], r["alpha"]): r for r in rows}
        named = [sum(bool(at[s, a]["false_named"]) for s in rides) for a in alphas]
        other = [sum(bool(at[s, a]["discovered"] or at[s, a]["unexplained"]) for s in rides) for a in alphas]
        min_adj = [min(v["p_adjusted"] for v in at[s, alphas[0]]["first_step"].values()) for s in rides]
        fdr_figure(args.figure, alphas, named, len(rides), min_adj, other)
        return

    if args.calibrate:
        for fam in args.families:
            cuts = [family_cut(fam, s, POWER_MAGNITUDES[fam]) for s in seeds]
            print(f"{fam} {POWER_MAGNITUDES[fam]}: cut {np.mean(cuts):.2f} (min {np.min(cuts):.2f}, max {np.max(cuts):.2f})",
                  flush=True)
        return

    trials = []
    if args.seeds:
        print("| family (magnitude) | trials | named | named or tied | other effect named (untied) | "
              "RMSE cut (mean, range) | h after (median, worst) [m] |")
        print("|---|---|---|---|---|---|---|")
    for fam in args.families if args.seeds else []:
        rows = []
        for s in seeds:
            r = power_trial(fam, s)
            rows.append(r)
            print(f"  {fam} seed {r['seed']}: {r['effect']} (tied {','.join(r['ambiguous_with']) or '-'}) block "
                  f"{r['block_s']:.2f} s, step 1 p {r['p_truth']:.2g} adjusted {r['p_adjusted_truth']:.2g}, own cut "
                  f"{r['truth_cut_first_step']:.2f}; cut {r['cut']:.2f} h {r['h_after']:.3f}", file=sys.stderr, flush=True)
        trials += rows
        det = sum(r["detected"] for r in rows)
        det_t = sum(r["detected_or_tied"] for r in rows)
        wrong = [n for r in rows for n in r["false_named"]]
        cuts = np.array([r["cut"] for r in rows])
        hs = np.array([r["h_after"] for r in rows])
        mag = ", ".join(f"{k}={v:g}" for k, v in POWER_MAGNITUDES[fam].items())
        print(f"| {fam} ({mag}) | {len(rows)} | {det}/{len(rows)} | {det_t}/{len(rows)} | {len(wrong)}"
              f"{' (' + ', '.join(sorted(set(wrong))) + ')' if wrong else ''} | {cuts.mean():.2f} "
              f"({cuts.min():.2f}-{cuts.max():.2f}) | {np.median(hs):.3f}, {hs[np.argmax(np.abs(hs - 0.61))]:.3f} |",
              flush=True)
    null_seeds = range(args.null_first_seed, args.null_first_seed + args.null_seeds)
    if args.null_seeds and args.fdr:
        per_ride = []
        for s in null_seeds:
            rows = null_calibration_trial(s, tuple(args.alphas))
            per_ride.append(rows)
            trials += rows
            fs = rows[0]["first_step"]
            print(f"  none seed {s}: " + ", ".join(f"alpha {r['alpha']:g}: {r['effect']}" for r in rows)
                  + f"; block {rows[0]['block_s']:.2f} s; step 1 smallest adjusted p "
                  f"{min(v['p_adjusted'] for v in fs.values()):.2g}", file=sys.stderr, flush=True)
        n = len(per_ride)
        named = [sum(bool(rows[j]["false_named"]) for rows in per_ride) for j in range(len(args.alphas))]
        other = [sum(bool(rows[j]["discovered"] or rows[j]["unexplained"]) for rows in per_ride)
                 for j in range(len(args.alphas))]
        # monotone: a ride naming an effect at one level names one at every larger level
        flags = np.array([[bool(r["false_named"]) for r in rows] for rows in per_ride])
        order = np.argsort(args.alphas)
        monotone = bool(np.all(np.diff(flags[:, order].astype(int), axis=1) >= 0))
        min_adj = [min(v["p_adjusted"] for v in rows[0]["first_step"].values()) for rows in per_ride]
        print(f"\nno-effect rides {null_seeds.start}-{null_seeds.stop - 1}: decision monotone in alpha: {monotone}")
        print("| alpha | rides | library effect named | rate (95 % interval) | discovered or unexplained | "
              "step 1 smallest adjusted p < alpha |")
        print("|---|---|---|---|---|---|")
        for a, k, o in zip(args.alphas, named, other):
            lo, hi = clopper_pearson(k, n)
            print(f"| {a:g} | {n} | {k} | {k / n:.3f} ({lo:.3f}-{hi:.3f}) | {o} | "
                  f"{sum(p < a for p in min_adj)} |", flush=True)
        if args.figure:
            fdr_figure(args.figure, args.alphas, named, n, min_adj, other)
    elif args.null_seeds:
        rows = [power_trial(None, s) for s in null_seeds]
        trials += rows
        for r in rows:
            print(f"  none seed {r['seed']}: {r['effect']}", file=sys.stderr, flush=True)
        wrong = sum(bool(r["false_named"]) for r in rows)
        unexpl = sum(r["unexplained"] or "discovered" in r["effect"] for r in rows)
        print(f"| none (no effect) | {len(rows)} | - | - | {wrong} named; {unexpl} discovered/unexplained | "
              f"{np.mean([r['cut'] for r in rows]):.2f} | {np.median([r['h_after'] for r in rows]):.3f} |", flush=True)
    print(f"CPU time {time.process_time() - cpu0:.0f} s", file=sys.stderr)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(trials, fh, indent=1, default=float)


if __name__ == "__main__":
    main()
