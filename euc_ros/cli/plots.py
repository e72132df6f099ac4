"""Figure helpers shared by the CLI commands (PNG files, matplotlib imported lazily with Agg).

* :func:`plot_ride_states`: the EUC paper's Figs 6-7 layout: yaw psi, tilt theta, EUC pitch gamma,
  rider pitch phi (degrees) and the driving torque from both expressions, M_d1 against M_d2 (N m),
  over time.
* :func:`plot_rmse_curves`: the paper's Fig. 8: RMSE(h) of the 3-DoF and the 2-DoF model, one panel
  per recording (plus the pooled curves), with the optima marked.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

#: Figure resolution [dots per inch].
DPI = 110


def pyplot():
    """Return ``matplotlib.pyplot`` with the non-interactive Agg backend (imported on first use)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: str | Path, title: str = "") -> Path:
    """Title, tighten, write ``path`` (parent created) at :data:`DPI`, close the figure; return the path."""
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    pyplot().close(fig)
    return path


def _deg(a) -> np.ndarray:
    return np.degrees(np.asarray(a, dtype=float))


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
        PNG file to write.
    title : str
        Figure title (e.g. the model, h and RMSE).
    """
    plt = pyplot()
    fig, axes = plt.subplots(5, 1, figsize=(7.5, 9.5), sharex=True)
    labels = [r"$\psi$ [deg]", r"$\vartheta$ [deg]", r"$\gamma$ [deg]", r"$\varphi$ [deg]", r"$M_d$ [N m]"]
    for k, (st, (d1, d2)) in enumerate(zip(states_list, torques)):
        t = st.t - st.t[0]
        col = f"C{k % 10}"
        psi = np.where(st.has_euc, st.psi, np.nan)
        axes[0].plot(t, _deg(psi), color=col, lw=1)
        axes[1].plot(t, _deg(np.where(st.has_euc, st.theta, np.nan)), color=col, lw=1)
        axes[2].plot(t, _deg(st.gamma), color=col, lw=1)
        axes[3].plot(t, _deg(st.phi), color=col, lw=1)
        axes[4].plot(t, d1, color=col, lw=1, label=r"$M_{d,1}$" if k == 0 else None)
        axes[4].plot(t, d2, color=col, lw=1, ls="--", label=r"$M_{d,2}$" if k == 0 else None)
    for ax, lab in zip(axes, labels):
        ax.set_ylabel(lab)
        ax.grid(True, alpha=0.3)
    axes[4].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("t [s]")
    return save_figure(fig, path, title)


def plot_rmse_curves(h_grid: np.ndarray, panels: Mapping[str, Mapping[str, tuple[np.ndarray, float, float]]],
                     path: str | Path, *, title: str = "") -> Path:
    """Write a Fig. 8 style figure: RMSE of M_d1 - M_d2 against h, both models per panel.

    Parameters
    ----------
    h_grid : ndarray (g,)
        CoG heights [m].
    panels : mapping panel title -> mapping model -> (rmse curve (g,) [N m], h_opt [m], rmse_opt [N m])
        One panel per recording (and the pooled one).
    path : str or Path
        PNG file to write.
    title : str
        Figure title.
    """
    plt = pyplot()
    n = max(1, len(panels))
    cols = min(n, 3)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False)
    styles = {"3dof": ("C0", "-", "3 DoF"), "2dof": ("C3", "--", "2 DoF")}
    for ax, (name, models) in zip(axes.ravel(), panels.items()):
        for model, (curve, h_opt, r_opt) in models.items():
            col, ls, lab = styles.get(model, ("C2", ":", model))
            ax.plot(h_grid, curve, color=col, ls=ls, lw=1.4, label=f"{lab}: h={h_opt:.3f} m, {r_opt:.2f} N m")
            if np.isfinite(h_opt):
                ax.plot([h_opt], [r_opt], "o", color=col, ms=4)
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("h [m]")
        ax.set_ylabel("RMSE [N m]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    return save_figure(fig, path, title)
