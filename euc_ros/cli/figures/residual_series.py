"""The time series of ``euc-ros residual --plots DIR``.

``residual_time``: M_d1 - M_d2 over time per recording, of the base model and of the final one;
``residual_signature``: the residual against the selected effect's contribution. They shade the spans
without usable samples (:func:`~euc_ros.cli.figures.gaps.gap_spans`).
"""
from __future__ import annotations

import numpy as np

from euc_ros.cli.figures.common import h_text, pyplot
from euc_ros.cli.figures.gaps import GAP_LABEL, break_at_jumps, gap_spans, mark_gaps
from euc_ros.cli.figures.h_range import h_status


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


def draw_signature(result, rec, st, data: dict):
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

