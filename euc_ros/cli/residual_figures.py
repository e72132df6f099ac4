"""Figures of ``euc-ros residual --plots DIR``, drawn from the analysis result and its JSON document.

* ``residual_time``: M_d1 - M_d2 over time per recording, of the base model and of the final one;
* ``residual_signature``: the residual against the selected effect's contribution;
* ``rmse_before_after``: the held-out RMSE of the base and the final model;
* ``candidates``: the candidate table with a status per row (:func:`candidate_rows`): selected, tie,
  refused, not admissible, undetectable, not significant; refused and not admissible rows are coloured
  and their reasons listed under the table, so no refused effect reads as a contender;
* ``floor``: the floor measured from the wheel's contact path (when the analysis measured one);
* ``h_range``: the h of every model the data cannot tell apart, with the 95 % intervals of the base and
  the final model as bars (an end the data do not bound is an arrow to the axis edge, never a number);
* ``discovered_functions``: each discovered function with its 95 % band.

Every h is written with its status (:func:`h_status`, :func:`~euc_ros.cli.plots.h_text`): one the data do
not identify is a best fit, not for use. Time series shade the spans without usable samples
(:func:`~euc_ros.cli.plots.gap_spans`).
"""
from __future__ import annotations

import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from euc_ros.cli.plots import (
    GAP_LABEL,
    break_at_jumps,
    gap_spans,
    h_text,
    mark_gaps,
    pyplot,
    save_figure,
)

#: Row status of the candidate table, and its row colour.
STATUS_COLOURS = {
    "selected": "#d9ead3",
    "selected (tie)": "#d9ead3",
    "tie": "#fff2cc",
    "refused": "#f4cccc",
    "not admissible": "#fce5cd",
    "undetectable": "#e6e6e6",
    "not significant": "#ffffff",
    "not selected": "#ffffff",
    "baseline": "#ffffff",
}
#: Statuses of rows that are no explanation (their text is greyed).
EXCLUDED = ("refused", "not admissible", "undetectable")
#: Columns of the candidate table.
COLUMNS = ("effect", "status", "held-out RMSE [N m]", "p", "p adj.", "parameters")


@dataclass(frozen=True)
class CandidateRow:
    """One row of the candidate figure.

    Attributes
    ----------
    effect : str
        The candidate's name (``none``: the base model).
    status : str
        One of :data:`STATUS_COLOURS`.
    rmse : str
        Held-out RMSE [N m] (``-`` when undetectable).
    p, p_adjusted : str
        Its p-value and the family-wise one (``-``: not tested).
    parameters : str
        Fitted parameters, ``name=value``.
    note : str
        Why it was refused or is not admissible (empty otherwise).
    """

    effect: str
    status: str
    rmse: str
    p: str
    p_adjusted: str
    parameters: str
    note: str = ""

    def cells(self) -> list[str]:
        """The table cells, in the order of :data:`COLUMNS`."""
        return [self.effect, self.status, self.rmse, self.p, self.p_adjusted, self.parameters]


def _p(v) -> str:
    return "-" if v is None else f"{v:.2g}"


def candidate_rows(data: dict) -> list[CandidateRow]:
    """The candidate table of a residual JSON document, each row with its status.

    The status of a candidate, first match: ``selected`` (``selected (tie)`` when the data cannot tell it
    from another explanation); ``refused`` (its fit left a plausible range: a row flag ``refused`` or an
    entry of ``refused``); ``not admissible``; ``undetectable``; ``tie``; ``not significant`` (family-wise p
    at or above the significance level); ``not selected``. The row ``none`` (the base model) is
    ``selected`` when no effect was selected, else ``baseline``.

    Parameters
    ----------
    data : dict
        The residual analysis' JSON document (``candidates``, ``selection_steps``, ``refused``, ``ties``,
        ``ambiguous_with``, ``effect``, ``significance_level``).

    Returns
    -------
    list of CandidateRow
        In the order of ``data["candidates"]``.
    """
    named = {s["selected"] for s in data.get("selection_steps", [])
             if s.get("selected") not in (None, "discovered")}
    refused: dict[str, list[str]] = {}
    for r in data.get("refused", []):
        refused.setdefault(r["effect"], []).append(r.get("text") or f"refused {r['effect']}")
    tied = {e for t in data.get("ties", []) for e in t.get("effects", [])} | set(data.get("ambiguous_with", []))
    alpha = data.get("significance_level")
    rows = []
    for c in data.get("candidates", []):
        e = c["effect"]
        note = ""
        if e == "none":
            status = "selected" if data.get("effect") == "none" else "baseline"
        elif e in named:
            status = "selected (tie)" if e in tied else "selected"
        elif c.get("refused") or e in refused:
            status = "refused"
            note = "; ".join(dict.fromkeys([t for t in [c.get("refused")] if t] + refused.get(e, [])))
        elif c.get("inadmissible"):
            status = "not admissible"
            note = f"{e} not admissible: {str(c['inadmissible']).removeprefix(e + ': ')}"
        elif not c.get("detectable", True):
            status = "undetectable"
        elif e in tied:
            status = "tie"
        elif alpha is not None and c.get("p_adjusted") is not None and c["p_adjusted"] >= alpha:
            status = "not significant"
        else:
            status = "not selected"
        detectable = c.get("detectable", True) and c.get("rmse_after_nm") is not None
        rows.append(CandidateRow(
            effect=e, status=status, rmse=f"{c['rmse_after_nm']:.3f}" if detectable else "-",
            p=_p(c.get("p_value")), p_adjusted=_p(c.get("p_adjusted")),
            parameters=", ".join(f"{k}={v:.3g}" for k, v in (c.get("effect_parameters") or {}).items()),
            note=note))
    return rows


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


