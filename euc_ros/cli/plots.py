"""Figure helpers shared by the CLI commands (matplotlib imported lazily with Agg).

Figures are written in the formats and at the resolution :func:`configure` sets (``--plot-format``,
``--dpi``): PNG for a quick look, PDF and SVG (vector) for a paper. Text is written as text a journal
accepts (:data:`FONT_RC`): TrueType fonts embedded in PDF and PostScript (no Type 3 fonts), ``<text>``
elements in SVG. Every figure is laid out by matplotlib's constrained layout and then checked by
:func:`figure_problems` (text inside the canvas, no empty axes, legends clear of the data); a legend over
the data is moved below its axes, and what cannot be fixed is a warning on the console, never a lost
analysis.

An h is written with its status (:func:`h_text`): one the data do not identify reads as a best fit not
for use, never as the answer. Time series shade the spans without usable samples (:func:`gap_spans`,
:func:`mark_gaps`: occlusion gaps, frames not recorded, the filter's ends) and break their lines there.

* :func:`plot_ride_states`: the EUC paper's Figs 6-7 layout: yaw psi, tilt theta, EUC pitch gamma,
  rider pitch phi (degrees) and the driving torque from both expressions, M_d1 against M_d2 (N m),
  over time.
* :func:`plot_rmse_curves`: the paper's Fig. 8: RMSE(h) of the 3-DoF and the 2-DoF model, one panel
  per recording (plus the pooled curves), with the optima marked.
"""
from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

#: Default raster resolution [dots per inch] (print quality; vector formats ignore it).
DPI = 200
#: Formats a figure can be written in.
FORMATS = ("png", "pdf", "svg")
#: Current output settings (:func:`configure`).
_settings = {"formats": ("png",), "dpi": DPI, "strict": False}
#: rcParams of every figure written: TrueType (Type 42) fonts in PDF and PS, text kept as text in SVG.
FONT_RC = {"pdf.fonttype": 42, "ps.fonttype": 42, "svg.fonttype": "none"}
#: ``gid`` of the collection :func:`mark_gaps` adds (a background, not data: the checks skip it).
GAP_GID = "gaps"
#: Label of the shaded spans without usable samples.
GAP_LABEL = "no usable samples (gap)"


def configure(formats: Sequence[str] = ("png",), dpi: float = DPI, *, strict: bool = False) -> None:
    """Set the formats and resolution of the figures written from now on.

    Parameters
    ----------
    formats : sequence of {"png", "pdf", "svg"}
        Every figure is written once per format (same stem).
    dpi : float
        Raster resolution [dots per inch].
    strict : bool
        A layout problem (:func:`figure_problems`) raises instead of warning (tests; also with the
        environment variable ``EUC_ROS_STRICT_FIGURES=1``).
    """
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        from euc_ros.core.errors import ConfigError

        raise ConfigError(f"plot formats are {', '.join(FORMATS)}, got {', '.join(bad) or 'none'}", key="--plot-format")
    if not 30 <= dpi <= 2400:
        from euc_ros.core.errors import ConfigError

        raise ConfigError(f"--dpi must be in 30-2400, got {dpi:g}", key="--dpi")
    strict = strict or os.environ.get("EUC_ROS_STRICT_FIGURES", "") not in ("", "0")
    _settings.update(formats=tuple(dict.fromkeys(formats)), dpi=float(dpi), strict=strict)


def add_figure_arguments(parser) -> None:
    """``--plot-format`` and ``--dpi`` for a command that writes figures."""
    parser.add_argument("--plot-format", default="png", metavar="FMT[,FMT]",
                        help="figure formats: png, pdf, svg, comma-separated (pdf/svg are vector, for papers) [png]")
    parser.add_argument("--dpi", type=float, default=DPI, help=f"raster resolution of PNG figures [{DPI}]")


def configure_from_args(args) -> None:
    """Apply ``--plot-format`` and ``--dpi`` (when the command has them)."""
    fmt = getattr(args, "plot_format", None)
    if fmt is not None:
        configure([f.strip().lower() for f in str(fmt).split(",") if f.strip()], getattr(args, "dpi", DPI))


