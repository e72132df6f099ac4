"""The EUC paper's Figs 6-7 layout (:func:`plot_ride_states`).

Yaw psi, tilt theta, EUC pitch gamma, rider pitch phi (degrees) and the driving torque from both
expressions, M_d1 against M_d2 (N m), over time.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from euc_ros.cli.figures.checks import has_content
from euc_ros.cli.figures.common import pyplot, save_figure
from euc_ros.cli.figures.gaps import GAP_LABEL, break_at_jumps, gap_spans, mark_gaps


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
        if not has_content(ax):
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