def draw_candidates(data: dict):
    """The candidate table of a residual JSON document (:func:`candidate_rows`) as a Figure.

    One row per candidate with its status, coloured by it (:data:`STATUS_COLOURS`), and the reasons of the
    refused and not admissible ones under the table.
    """
    plt = pyplot()
    rows = candidate_rows(data)
    notes = [line for r in rows if r.note for line in textwrap.wrap(r.note, 140, subsequent_indent="    ")]
    table_h = 0.26 * (len(rows) + 1)
    notes_h = 0.17 * len(notes) + (0.1 if notes else 0.0)
    fig, ax = plt.subplots(figsize=(10, table_h + notes_h + 0.6))
    ax.axis("off")
    frac = table_h / (table_h + notes_h)
    table = ax.table(cellText=[r.cells() for r in rows], colLabels=list(COLUMNS), loc="center", cellLoc="left",
                     bbox=[0, 1 - frac, 1, frac], colWidths=[0.2, 0.12, 0.14, 0.07, 0.07, 0.4])
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    for (i, _), cell in table.get_celld().items():
        cell.PAD = 0.03
        if i == 0:
            cell.set_text_props(weight="bold")
            continue
        row = rows[i - 1]
        cell.set_facecolor(STATUS_COLOURS.get(row.status, "#ffffff"))
        if row.status in EXCLUDED:
            cell.get_text().set_color("0.35")
    if notes:
        ax.text(0.0, (1 - frac) - 0.02, "\n".join(notes), transform=ax.transAxes, ha="left", va="top", fontsize=7)
    effect = data.get("effect", "none")
    ax.set_title(f"candidates (selected: {effect}); refused and not admissible fits are no explanation",
                 fontsize=10)
    return fig


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


def _on_recording(rec, t_all: np.ndarray, mask: np.ndarray, *values: np.ndarray) -> tuple[np.ndarray, ...]:
    """Context samples where ``mask`` holds, put on the recording's samples.

    Parameters
    ----------
    rec : Recording
        The prepared recording (its ``index``: the recording's sample of each context sample; without it,
        found from the context's times, which are the recording's own from its first sample).
    t_all : ndarray (n,)
        The recording's sample times from its first sample [s].
    mask : ndarray (m,) of bool
        Over the context's samples.
    values : ndarray (m,)
        Over the context's samples.

    Returns
    -------
    tuple
        ``(usable (n,) of bool, *values on the recording (n,), NaN elsewhere)``.
    """
    index = np.asarray(rec.index) if rec.index is not None else np.searchsorted(t_all, rec.ctx.t)
    use = np.zeros(t_all.size, bool)
    use[index[mask]] = True
    out = []
    for v in values:
        full = np.full(t_all.size, np.nan)
        full[index[mask]] = np.asarray(v, float)[mask]
        out.append(full)
    return (use, *out)


