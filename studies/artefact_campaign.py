#!/usr/bin/env python3
"""The h error and the RMSE of M_d1 - M_d2 against soft-tissue sliding, both CoG methods.

    .venv/bin/python studies/artefact_campaign.py [--seeds 11 23 37] [--out docs/figures/cog/campaign.json]
        [--residual] [--figure docs/figures/cog/segment_fit.png]

Per seed: 3 acceleration + 3 deceleration runs of 7 s (true h = 0.61 m) simulated once without noise,
then every artefact case applied by the independent generator and analysed with both CoG methods
(:mod:`studies.cog_artefacts`). ``--residual`` also runs the residual analysis on artefact-only
rides and records whether it names a library effect (it must not). Prints Markdown tables; writes all
rows as JSON. Not a test: it takes ~10 min per seed on one core (the residual analysis most of it).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from studies.cog_artefacts import (  # noqa: E402
    AMPLITUDES_M,
    GOALS_M,
    PAPER_RMSE_NM,
    Case,
    evaluate,
    names_library_effect,
    recorded,
    residual_verdict,
    simulate_clean,
    summarize,
)

CASES = ([Case(a, accel_share=0.0) for a in AMPLITUDES_M]
         + [Case(a) for a in AMPLITUDES_M if a > 0]
         + [Case(0.003, offsets=True), Case(0.010, offsets=True)]
         + [Case(0.010, swaps=2, flips=2)])
INTERVAL_CASES = {Case(0.003), Case(0.010), Case(0.003, accel_share=0.0), Case(0.010, accel_share=0.0)}
RESIDUAL_CASES = [Case(0.003, offsets=True), Case(0.010)]


def table(summary) -> str:
    lines = ["| case | CoG method | h error mean [mm] | max abs h error [mm] | RMSE of M_d1 - M_d2 [N m] "
             "| 95 % interval contains 0.61 m | body-frames excluded / injected |",
             "|---|---|---|---|---|---|---|"]
    for r in summary:
        lines.append(f"| {r['case']} | {r['method']} | {r['h_err_mean_mm']:+.1f} | {r['h_err_max_abs_mm']:.1f} | "
                     f"{r['rmse_mean_nm']:.2f} | {r.get('ci_contains_truth', '-')} | "
                     f"{r['faults_excluded'] if r['method'] == 'skeleton' else '-'} / {r['fault_frames_injected']} |")
    lines.append(f"| paper, real rides | per-segment | - | - | {PAPER_RMSE_NM:.2f} | - | - |")
    return "\n".join(lines)


def goals(summary) -> str:
    out = []
    for slide, goal in GOALS_M.items():
        for r in summary:
            if r["case"] in (Case(slide).label, Case(slide, accel_share=0.0).label):
                ok = r["h_err_max_abs_mm"] <= 1e3 * goal
                out.append(f"{r['case']}, {r['method']}: max |h error| {r['h_err_max_abs_mm']:.1f} mm vs goal "
                           f"{1e3 * goal:.0f} mm -> {'met' if ok else 'NOT met'}")
    return "\n".join(out)


def figure(cleans, session, path: Path, seed: int) -> None:
    """A thigh's pivot (measured, fitted, true) and the rider CoG's forward coordinate over 3 s."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from euc_ros.core.states.geometry import frame_geometry
    from euc_ros.core.states.skeleton import SkeletonModel, skeleton_cog

    case = Case(0.010, swaps=2, flips=2)
    series, events = recorded(cleans, case, seed)
    k = next((i for i, ev in enumerate(events) if any(e.body in ("TR", "TL") for e in ev)), 0)
    ev = next((e for e in events[k] if e.body in ("TR", "TL")), None)
    body = ev.body if ev is not None else "TR"
    s, c = series[k], cleans[k]
    model = SkeletonModel.estimate(series, session)
    out = skeleton_cog(s.position, s.quat, s.tracked, session, s.bodies, model)
    g_seg = frame_geometry(s.position, s.quat, s.tracked, session, s.bodies)["G"]
    g_true = frame_geometry(c.position, c.quat, c.tracked, session, c.bodies)["G"]
    i, j = s.bodies.index(body), model.bodies.index(body)
    mid = ev.start if ev is not None else s.n_frames // 2
    sl = slice(max(0, mid - 180), min(s.n_frames, mid + 180))
    t = s.t[sl]
    # positions relative to the wheel track's start, forward axis of the run
    fwd = c.position[s.bodies.index("E"), -1, :2] - c.position[s.bodies.index("E"), 0, :2]
    fwd = np.append(fwd / np.linalg.norm(fwd), 0.0)

    def along(x):
        return 1e3 * ((x - c.position[i, sl]) @ fwd)

    fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    ax[0].plot(t, along(s.position[i, sl]), label=f"{body} pivot measured", color="0.6")
    ax[0].plot(t, along(out["P_fit"][j, sl]), label=f"{body} pivot fitted (chain)", color="C0")
    ax[0].axhline(0.0, color="k", lw=0.8, label="true")
    ax[0].set_ylabel("forward error [mm]")
    ax[0].legend(loc="upper right", fontsize=8)
    dz = 1e3 * (s.position[i, sl, 2] - c.position[i, sl, 2])
    ax[1].plot(t, dz, color="0.6", label="measured")
    ax[1].plot(t, 1e3 * (out["P_fit"][j, sl, 2] - c.position[i, sl, 2]), color="C0", label="fitted")
    ax[1].axhline(0.0, color="k", lw=0.8)
    ax[1].set_ylabel("vertical error [mm]")
    if ev is not None:
        for a in ax:
            a.axvspan(s.t[ev.start], s.t[min(ev.stop, s.n_frames - 1)], color="C3", alpha=0.2)
        ax[0].set_title(f"{case.label}; shaded: {ev.kind} of {ev.body} (excluded, predicted by the chain)",
                        fontsize=9)
    ax[2].plot(t, 1e3 * ((g_seg[sl] - g_true[sl]) @ fwd), color="0.6", label="per-segment G")
    ax[2].plot(t, 1e3 * ((out["G"][sl] - g_true[sl]) @ fwd), color="C0", label="skeleton G")
    ax[2].set_ylabel("G forward error [mm]")
    ax[2].set_xlabel("t [s]")
    lim = 3 * np.nanstd(1e3 * ((g_seg[sl] - g_true[sl]) @ fwd)) + 5
    ax[2].set_ylim(-lim, lim)
    ax[2].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[11, 23, 37])
    ap.add_argument("--out", default="docs/figures/cog/campaign.json")
    ap.add_argument("--residual", action="store_true", help="also run the residual analysis on artefact-only rides")
    ap.add_argument("--residual-seeds", type=int, nargs="+", default=None)
    ap.add_argument("--figure", default=None, help="write the measured-vs-fitted figure (first seed)")
    args = ap.parse_args(argv)
    rows, verdicts = [], []
    t0 = time.time()
    for seed in args.seeds:
        session, cleans = simulate_clean(seed)
        if args.figure and seed == args.seeds[0]:
            figure(cleans, session, Path(args.figure), seed)
        for case in CASES:
            rows += evaluate(cleans, session, case, seed, with_interval=case in INTERVAL_CASES)
            print(f"[{time.time() - t0:6.0f} s] seed {seed} {case.label}: "
                  + ", ".join(f"{r['method']} h {r['h_m']:.3f} RMSE {r['rmse_nm']:.2f}" for r in rows[-2:]),
                  file=sys.stderr, flush=True)
        if args.residual and seed in (args.residual_seeds or args.seeds):
            for case in RESIDUAL_CASES:
                for method in ("segments", "skeleton"):
                    v = residual_verdict(cleans, session, case, seed, method)
                    v["names_library_effect"] = names_library_effect(v["effect"])
                    verdicts.append(v)
                    print(f"[{time.time() - t0:6.0f} s] residual seed {seed} {case.label} {method}: {v['effect']}",
                          file=sys.stderr, flush=True)
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps({"rows": rows, "summary": summarize(rows), "residual": verdicts},
                                             indent=1) + "\n")
    summary = summarize(rows)
    print(table(summary))
    print()
    print(goals(summary))
    if verdicts:
        print()
        print("| artefact-only ride | CoG method | seed | residual analysis: effect | library effect named |")
        print("|---|---|---|---|---|")
        for v in verdicts:
            print(f"| {v['case']} | {v['method']} | {v['seed']} | {v['effect']} | "
                  f"{'YES' if v['names_library_effect'] else 'no'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
