"""Savitzky-Golay smoothing and derivatives that use every recorded sample, across gaps.

The Savitzky-Golay estimate at a sample is the least-squares polynomial through the window around it. When
samples are missing (dropped frames, an occluded body) the same least-squares fit can be made through the
samples that are there: :func:`masked_savgol` solves it at every sample, so a gap costs no stretch and no
trimmed edge, only precision where it is. With no sample missing the numbers are Savitzky-Golay's.

At the ends of the samples the window is the first or last whole one, evaluated off its centre (one-sided;
``ends="shift"``, the ends of Savitzky-Golay's ``mode="interp"`` where nothing is missing), or the centred
window through the samples it has (``ends="truncate"``).

Where the fit is ill-determined (too few samples, or all on one side of a long gap, or evaluated far off its
centre) its variance is large; :func:`masked_savgol` returns, per sample, the variance of the second derivative
relative to the full window's at its centre (the *inflation*: 1 with every sample, larger near gaps and ends),
and marks a sample usable when it stays under a bound. Only the wanted samples' fits are solved (``rows``), and
only the samples their windows cover are read.

Examples
--------
>>> t = np.arange(200) / 100.0
>>> y = 0.3 * t ** 3
>>> keep = np.ones(200, bool); keep[90:110] = False          # a 0.2 s gap
>>> out = masked_savgol(np.where(keep, y, np.nan), 41, 4, 0.01)
>>> bool(np.allclose(out.y_ddot[out.usable], 1.8 * t[out.usable], atol=1e-8))   # exact for a cubic
True
>>> int(out.usable.sum()) > int(keep[20:180].sum())            # gap samples and edges are estimated too
True
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre
from scipy import signal

from euc_ros.core.errors import ConfigError, InputError

#: Largest variance inflation of the second derivative for a sample to be usable (the full window: 1). At 4 its
#: standard deviation is at most twice the full window's: the noise of a centred window 4^(-1/5) = 0.76 times as
#: long (the variance of a Savitzky-Golay second derivative goes as the window to the -5th power), and a share f
#: of such samples raises the pooled noise variance of the second derivatives, and with it (to first order) the
#: pose noise's bias of h, by at most f (4 - 1) of itself.
MAX_INFLATION = 4.0


@dataclass(frozen=True)
class MaskedDerivatives:
    """Value and derivatives of the local fits, with how well each is determined.

    One row per sample (``n``), or per wanted row when :func:`masked_savgol` is given ``rows``.

    Parameters
    ----------
    y, y_dot, y_ddot : ndarray (n,) or (n, k)
        The fit's value and its first and second time derivatives [unit, unit/s, unit/s^2]; NaN where
        the fit is not determined.
    inflation : ndarray (n,)
        Variance of the second derivative over that of the full window at its centre (1 with every sample;
        inf where undetermined).
    usable : ndarray of bool (n,)
        Samples whose fit is determined and whose inflation is at most the bound.
    recorded : ndarray of bool (n,)
        Samples that were recorded (the others are estimated from their neighbours, not measured).
    """

    y: np.ndarray
    y_dot: np.ndarray
    y_ddot: np.ndarray
    inflation: np.ndarray
    usable: np.ndarray
    recorded: np.ndarray


def _correlate(x: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """``out[i] = sum_j kernel[j] x[i + j - h]`` along axis 0 (zero outside), for (n,) or (n, k) ``x``."""
    h = (kernel.size - 1) // 2
    k = kernel[::-1].reshape((-1,) + (1,) * (x.ndim - 1))
    full = signal.oaconvolve(x, k, mode="full", axes=0)
    return full[h:h + x.shape[0]]


def _fit_rows(n: int, h: int, rows: np.ndarray, ends: str) -> tuple[np.ndarray, np.ndarray]:
    """The window centre of each wanted row and its offset from it in the normalised time ``u`` [1/h].

    With ``ends="shift"`` (and a recording at least a window long) a row within ``h`` samples of either end
    takes the first or last whole window, centred ``h`` samples from that end; every other row is its own
    centre (offset 0).
    """
    centre = rows
    if ends == "shift" and n >= 2 * h + 1:
        centre = np.clip(rows, h, n - 1 - h)
    return centre, (rows - centre) / h


def _basis_at(u: np.ndarray, polyorder: int, d: int) -> np.ndarray:
    """``(m, p + 1)``: the ``d``-th derivative of each Legendre polynomial at the normalised times ``u``."""
    eye = np.eye(polyorder + 1)
    return np.column_stack([legendre.legval(u, legendre.legder(eye[k], d)) if d else legendre.legval(u, eye[k])
                            for k in range(polyorder + 1)])


def masked_savgol(y, window: int, polyorder: int, dt: float, *, max_inflation: float = MAX_INFLATION,
                  rows=None, ends: str = "shift") -> MaskedDerivatives:
    """Local least-squares polynomial fits through the recorded samples of every window.

    Parameters
    ----------
    y : array_like (n,) or (n, k)
        Samples on a regular grid of spacing ``dt``, NaN where missing (a row with any NaN is missing).
    window : int
        Odd window length [samples], ``> polyorder``.
    polyorder : int
        Order of the local polynomial.
    dt : float
        Sample spacing [s].
    max_inflation : float
        Largest variance inflation of the second derivative of a usable sample.
    rows : array_like of int, optional
        The samples whose fits are wanted (default: every sample). Only their windows' normal equations are
        solved, and the returned arrays have one row per entry, in order.
    ends : {"shift", "truncate"}
        At the samples within half a window of either end of ``y``: ``"shift"`` evaluates the fit of the first
        or last whole window off its centre (one-sided; with every sample recorded, the ends of
        ``scipy.signal.savgol_filter(mode="interp")``); ``"truncate"`` fits the centred window through the
        samples it has (those beyond the end count as missing).

    Returns
    -------
    MaskedDerivatives

    Raises
    ------
    ConfigError
        A window that is not odd and longer than the order, a spacing that is not positive, or unknown ``ends``.
    InputError
        ``y`` of another shape, or ``rows`` outside it.

    Notes
    -----
    In the normalised time ``u_j = j / h`` (``j = -h..h``, ``h = (window - 1) / 2``) with Legendre
    polynomials ``P_0..P_p``, the fit centred at sample ``c`` solves ``G_c a_c = b_c`` with
    ``G_c = sum_j m_{c+j} P(u_j) P(u_j)^T`` and ``b_c = sum_j m_{c+j} y_{c+j} P(u_j)`` (``m`` the recorded
    mask). Every entry of ``G_c`` and ``b_c`` is a correlation of the mask (or of the masked samples) with a
    fixed kernel, so all fits come from ``(p + 1)(p + 2) / 2 + (p + 1) k`` correlations and one batched solve
    at the wanted centres. The ``d``-th derivative at offset ``u`` from the centre is
    ``P^(d)(u) . a_c / (h dt)^d`` and its variance is proportional to ``P''(u)^T G_c^-1 P''(u)``; the inflation
    divides it by the full window's at its centre, ``P''(0)^T G^-1 P''(0)``. With every sample recorded the
    fit is Savitzky-Golay's, number for number up to round-off. A fit is determined where ``G_c`` has
    condition number under 1e12 and its window at least ``p + 1`` recorded samples.
    """
    window, polyorder = int(window), int(polyorder)
    if window % 2 != 1 or window <= polyorder:
        raise ConfigError(f"window must be odd and > polyorder, got {window} and {polyorder}", key="window")
    if not (np.isfinite(dt) and dt > 0):
        raise ConfigError(f"sample spacing must be > 0 s, got {dt!r}", key="dt")
    if ends not in ("shift", "truncate"):
        raise ConfigError(f"ends must be 'shift' or 'truncate', got {ends!r}", key="ends")
    y = np.asarray(y, dtype=float)
    if y.ndim not in (1, 2):
        raise InputError(f"y must have shape (n,) or (n, k), got {y.shape}", key="y")
    n = y.shape[0]
    rows = np.arange(n) if rows is None else np.asarray(rows, dtype=np.int64).reshape(-1)
    if rows.size and (rows.min() < 0 or rows.max() >= n):
        raise InputError(f"rows must lie in 0..{n - 1}", key="rows")
    y2 = y.reshape(n, -1)
    rec = np.all(np.isfinite(y2), axis=1)
    h = (window - 1) // 2
    centre, u_at = _fit_rows(n, h, rows, ends)
    fit_at, which = np.unique(centre, return_inverse=True)
    coef, Ginv, ok, ref = _solve_centres(y2, rec, fit_at, window, polyorder)
    P = legendre.legvander(np.arange(-h, h + 1) / h, polyorder).T     # (p + 1, window)
    g2 = _basis_at(np.zeros(1), polyorder, 2)[0]
    var_full = float(g2 @ np.linalg.solve(P @ P.T, g2))
    out, var2 = _evaluate(coef[which], Ginv[which], ok[which], u_at, polyorder, h * dt)
    out[0] = out[0] + ref
    infl = var2 / var_full
    usable = ok[which] & (infl <= max_inflation)
    shape = (rows.size,) + y.shape[1:]
    return MaskedDerivatives(out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape), infl, usable,
                             rec[rows])


def _window_runs(centres: np.ndarray, h: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The rows the windows centred at the sorted ``centres`` cover, and the centres' places among them.

    Overlapping windows merge into runs. A window lies inside its run but where it passes an end of the
    ``n`` rows, and a run that reaches an end is the first or last, so the correlations of the runs laid end
    to end are, at every centre, those of all ``n`` rows (and, with one run of every row, the same numbers).
    """
    lo, hi = np.maximum(centres - h, 0), np.minimum(centres + h + 1, n)
    first = np.flatnonzero(np.r_[True, lo[1:] > hi[:-1]])            # hi never decreases: runs are disjoint
    last = np.r_[first[1:], centres.size] - 1
    a, b = lo[first], hi[last]
    length = b - a
    start = np.cumsum(length) - length                                 # each run's place in the rows laid out
    src = np.repeat(a - start, length) + np.arange(int(length.sum()))
    run = np.repeat(np.arange(first.size), np.diff(np.r_[first, centres.size]))
    return src, centres - a[run] + start[run]