def draw_residual_time(result, recs, states, data: dict):
    """M_d1 - M_d2 over time, one panel per recording.

    The base 3-DoF model and the final one; the spans without usable samples shaded (occlusion gaps, the
    filter's ends, frames not recorded).
    """
    from euc_ros.core.model.extended import Model

    plt = pyplot()
    base_ok, _ = h_status(data)
    final = result.final_model
    base_x = np.array([result.h_base])
    fig, axes = plt.subplots(len(recs), 1, figsize=(9, 2.2 * len(recs) + 0.9), squeeze=False, sharex=False,
                             layout="constrained")
    for ax, rec, st in zip(axes[:, 0], recs, states):
        t_all = st.t - st.t[0]
        r0, m0 = Model().residual(rec, base_x)
        use0, y0 = _on_recording(rec, t_all, m0, r0)
        series = [y0]
        if final.effects:
            r1, m1 = final.residual(rec, result.final_x)
            series.append(_on_recording(rec, t_all, m1, r1)[1])
        t, *ys = break_at_jumps(t_all, *series)
        ax.plot(t, ys[0], lw=0.8, label=f"3-DoF, {h_text(result.h_base, base_ok)}")
        if final.effects:
            ax.plot(t, ys[1], lw=0.8, label=f"3-DoF + {final.name}")
        mark_gaps(ax, gap_spans(t_all, use0), label=GAP_LABEL)
        if not np.isfinite(y0).any():
            ax.text(0.5, 0.5, "no usable samples", ha="center", va="center", transform=ax.transAxes)
        ax.set_xlim(0.0, max(float(t_all[-1]), 1e-3))
        ax.set_ylabel("M_d1 - M_d2 [N m]")
        ax.set_title(rec.name, fontsize=9)
        ax.grid(alpha=0.3)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", fontsize=8, frameon=False, ncols=3)
    axes[-1, 0].set_xlabel("t [s]")
    return fig


