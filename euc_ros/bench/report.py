"""Markdown rendering of a ``euc-ros bench`` result (the table the README shows)."""
from __future__ import annotations

import math

#: Under the title of a quick run: what its figures are worth.
QUICK_NOTE = ("Quick run (`--quick`): shorter recordings and streams, fewer repeats, rides, cells and inputs than "
              "the full run; each figure is measured against its floor the same way, on less data, so the numbers "
              "are indicative (the full run's are the ones to quote).")


def _num(v, unit: str = "") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    a = abs(v)
    if unit in ("frames", "inputs") or (float(v).is_integer() and a >= 1000):
        s = f"{int(round(v)):,}".replace(",", " ")
    elif a >= 100:
        s = f"{v:.0f}"
    elif a >= 10:
        s = f"{v:.1f}"
    else:
        s = f"{v:.2f}"
    return f"{s} {unit}".strip()


def to_markdown(result: dict) -> str:
    """Figures table (value, floor, cost ratio, target), notes, peak memory and the machine."""
    m = result.get("machine", {})
    lines = [f"# Benchmarks ({'quick' if result.get('quick') else 'full'} run)", ""]
    lines.append(f"Machine: {m.get('cpu', '?')}, {m.get('cpus_allowed', '?')} of {m.get('logical_cpus', '?')} "
                 f"logical CPUs, {m.get('memory_gb', '?')} GB; {m.get('os', '?')}; Python {m.get('python', '?')}, "
                 f"numpy {m.get('numpy', '?')}, rclpy {m.get('rclpy', '?')}; commit {m.get('commit', '?')}.  ")
    la0, la1 = result.get("load_average_start"), result.get("load_average_end")
    lines.append(f"Taken {result.get('started_utc', '?')} in {result.get('wall_s', 0):.0f} s; load average "
                 f"(1/5/15 min) {la0} at the start, {la1} at the end.")
    if result.get("quick"):
        lines += ["", QUICK_NOTE]
    lines += ["", "Ratio = cost relative to the floor measured in the same run (value / floor for times, "
              "floor / value for rates): 1 is as cheap as the floor.", ""]
    lines.append("| benchmark | figure | value | floor | ratio | target | met |")
    lines.append("|---|---|---|---|---|---|---|")
    notes = []
    for b in result["benchmarks"]:
        if b.get("error"):
            lines.append(f"| {b['name']} | **failed** | {b['error'][:120]} | | | | |")
            continue
        for f in b["figures"]:
            met = "" if f.get("met") is None else ("yes" if f["met"] else "**no**")
            ratio = "-" if f.get("ratio") is None else f"{f['ratio']:.2f}"
            lines.append(f"| {b['name']} | {f['metric']} | {_num(f['value'], f['unit'])} | "
                         f"{_num(f.get('floor'), f['unit']) if f.get('floor') is not None else '-'} | {ratio} | "
                         f"{f.get('target') or ''} | {met} |")
            if f.get("note"):
                notes.append(f"- {b['name']}, {f['metric']}: {f['note']}")
    if notes:
        lines += ["", "Notes:", "", *notes]
    lines += ["", "Peak memory (resident set, MB):", "", "| benchmark | process | peak RSS [MB] |", "|---|---|---|"]
    for b in result["benchmarks"]:
        for label, mb in (b.get("peak_rss_mb") or {}).items():
            lines.append(f"| {b['name']} | {label} | {_num(mb)} |")
    lines += ["", "Wall time per benchmark (total: with the recordings a first run generates; measuring: "
              "without them):", "", "| benchmark | total [s] | measuring [s] |", "|---|---|---|"]
    for b in result["benchmarks"]:
        lines.append(f"| {b['name']} | {_num(b.get('total_s'))} | {_num(b.get('wall_s'))} |")
    return "\n".join(lines) + "\n"
