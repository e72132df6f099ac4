"""Spans without usable samples in time series: occlusion gaps, frames not recorded, the filter's ends.

:func:`gap_spans` finds them, :func:`mark_gaps` shades them, and lines break there (:func:`break_at_jumps`).
"""
from __future__ import annotations

import numpy as np

#: ``gid`` of the collection :func:`mark_gaps` adds (a background, not data: the checks skip it).
GAP_GID = "gaps"
#: Label of the shaded spans without usable samples.
GAP_LABEL = "no usable samples (gap)"


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