def _solve_centres(y2: np.ndarray, rec: np.ndarray, at: np.ndarray, window: int, polyorder: int):
    """The fits of the windows centred at the samples ``at``: coefficients, ``G^-1`` and where determined.

    Returns ``coef`` (m, p + 1, k) and ``Ginv`` (m, p + 1, p + 1), NaN where undetermined, ``ok`` (m,) and
    ``ref`` (k,): the fits are those of the samples less ``ref``, their median.
    """
    q = polyorder + 1
    h = (window - 1) // 2
    # the samples less a constant (it cancels in the derivatives: round-off at the motion's scale)
    ref = np.nanmedian(y2[rec], axis=0) if rec.any() else np.zeros(y2.shape[1])
    if at.size == 0:
        return np.zeros((0, q, y2.shape[1])), np.zeros((0, q, q)), np.zeros(0, bool), ref
    src, at = _window_runs(at, h, y2.shape[0])         # only the rows the windows cover, run after run
    rec = rec[src]
    m = rec.astype(float)
    ym = np.where(rec[:, None], y2[src] - ref, 0.0)
    P = legendre.legvander(np.arange(-h, h + 1) / h, polyorder).T
    G = np.empty((at.size, q, q))
    for a in range(q):
        for b in range(a, q):
            G[:, a, b] = G[:, b, a] = _correlate(m, P[a] * P[b])[at]
    B = np.stack([_correlate(ym, P[a])[at] for a in range(q)], axis=1)   # (m, p + 1, k)
    with np.errstate(all="ignore"):
        cond = np.linalg.cond(G)
        count = np.convolve(np.pad(m, h), np.ones(window), mode="valid")          # recorded samples per window
        ok = np.isfinite(cond) & (cond < 1e12) & (count[at] >= q)
    coef = np.full((at.size, q, y2.shape[1]), np.nan)
    Ginv = np.full((at.size, q, q), np.nan)
    if ok.any():
        coef[ok] = np.linalg.solve(G[ok], B[ok])
        Ginv[ok] = np.linalg.inv(G[ok])
    return coef, Ginv, ok, ref


