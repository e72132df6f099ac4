"""The report of ``euc-ros campaign open-world``: the per-family Markdown table, its figure and the report.

The rides, their rows and the per-family table's numbers come from the core (:mod:`euc_ros.core.openworld`:
:mod:`~euc_ros.core.openworld.study` makes and traces the rides, :mod:`~euc_ros.core.openworld.judge`
judges them and makes the table); this module only formats them: :func:`table_lines` (the table with its
goals marked), :func:`figure` (three panels, matplotlib imported when drawn) and :func:`markdown` (the
report, how it was run and every ride).
"""
from __future__ import annotations

import json
import math
import platform
from pathlib import Path

import numpy as np

from euc_ros.core.openworld.judge import CLEAN_MM, EXPLAINED_RATIO, GOALS, median
from euc_ros.core.openworld.study import ARTEFACT_DEG_PER_MM, ARTEFACT_MM, NOISE_POS_MM, NOISE_ROT_DEG
from euc_ros.core.worldsim import forces as F
from euc_ros.core.worldsim.open_world_seeds import FAMILIES


def _fmt(v, spec: str = ".0f", unit: str = "") -> str:
    if isinstance(v, (int, float)) and math.isinf(v):
        return "unbounded"
    return "-" if v is None else f"{v:{spec}}{unit}"


def _mark(ok) -> str:
    return "" if ok is None else (" ✓" if ok else " ✗")


