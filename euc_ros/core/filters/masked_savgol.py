"""Savitzky-Golay smoothing and derivatives that use every recorded sample, across gaps.

The Savitzky-Golay estimate at a sample is the least-squares polynomial through the window around it. When
samples are missing (dropped frames, an occluded body) the same least-squares fit can be made through the
samples that are there: :func:`masked_savgol` solves it at every sample, so a gap costs no stretch and no
trimmed edge, only precision where it is. With no sample missing the numbers are Savitzky-Golay's.

Where the fit is ill-determined (too few samples, or all on one side of a long gap) its variance is large;
:func:`masked_savgol` returns, per sample, the variance of the second derivative relative to the full
window's (the *inflation*: 1 with every sample, larger near gaps), and marks a sample usable when it stays
under a bound.

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

#: Largest variance inflation of the second derivative for a sample to be usable (the full window: 1).
MAX_INFLATION = 4.0


@dataclass(frozen=True)
class MaskedDerivatives:
    """Value and derivatives of the local fits, with how well each is determined.

    Attributes
    ----------
    y, y_dot, y_ddot : ndarray (n,) or (n, k)
        The fit's value and its first and second time derivatives [unit, unit/s, unit/s^2]; NaN where
        the fit is not determined.
    inflation : ndarray (n,)
        Variance of the second derivative over that of the full window (1 with every sample; inf where
        undetermined).
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


def masked_savgol(y, window: int, polyorder: int, dt: float, *,
                  max_inflation: float = MAX_INFLATION) -> MaskedDerivatives:
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

    Returns
    -------
    MaskedDerivatives

    Raises
    ------
    ConfigError
        A window that is not odd and longer than the order, or a spacing that is not positive.
    InputError
        ``y`` of another shape.

    Notes
    -----
    In the normalised time ``u_j = j / h`` (``j = -h..h``, ``h = (window - 1) / 2``) with Legendre
    polynomials ``P_0..P_p``, the fit at sample ``i`` solves ``G_i a_i = b_i`` with
    ``G_i = sum_j m_{i+j} P(u_j) P(u_j)^T`` and ``b_i = sum_j m_{i+j} y_{i+j} P(u_j)`` (``m`` the recorded
    mask). Every entry of ``G_i`` and ``b_i`` is a correlation of the mask (or of the masked samples) with a
    fixed kernel, so all fits come from ``(p + 1)(p + 2) / 2 + (p + 1) k`` correlations and one batched solve.
    The ``d``-th derivative at the window's centre is ``P^(d)(0) . a_i / (h dt)^d`` and its variance is
    proportional to ``P''(0)^T G_i^-1 P''(0)``; with every sample recorded ``G_i`` is the full window's and the
    fit is Savitzky-Golay's, number for number up to round-off.
    """
    window, polyorder = int(window), int(polyorder)
    if window % 2 != 1 or window <= polyorder:
        raise ConfigError(f"window must be odd and > polyorder, got {window} and {polyorder}", key="window")
    if not (np.isfinite(dt) and dt > 0):
        raise ConfigError(f"sample spacing must be > 0 s, got {dt!r}", key="dt")
    y = np.asarray(y, dtype=float)
    if y.ndim not in (1, 2):
        raise InputError(f"y must have shape (n,) or (n, k), got {y.shape}", key="y")
    n = y.shape[0]
    y2 = y.reshape(n, -1)
    rec = np.all(np.isfinite(y2), axis=1)
    m = rec.astype(float)
    h = (window - 1) // 2
    u = np.arange(-h, h + 1) / h
    P = legendre.legvander(u, polyorder).T                          # (p + 1, window)
    q = polyorder + 1
    G = np.empty((n, q, q))
    for a in range(q):
        for b in range(a, q):
            G[:, a, b] = G[:, b, a] = _correlate(m, P[a] * P[b])
    # the samples less a constant (it cancels in the derivatives: round-off at the motion's scale)
    ref = np.nanmedian(y2[rec], axis=0) if rec.any() else np.zeros(y2.shape[1])
    ym = np.where(rec[:, None], y2 - ref, 0.0)
    B = np.stack([_correlate(ym, P[a]) for a in range(q)], axis=1)   # (n, p + 1, k)
    eye = np.eye(q)
    g = [np.array([legendre.legval(0.0, legendre.legder(eye[k], d)) if d else legendre.legval(0.0, eye[k])
                   for k in range(q)]) for d in (0, 1, 2)]
    full = P @ P.T
    var_full = float(g[2] @ np.linalg.solve(full, g[2]))
    ok = np.zeros(n, bool)
    with np.errstate(all="ignore"):
        cond = np.linalg.cond(G)
        ok = np.isfinite(cond) & (cond < 1e12) & (np.convolve(m, np.ones(window), mode="same") >= q)
    coef = np.full((n, q, y2.shape[1]), np.nan)
    infl = np.full(n, np.inf)
    if ok.any():
        coef[ok] = np.linalg.solve(G[ok], B[ok])
        infl[ok] = np.einsum("i,nij,j->n", g[2], np.linalg.inv(G[ok]), g[2]) / var_full
    out = [np.einsum("k,nkc->nc", g[d], coef) / (h * dt) ** d for d in (0, 1, 2)]
    out[0] = out[0] + ref
    usable = ok & (infl <= max_inflation)
    shape = y.shape
    return MaskedDerivatives(out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape), infl, usable, rec)