def _evaluate(coef: np.ndarray, Ginv: np.ndarray, ok: np.ndarray, u: np.ndarray, polyorder: int, scale: float):
    """Value and derivatives of each fit at its offset ``u``, and the variance factor of its second derivative.

    ``scale`` is ``h dt`` [s]. Returns ``[y, y_dot, y_ddot]`` (each (m, k)) and ``P''(u)^T G^-1 P''(u)`` (m,),
    inf where the fit is undetermined. The centred fits (``u = 0``) share one evaluation vector.
    """
    centred = u == 0
    off = ~centred
    m, k = coef.shape[0], coef.shape[2]
    out = [np.empty((m, k)) for _ in range(3)]
    for d in (0, 1, 2):
        g = _basis_at(np.zeros(1), polyorder, d)[0]
        out[d][centred] = np.einsum("k,nkc->nc", g, coef[centred]) / scale ** d
        if off.any():
            out[d][off] = np.einsum("nk,nkc->nc", _basis_at(u[off], polyorder, d), coef[off]) / scale ** d
    var2 = np.full(m, np.inf)
    c_ok, o_ok = centred & ok, off & ok
    g2 = _basis_at(np.zeros(1), polyorder, 2)[0]
    var2[c_ok] = np.einsum("i,nij,j->n", g2, Ginv[c_ok], g2)
    if o_ok.any():
        v = _basis_at(u[o_ok], polyorder, 2)
        var2[o_ok] = np.einsum("ni,nij,nj->n", v, Ginv[o_ok], v)
    return out, var2
