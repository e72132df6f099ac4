"""The splines of the discovery's lab-field and speed families (:mod:`.families`).

* :func:`bspline_basis`: B-splines clamped to a range, the argument clipped to it (constant beyond);
* :func:`uniform_knots`: interior knots in equal pieces no longer than a spacing;
* :func:`local_pieces`, :func:`local_bspline_basis`: uniform B-splines whose support meets a span, zero beyond
  their support;
* :func:`revisited_span`: the span of a lab coordinate two passes meet, where a lab field can be checked on a
  held-out pass.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy import signal
from scipy.interpolate import BSpline


def bspline_basis(x: np.ndarray, lo: float, hi: float, degree: int, interior: np.ndarray) -> np.ndarray:
    """B-spline basis on [lo, hi], ``x`` clipped to it (partition of unity).

    Parameters
    ----------
    x : ndarray (n,)
    lo, hi : float
        The range (the outer knots, repeated), in ``x``'s unit.
    degree : int
    interior : array_like (k,)
        Interior knots, ascending, inside the range.

    Returns
    -------
    ndarray (n, k + degree + 1)
    """
    t = np.concatenate([np.full(degree + 1, lo), np.asarray(interior, float), np.full(degree + 1, hi)])
    xc = np.clip(np.asarray(x, float), lo, hi)
    return BSpline.design_matrix(xc, t, degree).toarray()


def uniform_knots(lo: float, hi: float, spacing: float | None) -> np.ndarray:
    """Interior knots about every ``spacing`` on [lo, hi]: the range in equal pieces no longer than it.

    Parameters
    ----------
    lo, hi : float
        The range.
    spacing : float or None
        Longest piece, in the range's unit.

    Returns
    -------
    ndarray
        The knots, ascending; none for ``spacing`` None or an empty range.
    """
    if spacing is None or not hi > lo:
        return np.zeros(0)
    pieces = max(int(np.ceil((hi - lo) / spacing)), 1)
    return np.linspace(lo, hi, pieces + 1)[1:-1]


def local_pieces(lo: float, hi: float, spacing: float) -> int:
    """Equal pieces of [lo, hi] no longer than ``spacing``, at least one.

    :func:`local_bspline_basis` has ``pieces + degree`` functions.

    Parameters
    ----------
    lo, hi : float
        The range.
    spacing : float
        Longest piece.

    Returns
    -------
    int

    Examples
    --------
    >>> local_pieces(0.0, 8.5, 1.0), local_pieces(0.0, 8.0, 1.0), local_pieces(0.0, 0.2, 1.0)
    (9, 8, 1)
    """
    return max(int(np.ceil((hi - lo) / spacing - 1e-9)), 1)


def local_bspline_basis(x: np.ndarray, lo: float, hi: float, degree: int, spacing: float) -> np.ndarray:
    """Uniform B-splines whose support meets [lo, hi], zero outside their support (no clipping).

    The pieces are equal and no longer than ``spacing``; the functions at the ends reach ``degree`` pieces beyond
    the range and fall to zero there, so a field is fitted where the range is and says nothing beyond it.

    Parameters
    ----------
    x : ndarray (n,)
    lo, hi : float
        The range, ``hi > lo``.
    degree : int
    spacing : float
        Longest piece, in ``x``'s unit.

    Returns
    -------
    ndarray (n, pieces + degree)

    Examples
    --------
    >>> B = local_bspline_basis(np.array([-10.0, 0.0, 0.5, 1.0, 10.0]), 0.0, 1.0, 3, 0.5)
    >>> B.shape, bool(np.all(B[[0, -1]] == 0)), bool(np.allclose(B[1:4].sum(axis=1), 1.0))
    ((5, 5), True, True)
    """
    pieces = local_pieces(lo, hi, spacing)
    step = (hi - lo) / pieces
    t = lo + step * np.arange(-2 * degree, pieces + 2 * degree + 1)
    x = np.asarray(x, float)
    inside = (x >= t[degree]) & (x <= t[-degree - 1])
    out = np.zeros((x.size, t.size - degree - 1))
    if np.any(inside):
        out[inside] = BSpline.design_matrix(x[inside], t, degree).toarray()
    # the functions whose support meets (lo, hi): first knot above lo - (degree + 1) step
    return out[:, degree:degree + pieces + degree]


def revisited_span(series: Sequence[np.ndarray], reversal: float) -> tuple[float, float] | None:
    """The span of a lab coordinate met by at least two passes.

    A pass is a stretch of one recording along which the coordinate keeps its direction: it ends at a turning
    point, an extreme the coordinate comes back from by ``reversal`` on both sides (a peak's prominence). A field
    fixed in the lab can be told from a passing gust only where a second pass meets it again; elsewhere a held-out
    pass has nothing to check a fit against.

    Parameters
    ----------
    series : sequence of ndarray
        The coordinate along each recording.
    reversal : float
        Return from the furthest point that ends a pass (the coordinate's unit).

    Returns
    -------
    (float, float) or None
        The hull of the positions two or more passes cover; None when no two passes overlap.

    Examples
    --------
    >>> x = np.r_[np.linspace(0, 5, 51), np.linspace(5, 3, 21)]
    >>> revisited_span([x], 0.25)
    (3.0, 5.0)
    >>> revisited_span([np.linspace(0, 5, 50), np.linspace(4, 9, 50)], 0.25)
    (4.0, 5.0)
    >>> revisited_span([np.linspace(0, 5, 50)], 0.25) is None
    True
    """
    passes = []
    for x in series:
        x = np.asarray(x, float)
        x = x[np.isfinite(x)]
        if x.size < 2:
            continue
        # the turning points: extremes the coordinate comes back from by `reversal` on both sides (a peak's
        # prominence), so jitter smaller than it turns nothing
        turns = np.sort(np.concatenate([signal.find_peaks(x, prominence=reversal)[0],
                                        signal.find_peaks(-x, prominence=reversal)[0]]))
        edges = np.unique(np.concatenate([[0], turns, [x.size - 1]]))
        # each pass from one turning point to the next, both included
        lo = np.minimum.reduceat(x, edges[:-1])
        hi = np.maximum.reduceat(x, edges[:-1])
        ends = x[edges[1:]]
        passes += list(zip(np.minimum(lo, ends).tolist(), np.maximum(hi, ends).tolist()))
    lows, highs = [], []
    for j, (a0, a1) in enumerate(passes):
        for b0, b1 in passes[j + 1:]:
            lo, hi = max(a0, b0), min(a1, b1)
            if hi > lo:
                lows.append(lo)
                highs.append(hi)
    return (min(lows), max(highs)) if lows else None
