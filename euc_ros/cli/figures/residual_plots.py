"""Figures of ``euc-ros residual --plots DIR`` (:func:`write_plots`).

Drawn from the analysis result and its JSON document:

* ``residual_time``: M_d1 - M_d2 over time per recording, of the base model and of the final one;
* ``residual_signature``: the residual against the selected effect's contribution;
* ``rmse_before_after``: the held-out RMSE of the base and the final model;
* ``candidates``: the candidate table with a status per row
  (:func:`~euc_ros.cli.figures.candidates_table.candidate_rows`): selected, tie, refused, not admissible,
  undetectable, not significant; refused and not admissible rows are coloured and their reasons listed
  under the table, so no refused effect reads as a contender;
* ``floor``: the floor measured from the wheel's contact path (when the analysis measured one);
* ``h_range``: the h of every model the data cannot tell apart, with the 95 % intervals of the base and
  the final model as bars (an end the data do not bound is an arrow to the axis edge, never a number);
* ``discovered_functions``: each discovered function with its 95 % band.

Every h is written with its status (:func:`~euc_ros.cli.figures.h_range.h_status`,
:func:`~euc_ros.cli.figures.common.h_text`): one the data do not identify is a best fit, not for use. Time
series shade the spans without usable samples (:func:`~euc_ros.cli.figures.gaps.gap_spans`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from euc_ros.cli.figures.candidates_table import draw_candidates
from euc_ros.cli.figures.common import pyplot, save_figure
from euc_ros.cli.figures.h_range import draw_h_range
from euc_ros.cli.figures.residual_series import draw_residual_time, draw_signature


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
    paths.append(save_figure(draw_signature(result, recs[0], states[0], doc), out_dir / "residual_signature.png"))

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