def table_lines(summ: dict) -> list[str]:
    """The per-family Markdown table (goals marked ✓ met, ✗ missed)."""
    lines = ["| family | n (failed) | explained | explained, < 3 mm (n) | false name | no name | `none` | "
             "coverage 95 % | median width [mm] | median width, <= 5 mm (n) | median width, clean [mm] (n) | "
             "floor [N m] | ratio design / measured | before / predicted |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for fam, s in summ["families"].items():
        g = s["goals_met"]
        lines.append(
            f"| {fam} | {s['n']} ({s['failed']}) | "
            f"{_fmt(s['explained_pct'], '.0f', ' %')}{_mark(g.get('explained'))} | "
            + (f"{_fmt(s.get('explained_low_sliding_pct'), '.0f', ' %')}{_mark(g.get('explained_low_sliding'))} "
               f"({s.get('n_low_sliding', '-')}) | " if fam != "none" else "- | ") +
            f"{_fmt(s['false_name_pct'], '.0f', ' %')}{_mark(g['false_name'])} | "
            f"{_fmt(s['no_name_pct'], '.0f', ' %')}{_mark(g.get('controls_no_name'))} | "
            f"{_fmt(s.get('none_pct'), '.0f', ' %')}{_mark(g.get('controls_none'))} | "
            f"{_fmt(s['coverage_pct'], '.0f', ' %')}{_mark(g['coverage'])} | {_fmt(s['width_median_mm'], '.1f')} | "
            f"{_fmt(s.get('width_usual_median_mm'), '.1f')}{_mark(g.get('width_usual'))} ({s.get('n_usual', '-')}) | "
            f"{_fmt(s['width_clean_median_mm'], '.1f')}{_mark(g['width_clean'])} ({s['n_clean']}) | "
            f"{_fmt(s['floor_median_nm'], '.2f')} | {_fmt(s['ratio_design_median'], '.2f')} / "
            f"{_fmt(s['ratio_measured_median'], '.2f')} | {_fmt(s['before_vs_predicted_median'], '.2f')} |")
    return lines


def figure(rows: list[dict], summ: dict, path) -> Path:
    """Three panels: per-family percentages, measured against design ratio, h error against artefact level.

    The per-family percentages; the measured against the design ratio; the h error in units of the interval's
    half width against the artefact level.
    """
    from euc_ros.cli.figures import pyplot, save_figure

    plt = pyplot()
    fams = list(summ["families"])
    fig, ax = plt.subplots(1, 3, figsize=(13.0, 3.8))
    keys = (("explained_pct", "explained"), ("false_name_pct", "false name"), ("coverage_pct", "coverage"))
    x = np.arange(len(fams))
    for k, (key, label) in enumerate(keys):
        vals = [summ["families"][f][key] if summ["families"][f][key] is not None else 0.0 for f in fams]
        ax[0].bar(x + (k - 1) * 0.27, vals, 0.27, label=label)
    ax[0].axhline(GOALS["coverage_pct_min"], color="k", lw=0.8, ls="--")
    ax[0].axhline(GOALS["false_name_pct_max"], color="k", lw=0.8, ls=":")
    ax[0].set_xticks(x, fams, rotation=30, fontsize=8)
    ax[0].set_ylabel("% of rides")
    ax[0].set_ylim(0, 105)
    ax[0].legend(fontsize=7, loc="upper right")
    ok = [r for r in rows if r["status"] == "ok"]
    colors = {f: plt.get_cmap("tab10")(i) for i, f in enumerate(FAMILIES)}
    for f in fams:
        rr = [r for r in ok if r["family"] == f and r.get("ratio_design") is not None]
        if rr:
            ax[1].scatter([r["ratio_design"] for r in rr], [r["ratio_measured"] for r in rr], s=14, color=colors[f],
                          label=f)
    ax[1].plot([0, 1], [0, 1], "k-", lw=0.6)
    ax[1].axhline(EXPLAINED_RATIO, color="k", lw=0.8, ls="--")
    ax[1].set_xlim(0, 1)
    ax[1].set_ylim(0, 1.1)
    ax[1].set_xlabel("design ratio floor / sqrt(floor² + effect²)")
    ax[1].set_ylabel("measured RMSE after / before")
    ax[1].legend(fontsize=7)
    for f in fams:
        rr = [r for r in ok if r["family"] == f and r.get("width_mm") and r.get("h_after_lo_m") is not None
              and r.get("h_after_hi_m") is not None]
        if rr:
            z = np.clip([(r["h_after_m"] - r["h_true_m"]) / (0.5 * (r["h_after_hi_m"] - r["h_after_lo_m"]))
                         for r in rr], -4.0, 4.0)
            ax[2].scatter([r["artefact_mm"] for r in rr], z, s=14, color=colors[f], label=f)
    ax[2].axhline(1.0, color="k", lw=0.8, ls="--")
    ax[2].axhline(-1.0, color="k", lw=0.8, ls="--")
    ax[2].set_ylim(-4.2, 4.2)
    ax[2].set_xlabel("soft-tissue sliding [mm]")
    ax[2].set_ylabel("h error / interval half-width")
    ax[2].set_title("h error in half-widths (clipped at 4)", fontsize=9)
    ax[1].set_title("calibration and outcome", fontsize=9)
    ax[0].set_title("per family (goals dashed)", fontsize=9)
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, Path(path))