def pyplot():
    """Return ``matplotlib.pyplot`` with the non-interactive Agg backend and the font settings of :data:`FONT_RC`.

    It is imported on first use.
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    matplotlib.rcParams.update(FONT_RC)
    import matplotlib.pyplot as plt

    return plt


def h_text(h: float, identifiable: bool | None = True, *, digits: int = 3) -> str:
    """An h [m] as a figure states it, with its status.

    Parameters
    ----------
    h : float
        The fitted h [m].
    identifiable : bool or None
        Whether the data identify h (``identifiable`` of the analysis); None: not assessed.
    digits : int
        Decimals of the metre value.

    Returns
    -------
    str
        ``h = 0.667 m``; ``h not identifiable (best fit 0.667 m, not for use)``; ``h = 0.667 m
        (identifiability not assessed)``; ``h not determined`` for a value that is not finite.
    """
    if h is None or not np.isfinite(h):
        return "h not determined"
    if identifiable is False:
        return f"h not identifiable (best fit {h:.{digits}f} m, not for use)"
    if identifiable is None:
        return f"h = {h:.{digits}f} m (identifiability not assessed)"
    return f"h = {h:.{digits}f} m"


def gap_spans(t: np.ndarray, usable: np.ndarray, *, step: float | None = None) -> np.ndarray:
    """Time spans without a usable sample.

    Parameters
    ----------
    t : ndarray (n,)
        Sample times, increasing (frames that were not recorded are absent: the time step jumps).
    usable : ndarray (n,) of bool
        Which samples the figure's analysis uses.
    step : float, optional
        The nominal time step (default: the median step of ``t``); consecutive usable samples farther
        apart than 1.5 steps enclose a gap.

    Returns
    -------
    ndarray (k, 2)
        ``[start, end]`` of each gap, in the unit of ``t``: from the last usable sample before it to the
        first one after it, from the first sample to the first usable one, and from the last usable one
        to the last sample (the whole span when nothing is usable).
    """
    t = np.asarray(t, float)
    use = np.asarray(usable, bool)
    keep = np.isfinite(t)
    t, use = t[keep], use[keep]
    if t.size == 0:
        return np.zeros((0, 2))
    if not use.any():
        return np.array([[t[0], t[-1]]])
    if step is None:
        step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    tu = t[use]
    inner = np.flatnonzero(np.diff(tu) > 1.5 * step)
    head = np.array([[t[0], tu[0]]]) if tu[0] > t[0] else np.zeros((0, 2))
    tail = np.array([[tu[-1], t[-1]]]) if t[-1] > tu[-1] else np.zeros((0, 2))
    return np.concatenate([head, np.stack([tu[inner], tu[inner + 1]], axis=1), tail])


def mark_gaps(ax, spans: np.ndarray, *, label: str | None = None):
    """Shade ``spans`` (k, 2) [x data] over the full height of ``ax`` (one collection, ``gid`` :data:`GAP_GID`).

    Returns the collection (None without spans). ``label`` names it in a legend.
    """
    from matplotlib.collections import PolyCollection

    spans = np.asarray(spans, float).reshape(-1, 2)
    if not spans.size:
        return None
    y0, y1 = np.zeros(len(spans)), np.ones(len(spans))
    verts = np.stack([np.stack([spans[:, 0], y0], 1), np.stack([spans[:, 1], y0], 1),
                      np.stack([spans[:, 1], y1], 1), np.stack([spans[:, 0], y1], 1)], axis=1)
    coll = PolyCollection(verts, transform=ax.get_xaxis_transform(), facecolors="0.55", edgecolors="none",
                          alpha=0.25, zorder=0, label=label)
    coll.set_gid(GAP_GID)
    ax.add_collection(coll, autolim=False)
    return coll


def break_at_jumps(t: np.ndarray, *ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """``t`` and ``ys`` with a NaN sample inserted where the time step jumps (frames not recorded).

    A line drawn through them breaks there instead of bridging the gap.

    Returns ``(t, *ys)``; unchanged when no step exceeds 1.5 times the median step.
    """
    t = np.asarray(t, float)
    ys = tuple(np.asarray(y, float) for y in ys)
    if t.size < 3:
        return (t, *ys)
    d = np.diff(t)
    cut = np.flatnonzero(d > 1.5 * np.nanmedian(d)) + 1
    if not cut.size:
        return (t, *ys)
    mid = 0.5 * (t[cut - 1] + t[cut])
    return (np.insert(t, cut, mid), *(np.insert(y, cut, np.nan) for y in ys))


def _data_points(ax) -> np.ndarray:
    """Display coordinates (m, 2) of the data drawn in ``ax`` (lines, markers, bars)."""
    pts = []
    for line in ax.get_lines():
        xy = np.asarray(line.get_xydata(), float)
        if xy.size:
            pts.append(ax.transData.transform(xy[np.all(np.isfinite(xy), axis=1)]))
    for coll in ax.collections:
        if coll.get_gid() == GAP_GID:
            continue
        off = np.asarray(coll.get_offsets(), float)
        if off.size and off.ndim == 2:
            pts.append(coll.get_offset_transform().transform(off[np.all(np.isfinite(off), axis=1)]))
    for patch in ax.patches:
        bb = patch.get_window_extent()
        if np.all(np.isfinite([bb.x0, bb.y0, bb.x1, bb.y1])) and bb.width < 0.5 * ax.bbox.width:
            pts.append(np.array([[bb.x0, bb.y1], [bb.x1, bb.y1], [0.5 * (bb.x0 + bb.x1), bb.y1]]))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def _has_content(ax) -> bool:
    """Whether ``ax`` shows something (shaded gaps alone are no content).

    Something is a line with a finite point, data collections, patches, images, tables or text.
    """
    lines = [ln for ln in ax.get_lines() if np.isfinite(np.asarray(ln.get_xydata(), float)).all(axis=1).any()]
    return bool(lines or [c for c in ax.collections if c.get_gid() != GAP_GID] or ax.patches or ax.images
                or ax.tables or [t for t in ax.texts if t.get_text().strip()])


def figure_problems(fig) -> list[str]:
    """What makes a figure unfit to print: text outside the canvas, visible empty axes, a legend over data.

    The figure is drawn first (the layout is final). Returns one sentence per problem (empty: fit).
    """
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    canvas = fig.bbox
    problems = []
    def outside(bb) -> bool:
        return bb.x0 < canvas.x0 - 1 or bb.y0 < canvas.y0 - 1 or bb.x1 > canvas.x1 + 1 or bb.y1 > canvas.y1 + 1

    # what is drawn: each axes' tight box (its ticks, labels, title and legend) and the figure's own texts
    for ax in fig.axes:
        if ax.get_visible() and outside(ax.get_tightbbox(renderer)):
            problems.append(f"labels of the axes {ax.get_title()[:40]!r} are cut by the canvas edge")
    for t in [*fig.texts, *([fig._suptitle] if fig._suptitle is not None else []), *fig.legends]:
        if t.get_visible() and outside(t.get_window_extent(renderer)):
            problems.append("a figure title or legend is cut by the canvas edge")
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        if not _has_content(ax):
            problems.append(f"axes {ax.get_title()[:40]!r} are empty")
        leg = ax.get_legend()
        if leg is not None and leg.get_visible():
            bb = leg.get_window_extent(renderer)
            pts = _data_points(ax)
            inside = ((pts[:, 0] > bb.x0) & (pts[:, 0] < bb.x1) & (pts[:, 1] > bb.y0) & (pts[:, 1] < bb.y1)).sum() \
                if pts.size else 0
            if inside:
                problems.append(f"the legend of {ax.get_title()[:40]!r} covers {inside} data point(s)")
    return problems


def _move_legends_below(fig) -> None:
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is not None:
            handles, labels = ax.get_legend_handles_labels()
            ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.18), fontsize=8,
                      ncols=min(3, max(1, len(labels))), frameon=False)


def save_figure(fig, path: str | Path, title: str = "") -> Path:
    """Title, lay out, check, write ``path`` in every configured format (parent created), close the figure.

    Returns the path of the first format written (the one a report links).
    """
    if title:
        fig.suptitle(title, fontsize=10)
    fig.set_layout_engine("constrained")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)      # layout notes: checked below instead
        problems = figure_problems(fig)
        if any("legend" in p for p in problems):
            _move_legends_below(fig)
            problems = figure_problems(fig)
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        written = []
        import matplotlib

        with matplotlib.rc_context(FONT_RC):
            for fmt in _settings["formats"]:
                out = path.with_suffix(f".{fmt}")
                meta = {"Creator": "euc_ros"} if fmt != "png" else None
                fig.savefig(out, dpi=_settings["dpi"], format=fmt, metadata=meta)
                written.append(out)
    pyplot().close(fig)
    if problems:
        text = f"figure {path.name}: " + "; ".join(problems)
        if _settings["strict"]:
            raise AssertionError(text)
        print(f"warning: {text}", file=sys.stderr)
    return written[0]


def _deg(a) -> np.ndarray:
    return np.degrees(np.asarray(a, dtype=float))


def draw_ride_states(states_list: Sequence, torques: Sequence[tuple[np.ndarray, np.ndarray]]):
    """The figure of :func:`plot_ride_states`, drawn and not written (returns the Figure).

    Spans without a valid sample (``states.valid`` false: occlusion gaps and the filter's ends; frames not
    recorded) are shaded on every panel and break the lines; a panel without any finite value says so.
    """
    plt = pyplot()
    fig, axes = plt.subplots(5, 1, figsize=(7.5, 9.5), sharex=True)
    labels = [r"$\psi$ [deg]", r"$\vartheta$ [deg]", r"$\gamma$ [deg]", r"$\varphi$ [deg]", r"$M_d$ [N m]"]
    end = 0.0
    for k, (st, (d1, d2)) in enumerate(zip(states_list, torques)):
        t0 = st.t - st.t[0]
        col = f"C{k % 10}"
        t, psi, theta, gamma, phi, m1, m2 = break_at_jumps(
            t0, _deg(np.where(st.has_euc, st.psi, np.nan)), _deg(np.where(st.has_euc, st.theta, np.nan)),
            _deg(st.gamma), _deg(st.phi), d1, d2)
        axes[0].plot(t, psi, color=col, lw=1)
        axes[1].plot(t, theta, color=col, lw=1)
        axes[2].plot(t, gamma, color=col, lw=1)
        axes[3].plot(t, phi, color=col, lw=1)
        axes[4].plot(t, m1, color=col, lw=1, label=r"$M_{d,1}$" if k == 0 else None)
        axes[4].plot(t, m2, color=col, lw=1, ls="--", label=r"$M_{d,2}$" if k == 0 else None)
        spans = gap_spans(t0, st.valid)
        for i, ax in enumerate(axes):
            mark_gaps(ax, spans, label=GAP_LABEL if i == len(axes) - 1 and k == 0 else None)
        end = max(end, float(t0[-1]))
    for ax, lab in zip(axes, labels):
        ax.set_ylabel(lab)
        ax.grid(True, alpha=0.3)
        if not _has_content(ax):
            ax.text(0.5, 0.5, "no valid samples", ha="center", va="center", transform=ax.transAxes)
    if end > 0:
        axes[-1].set_xlim(0.0, end)
    axes[4].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("t [s]")
    return fig


def plot_ride_states(states_list: Sequence, torques: Sequence[tuple[np.ndarray, np.ndarray]], path: str | Path, *,
                     title: str = "") -> Path:
    """Write a Figs 6-7 style figure: psi, theta, gamma, phi [deg] and M_d1, M_d2 [N m] over time.

    Parameters
    ----------
    states_list : sequence of RiderStates
        One or several runs (overlaid, each from its own t = 0).
    torques : sequence of (M_d1, M_d2)
        Driving torques [N m] of each run (NaN where invalid).
    path : str or Path
        Figure file to write (its suffix is replaced by each configured format).
    title : str
        Figure title (e.g. the model, h with its status (:func:`h_text`) and RMSE).

    Notes
    -----
    The spans without usable samples are shaded (:func:`draw_ride_states`).
    """
    return save_figure(draw_ride_states(states_list, torques), path, title)


def plot_rmse_curves(h_grid: np.ndarray, panels: Mapping[str, Mapping[str, tuple[np.ndarray, float, float]]],
                     path: str | Path, *, title: str = "", interval: tuple[float, float] | None = None,
                     interval_panel: str | None = None, identifiable: bool | None = True) -> Path:
    """Write a Fig. 8 style figure: RMSE of M_d1 - M_d2 against h, both models per panel.

    Parameters
    ----------
    h_grid : ndarray (g,)
        CoG heights [m].
    panels : mapping panel title -> mapping model -> (rmse curve (g,) [N m], h_opt [m], rmse_opt [N m])
        One panel per recording (and the pooled one).
    path : str or Path
        Figure file to write (its suffix is replaced by each configured format).
    title : str
        Figure title.
    interval : (float, float), optional
        The 95 % interval of h [m], shaded on ``interval_panel`` (default: the last panel, the pooled
        one when there are several recordings).
    identifiable : bool or None
        Whether the data identify h: the optima are labelled with it (:func:`h_text`; None: not assessed).
    """
    plt = pyplot()
    n = max(1, len(panels))
    cols = min(n, 3)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.4 * rows + 0.4), squeeze=False)
    styles = {"3dof": ("C0", "-", "3 DoF"), "2dof": ("C3", "--", "2 DoF")}
    names = list(panels)
    target = interval_panel if interval_panel in panels else (names[-1] if names else None)
    for ax, (name, models) in zip(axes.ravel(), panels.items()):
        drawn = False
        if interval is not None and name == target and all(np.isfinite(interval)):
            ax.axvspan(interval[0], interval[1], color="C0", alpha=0.15, lw=0,
                       label=f"95 % interval [{interval[0]:.3f}, {interval[1]:.3f}] m")
        for model, (curve, h_opt, r_opt) in models.items():
            curve = np.asarray(curve, float)
            if not np.isfinite(curve).any():
                continue
            col, ls, lab = styles.get(model, ("C2", ":", model))
            ax.plot(h_grid, curve, color=col, ls=ls, lw=1.4,
                    label=f"{lab}: {h_text(h_opt, identifiable)}, {r_opt:.2f} N m")
            if np.isfinite(h_opt):
                ax.plot([h_opt], [r_opt], "o", color=col, ms=4)
            drawn = True
        if not drawn:
            ax.text(0.5, 0.5, "no valid samples", ha="center", va="center", transform=ax.transAxes)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("h [m]")
        ax.set_ylabel("RMSE of M_d1 - M_d2 [N m]")
        ax.grid(True, alpha=0.3)
        if drawn:
            ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False)
    for ax in axes.ravel()[n:]:
        fig.delaxes(ax)
    return save_figure(fig, path, title)
