"""The paper's Fig. 8 (:func:`plot_rmse_curves`).

RMSE(h) of the 3-DoF and the 2-DoF model, one panel per recording (plus the pooled curves), with the
optima marked.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from euc_ros.cli.figures.common import h_text, pyplot, save_figure


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
