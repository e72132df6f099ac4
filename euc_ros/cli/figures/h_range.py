"""The ``h_range`` figure of ``euc-ros residual --plots DIR``.

The h of every model the data cannot tell apart, with the 95 % intervals of the base and the final model as
bars (an end the data do not bound is an arrow to the axis edge, never a number). Every h is written with
its status (:func:`h_status`, :func:`~euc_ros.cli.figures.common.h_text`): one the data do not identify
is a best fit, not for use.
"""
from __future__ import annotations

import textwrap

import numpy as np

from euc_ros.cli.figures.common import h_text, pyplot


def h_status(data: dict) -> tuple[bool | None, bool | None]:
    """Whether the data identify the base model's h (``h_m``) and the final model's (``h_after_m``).

    As the console says: the document's ``identifiable`` and ``h_after_identifiable``.

    Without them (a document that did not assess them, such as ``ResidualResult.to_json``) the status is
    None (not assessed), except that a final interval ``h_after_ci95_m`` with an open end is not identified.
    """
    base = data.get("identifiable")
    final = data.get("h_after_identifiable")
    if final is None:
        ci = data.get("h_after_ci95_m")
        final = False if ci is not None and None in ci else None
    return (None if base is None else bool(base)), (None if final is None else bool(final))


def draw_h_range(data: dict):
    """The h of every model the data cannot tell apart (``tied_models``), each interval a bar; None without tied models.

    Drawn between the base model (its ``h_ci95_m``) and the final model (``h_after_ci95_m``).

    An interval end the data do not bound (None) is an arrow to the axis edge; a model without an interval
    of its own (a tied model without ``h_ci95_m``) is a point.
    """
    tied = data.get("tied_models") or []
    if not tied:
        return None
    plt = pyplot()
    base_ok, final_ok = h_status(data)
    rows = [("base 3-DoF model (no effect)", data["h_m"], data.get("h_ci95_m"), "base")]
    rows += [("\n".join(textwrap.wrap(t["effect"], 44)), t["h_m"], t.get("h_ci95_m"), "tied") for t in tied]
    rows.append(("\n".join(textwrap.wrap(f"final model: {data.get('effect', '')}", 44)),
                 data.get("h_after_m", float("nan")),
                 data.get("h_after_ci95_m"), "final"))
    h = np.array([float(r[1]) if r[1] is not None else np.nan for r in rows])
    lo = np.array([np.nan if r[2] is None or r[2][0] is None else float(r[2][0]) for r in rows])
    hi = np.array([np.nan if r[2] is None or r[2][1] is None else float(r[2][1]) for r in rows])
    has_iv = np.array([r[2] is not None for r in rows])
    y = np.arange(len(rows), dtype=float)
    fig, ax = plt.subplots(figsize=(8.5, 0.6 * len(rows) + 3.0), layout="constrained")
    rng = data.get("h_range_m") or [None, None]
    span = [float(v) for v in rng if v is not None and np.isfinite(v)]
    if len(span) == 2:
        what = "h range" if final_ok else "range of the best-fit h"
        ax.axvspan(span[0], span[1], color="tab:orange", alpha=0.2, lw=0,
                   label=f"{what} of the tied models [{span[0]:.3f}, {span[1]:.3f}] m")
    finite = np.concatenate([h, lo, hi, span])
    finite = finite[np.isfinite(finite)]
    x0, x1 = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
    pad = max(0.05, 0.1 * (x1 - x0))
    ax.set_xlim(x0 - pad, x1 + pad)
    styles = {"base": ("s", "k", "base 3-DoF model, 95 % interval"),
              "tied": ("o", "tab:blue", "h of each tied model"),
              "final": ("D", "tab:green", "final model, 95 % interval (holds every tied h)")}
    kinds = np.array([r[3] for r in rows])
    for kind, (marker, colour, label) in styles.items():
        sel = kinds == kind
        if not sel.any():
            continue
        bar = sel & has_iv
        if bar.any():
            # the bounded side of each interval; an open side is drawn as an arrow below
            err = np.stack([np.where(np.isfinite(lo[bar]), h[bar] - lo[bar], 0.0),
                            np.where(np.isfinite(hi[bar]), hi[bar] - h[bar], 0.0)])
            ax.errorbar(h[bar], y[bar], xerr=np.clip(err, 0.0, None), fmt=marker, color=colour, ms=6,
                        capsize=4, lw=1.4, label=label)
        dots = sel & ~has_iv
        if dots.any():
            ax.plot(h[dots], y[dots], marker, color=colour, ms=6,
                    label=label if not bar.any() else None)
    open_lo = has_iv & ~np.isfinite(lo) & np.isfinite(h)
    open_hi = has_iv & ~np.isfinite(hi) & np.isfinite(h)
    for edge, open_end in ((0.0, open_lo), (1.0, open_hi)):
        for hv, yv in zip(h[open_end], y[open_end]):
            ax.annotate("", xy=(edge, yv), xycoords=("axes fraction", "data"), xytext=(hv, yv),
                        textcoords="data", arrowprops={"arrowstyle": "->", "color": "0.3", "lw": 1.2})
    if (open_lo | open_hi).any():
        ax.plot([], [], color="0.3", marker=">", lw=1.2, label="interval not bounded (arrow to the edge)")
    ax.set_yticks(y, [r[0] for r in rows], fontsize=8)
    ax.set_ylim(len(rows) - 0.4, -0.6)
    ax.set_xlabel("rider CoG height h [m]")
    ax.set_title(f"models the held-out data cannot tell apart\nbase 3-DoF model: {h_text(data['h_m'], base_ok)}\n"
                 f"final model: {h_text(data.get('h_after_m', float('nan')), final_ok)}", fontsize=9)
    ax.grid(axis="x", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", fontsize=8, frameon=False, ncols=2)
    return fig