def _draw_signature(result, rec, st, data: dict):
    """The residual against the selected effect's contribution.

    Over time (always readable, also for an effect that is nearly constant, such as rolling resistance at one
    sign of the speed), and as a scatter when the contribution varies enough to spread the points.
    """
    from euc_ros.core.model.extended import Model

    plt = pyplot()
    _, final_ok = h_status(data)
    final = result.final_model
    r0, m0 = Model().residual(rec, np.array([result.h_after]))
    if final.effects:
        r1, m1 = final.residual(rec, result.final_x)
        m = m0 & m1
        sig = (r0 - r1)[m]
    else:
        m, sig = m0, np.zeros(int(m0.sum()))
    varies = final.effects and sig.size > 2 and np.std(sig) > 0.1 * max(abs(np.mean(sig)), 1e-9)
    fig, axes = plt.subplots(1, 2 if varies else 1, figsize=(10 if varies else 7, 3.8), squeeze=False)
    ax = axes[0, 0]
    t_all = st.t - st.t[0]
    contribution = np.zeros(r0.size)
    contribution[m] = sig
    use, y_res, y_sig = _on_recording(rec, t_all, m, r0, contribution)
    t, y_res, y_sig = break_at_jumps(t_all, y_res, y_sig)
    ax.plot(t, y_res, lw=0.7, color="tab:gray",
            label=f"residual of the 3-DoF model, {h_text(result.h_after, final_ok)}")
    if final.effects:
        ax.plot(t, y_sig, lw=1.2, color="tab:blue", label=f"fitted {final.name}")
    else:
        ax.axhline(0.0, color="tab:blue", lw=1, label="no effect selected")
    mark_gaps(ax, gap_spans(t_all, use), label=GAP_LABEL)
    ax.set_xlim(0.0, max(float(t_all[-1]), 1e-3))
    ax.set_xlabel("t [s]")
    ax.set_ylabel("torque [N m]")
    ax.set_title(rec.name, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False, ncols=2)
    if varies:
        ax = axes[0, 1]
        ax.plot(sig, r0[m], ".", ms=2, alpha=0.5)
        lim = float(np.nanmax(np.abs(np.concatenate([sig, r0[m]]))))
        ax.plot([-lim, lim], [-lim, lim], "k--", lw=1, label="1:1")
        ax.set_xlabel(f"fitted {final.name} [N m]")
        ax.set_ylabel("residual [N m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    return fig


def _draw_floor(fl, states, params):
    """The contact height along the lab x axis with the fitted floor plane."""
    from euc_ros.core.states.floor import contact_heights

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9, 3.6))
    for st in states:
        v = st.valid
        z = contact_heights(st.C[v], st.theta[v], params.R)
        ax.plot(st.C[v, 0], 1e3 * z, ".", ms=1.5, alpha=0.6, label=st.name)
        plane = fl.plane[0] + fl.plane[1] * st.C[v, 0] + fl.plane[2] * st.C[v, 1]
        ax.plot(st.C[v, 0], 1e3 * plane, "k-", lw=0.8)
    if not any(np.any(st.valid) for st in states):
        ax.text(0.5, 0.5, "no valid samples", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("lab x [m]")
    ax.set_ylabel("contact height C_z - R cos(theta) [mm]")
    ax.set_title(f"floor from the contact path ({'flat' if fl.flat else 'not flat'}): plane slope "
                 f"{np.degrees(fl.slope_rad):.2f} deg, deviation {1e3 * fl.deviation_m:.1f} mm,\n"
                 f"scatter {1e3 * fl.scatter_m:.2f} mm; black: fitted plane", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, markerscale=4, loc="best")
    return fig


def discovered_figure(rows: list[dict], path: Path) -> Path:
    """Each discovered function over its argument's observed range with its 95 % band.

    One panel per row of the residual JSON's ``discovered``; a drift has one curve per recording.
    """
    plt = pyplot()
    fig, axes = plt.subplots(len(rows), 1, figsize=(7.5, 2.6 * len(rows) + 0.4), squeeze=False)
    for ax, d in zip(axes[:, 0], rows):
        grid = np.asarray(d["grid"], float)
        values = np.asarray(d["values"], float).reshape(-1, grid.size)
        lo = np.asarray([np.nan if v is None else v for v in np.ravel(d["band_lo"])], float).reshape(values.shape)
        hi = np.asarray([np.nan if v is None else v for v in np.ravel(d["band_hi"])], float).reshape(values.shape)
        names = d.get("curves") or [""]
        for k in range(values.shape[0]):
            line, = ax.plot(grid, values[k], lw=1.2, label=names[k] or "fitted")
            if np.any(np.isfinite(lo[k])):
                ax.fill_between(grid, lo[k], hi[k], color=line.get_color(), alpha=0.2, lw=0,
                                label="95 % band" if k == 0 else None)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xlabel(f"{d['argument']} [{d['argument_unit']}]")
        ax.set_ylabel(f"[{d['unit']}]")
        ax.set_title(f"{d['family']}: {d['function']} on {d['coordinate']} at the {d['point']}", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best", ncols=2)
    return save_figure(fig, path)


def write_plots(result, states, params, out_dir: Path, *, data: dict | None = None) -> list[Path]:
    """Write the residual analysis' figures into ``out_dir`` (see the module's list).

    Parameters
    ----------
    result : ResidualResult
        The analysis (:func:`euc_ros.core.residual.analysis.analyze`).
    states : sequence of RiderStates
        The recordings' states, in the analysis' order.
    params : EucParams
        The session's parameters.
    out_dir : Path
        Folder of the figures (created).
    data : dict, optional
        The command's JSON document (:func:`euc_ros.core.residual.pipeline.trace_residual`): its ``identifiable``,
        ``h_ci95_m`` and ``h_after_ci95_m`` give the h their status and intervals. Default: the result's own
        JSON, which does not assess the identifiability of h (the figures say so).

    Returns
    -------
    list of Path
        The figures written (first configured format).
    """
    from euc_ros.core.states.contexts import prepare

    doc = data if data is not None else result.to_json()
    out_dir.mkdir(parents=True, exist_ok=True)
    recs = prepare(states, params, floor=result.floor_fit)
    paths = []
    if result.floor_fit is not None:
        paths.append(save_figure(_draw_floor(result.floor_fit, states, params), out_dir / "floor.png"))
    fig = draw_h_range(doc)
    if fig is not None:
        paths.append(save_figure(fig, out_dir / "h_range.png"))
    paths.append(save_figure(draw_residual_time(result, recs, states, doc), out_dir / "residual_time.png"))
    paths.append(save_figure(_draw_signature(result, recs[0], states[0], doc), out_dir / "residual_signature.png"))

    plt = pyplot()
    final = result.final_model
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.bar(["before\n(3-DoF)", f"after\n({final.name})"], [result.rmse_before, result.rmse_after],
           color=["tab:gray", "tab:blue"])
    for i, v in enumerate([result.rmse_before, result.rmse_after]):
        ax.text(i, v, f"{v:.3f}", ha="center", va="bottom")
    ax.set_ylabel("held-out RMSE of M_d1 - M_d2 [N m]")
    paths.append(save_figure(fig, out_dir / "rmse_before_after.png"))

    if result.discovered:
        paths.append(discovered_figure(result.discovered, out_dir / "discovered_functions.png"))
    paths.append(save_figure(draw_candidates(doc), out_dir / "candidates.png"))
    return paths