def markdown(summ: dict, rows: list[dict], meta: dict, figure_path: Path | None, md_path: Path) -> str:
    """The report: how it was run, the table with its goals, the outcomes by family, the failures."""
    import os

    ok = [r for r in rows if r["status"] == "ok"]
    secs = [r["seconds"] for r in rows if r.get("seconds") is not None]
    lines = ["# Open-world study: hidden random laws in rides of the independent generator", "",
             "Each ride hides a random force law of one family in a ride of `euc_ros.core.worldsim` (its own "
             "dynamics, controllers and writer) and runs `euc-ros residual` on it. The laws, their points of "
             "application and the amplitude calibration are in `euc_ros/core/worldsim/forces.py`, the study in "
             "`euc_ros/core/openworld/` (rides in `study.py`, judging in `judge.py`; this report in "
             "`euc_ros/cli/open_world.py`); the seeds were fixed in `euc_ros/core/worldsim/open_world_seeds.py` "
             "before any run.", "",
             *([f"**{meta['note']}**", ""] if meta.get("note") else []),
             "## How it was run", "",
             f"* command: `{meta['command']}`",
             f"* seeds: `{meta['seed_set']}` set, the first {meta['per_family']} per family "
             f"({meta['seed_range']}); families {', '.join(meta['families'])}",
             f"* rides: {meta['duration_s']:g} s at {meta['rate_hz']:g} Hz, integrator rtol {meta['rtol']:g}; "
             f"pose noise {NOISE_POS_MM} mm and {NOISE_ROT_DEG} deg; soft-tissue sliding uniform {ARTEFACT_MM[0]:g}-"
             f"{ARTEFACT_MM[1]:g} mm ({ARTEFACT_DEG_PER_MM} deg per mm); design ratio uniform "
             f"{F.RATIO_RANGE[0]}-{F.RATIO_RANGE[1]}",
             f"* date {meta['date']}, machine {meta['machine']}, {meta['where']}; "
             f"{len(rows)} rides in {meta['wall_s'] / 60:.1f} min, "
             f"median {median(secs) or 0:.1f} s per ride and process", "",
             "## Results", "", *table_lines(summ), "",
             f"*explained*: held-out RMSE after / before <= {EXPLAINED_RATIO} by a right library name "
             "(`right_library_names`) or by discovered terms"
             + (" of the hidden family (the discovered rows' `family`)" if summ.get("family_key") else
                " (the discovered rows carried no `family`: any discovered term counts)")
             + ". *false name*: a library effect that is not a right name for the ride's law (controls: any). "
             "*no name*: no library effect named. *`none`*: controls whose effect is `none`. *coverage*: the true "
             "h inside `h_after_ci95_m`, an unbounded end counted as a miss. *<= 5 mm*, *< 3 mm*: rides with at "
             f"most that much sliding. *clean*: sliding below {CLEAN_MM:g} mm. *floor*: the held-out RMSE of the "
             "same ride without the law. "
             "*ratio design / measured*: medians of floor / sqrt(floor² + effect²) (the effect's RMS along the "
             "analysed ride) and of the analysis' RMSE after / before. *before / predicted*: median of the "
             "measured RMSE before over sqrt(floor² + effect²), the calibration's check. Goals: false name <= "
             f"{GOALS['false_name_pct_max']:g} %, coverage >= {GOALS['coverage_pct_min']:g} %, median width <= "
             f"{GOALS['width_usual_mm_max']:g} mm at <= 5 mm of sliding and <= {GOALS['width_clean_mm_max']:g} mm "
             f"clean, explained >= {GOALS['explained_pct_min']:g} % (>= {GOALS['explained_low_sliding_pct_min']:g} % "
             f"under 3 mm), controls naming nothing >= {GOALS['controls_no_name_pct_min']:g} % and saying `none` >= "
             f"{GOALS['controls_none_pct_min']:g} % (✓ met, ✗ missed).", ""]
    if figure_path is not None:
        rel = os.path.relpath(figure_path, md_path.parent)
        lines += [f"![open-world study]({rel})", ""]
    lines += ["## Outcomes by family", "", "| family | the analysis' effect (rides) |", "| --- | --- |"]
    for fam, s in summ["families"].items():
        eff = ", ".join(f"`{k}` {v}" for k, v in sorted(s["effects"].items(), key=lambda kv: -kv[1]))
        lines.append(f"| {fam} | {eff or '-'} |")
    lines.append("")
    if summ["failures"]:
        lines += ["## Failures", ""] + [f"* {f['task']}: {f['error']}" for f in summ["failures"]] + [""]
    lines += ["## Rides", "", "| ride | point | artefact [mm] | design ratio | effect | after / before | "
              "h - true [mm] | width [mm] |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in ok:
        pt = json.loads(r["point"])["kind"] if r.get("point") else "-"
        dh = 1e3 * (r["h_after_m"] - r["h_true_m"])
        lines.append(f"| {r['task']} | {pt} | {r['artefact_mm']:.1f} | {_fmt(r['ratio_design'], '.2f')} | "
                     f"`{r['effect']}` | {r['ratio_measured']:.2f} | {dh:+.1f} | {_fmt(r['width_mm'], '.1f')} |")
    return "\n".join(lines) + "\n"


def machine() -> str:
    """The machine in one line for the report: architecture, CPU count, Python and OS.

    Returns
    -------
    str
    """
    import os

    return f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, {platform.system()}"
