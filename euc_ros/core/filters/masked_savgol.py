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

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.overlap_add import oaconvolve_many
from euc_ros.core.robust import median

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


def _correlate(x: np.ndarray, kernels):
    """``out[i] = sum_j kernel[j] x[i + j - h]`` along axis 0 (zero outside) per kernel, for (n,) or (n, k) ``x``.

    The kernels have one odd length; a generator of the results, in order, each from scipy's ``oaconvolve``
    with ``x``'s transform made once (:func:`~euc_ros.core.filters.overlap_add.oaconvolve_many`).
    """
    h = (kernels[0].size - 1) // 2
    ks = [kernel[::-1].reshape((-1,) + (1,) * (x.ndim - 1)) for kernel in kernels]
    for full in oaconvolve_many(x, ks, axes=0):
        yield full[h:h + x.shape[0]]


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
    plan = _plan(rec, rows, window, polyorder, ends)
    coef, ref = _solve_centres(y2, rec, plan)
    out = _evaluate(coef[plan.which], plan, polyorder, h * dt)
    out[0] = out[0] + ref
    infl = plan.var2 / plan.var_full
    usable = plan.ok[plan.which] & (infl <= max_inflation)
    shape = (rows.size,) + y.shape[1:]
    return MaskedDerivatives(out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape), infl, usable,
                             rec[rows])


@dataclass(frozen=True)
class _Plan:
    """What the fits of :func:`masked_savgol` depend on besides the samples' values: the recorded mask's part.

    The wanted rows' window centres and offsets, the rows the windows cover, the normal matrices ``G`` (and which
    are determined), the basis vectors of the evaluation and the variance factors. Recordings analysed again with
    other values on the same samples (SIMEX's re-noised replicates, another filter's probe of the same window) share
    it (:func:`_plan` keeps the last few).
    """

    which: np.ndarray               # (rows,): the fit (of ``at``) each wanted row evaluates
    u_at: np.ndarray                # (rows,): each row's offset from its centre [1/h]
    src: np.ndarray                 # the rows the windows cover, run after run
    at: np.ndarray                  # (m,): the centres' places among ``src``
    rec: np.ndarray                 # recorded, of the ``src`` rows
    ok: np.ndarray                  # (m,): determined fits
    G_ok: np.ndarray                # the determined fits' normal matrices
    P: np.ndarray                   # (p + 1, window): the Legendre basis over the window
    centred: np.ndarray             # (rows,): rows evaluated at their centre
    basis: tuple                    # per derivative: (centre vector (p + 1,), off-centre rows' (o, p + 1) or None)
    var2: np.ndarray                # (rows,): P''(u)^T G^-1 P''(u), inf where undetermined
    var_full: float                 # the same for the full window at its centre

    @property
    def nbytes(self) -> int:
        """Bytes of the plan's arrays."""
        arrays = [self.which, self.u_at, self.src, self.at, self.rec, self.ok, self.G_ok, self.P, self.centred,
                  self.var2] + [b for pair in self.basis for b in pair if b is not None]
        return int(sum(a.nbytes for a in arrays))


#: Plans kept by :func:`_plan` (each a few of the wanted rows' small matrices) and the largest kept [bytes].
_PLANS: dict = {}
PLANS_KEPT = 8
PLAN_MAX_BYTES = 8 << 20


def _plan(rec: np.ndarray, rows: np.ndarray, window: int, polyorder: int, ends: str) -> _Plan:
    """The :class:`_Plan` of a recorded mask and wanted rows (the last :data:`PLANS_KEPT` small ones kept).

    The key is the mask and the rows themselves (their bytes), so a kept plan is used only for the same samples.
    """
    key = (rec.size, window, polyorder, ends, np.packbits(rec).tobytes(), rows.tobytes())
    plan = _PLANS.get(key)
    if plan is not None:
        return plan
    plan = _make_plan(rec, rows, window, polyorder, ends)
    if plan.nbytes <= PLAN_MAX_BYTES:
        for a in [plan.which, plan.u_at, plan.src, plan.at, plan.rec, plan.ok, plan.G_ok, plan.P, plan.centred,
                  plan.var2] + [b for pair in plan.basis for b in pair if b is not None]:
            a.setflags(write=False)       # shared by the fits that use it
        while len(_PLANS) >= PLANS_KEPT:
            _PLANS.pop(next(iter(_PLANS)))
        _PLANS[key] = plan
    return plan


def _make_plan(rec: np.ndarray, rows: np.ndarray, window: int, polyorder: int, ends: str) -> _Plan:
    """The :class:`_Plan` of :func:`_plan`, made."""
    n, q, h = rec.size, polyorder + 1, (window - 1) // 2
    centre, u_at = _fit_rows(n, h, rows, ends)
    fit_at, which = np.unique(centre, return_inverse=True)
    P = legendre.legvander(np.arange(-h, h + 1) / h, polyorder).T     # (p + 1, window)
    if fit_at.size == 0:
        src, at, G, ok = np.zeros(0, np.int64), fit_at, np.zeros((0, q, q)), np.zeros(0, bool)
    else:
        src, at = _window_runs(fit_at, h, n)          # only the rows the windows cover, run after run
        m = rec[src].astype(float)
        G = np.empty((at.size, q, q))
        pairs = [(a, b) for a in range(q) for b in range(a, q)]
        for (a, b), corr in zip(pairs, _correlate(m, [P[a] * P[b] for a, b in pairs])):
            G[:, a, b] = G[:, b, a] = corr[at]
        with np.errstate(all="ignore"):
            cond = np.linalg.cond(G)
            count = np.convolve(np.pad(m, h), np.ones(window), mode="valid")          # recorded samples per window
            ok = np.isfinite(cond) & (cond < 1e12) & (count[at] >= q)
    Ginv = np.full((at.size, q, q), np.nan)
    if ok.any():
        Ginv[ok] = np.linalg.inv(G[ok])
    g2 = _basis_at(np.zeros(1), polyorder, 2)[0]
    var_full = float(g2 @ np.linalg.solve(P @ P.T, g2))
    centred = u_at == 0
    off = ~centred
    basis = tuple((_basis_at(np.zeros(1), polyorder, d)[0], _basis_at(u_at[off], polyorder, d) if off.any() else None)
                  for d in (0, 1, 2))
    Ginv, ok_w = Ginv[which], ok[which]
    var2 = np.full(which.size, np.inf)
    c_ok, o_ok = centred & ok_w, off & ok_w
    var2[c_ok] = np.einsum("i,nij,j->n", g2, Ginv[c_ok], g2)
    if o_ok.any():
        v = _basis_at(u_at[o_ok], polyorder, 2)
        var2[o_ok] = np.einsum("ni,nij,nj->n", v, Ginv[o_ok], v)
    return _Plan(which, u_at, src, at, rec[src], ok, G[ok], P, centred, basis, var2, var_full)


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


def _solve_centres(y2: np.ndarray, rec: np.ndarray, plan: _Plan):
    """The coefficients (m, p + 1, k) of the fits of ``plan``'s centres, NaN where undetermined, and ``ref`` (k,).

    The fits are those of the samples less ``ref``, their median.
    """
    q = plan.P.shape[0]
    # the samples less a constant (it cancels in the derivatives: round-off at the motion's scale): their median,
    # numpy's (from 600 rows on nanmedian takes each column's np.median, which robust.median gives bit for bit
    # with less of the selection; the recorded rows have no NaN)
    kept = y2[rec]
    ref = (median(kept, axis=0) if kept.shape[0] >= 600 else np.nanmedian(kept, axis=0)) if rec.any() \
        else np.zeros(y2.shape[1])
    del kept
    if plan.at.size == 0:
        return np.zeros((0, q, y2.shape[1])), ref
    ym = np.where(plan.rec[:, None], y2[plan.src] - ref, 0.0)
    B = np.stack([corr[plan.at] for corr in _correlate(ym, list(plan.P))], axis=1)   # (m, p + 1, k)
    coef = np.full((plan.at.size, q, y2.shape[1]), np.nan)
    if plan.ok.any():
        coef[plan.ok] = np.linalg.solve(plan.G_ok, B[plan.ok])
    return coef, ref


def _evaluate(coef: np.ndarray, plan: _Plan, polyorder: int, scale: float) -> list:
    """Value and derivatives of each fit at its offset: ``[y, y_dot, y_ddot]``, each (m, k).

    ``scale`` is ``h dt`` [s]. The centred fits (``u = 0``) share one evaluation vector.
    """
    centred = plan.centred
    off = ~centred
    m, k = coef.shape[0], coef.shape[2]
    out = [np.empty((m, k)) for _ in range(3)]
    for d, (g, g_off) in enumerate(plan.basis):
        out[d][centred] = np.einsum("k,nkc->nc", g, coef[centred]) / scale ** d
        if g_off is not None:
            out[d][off] = np.einsum("nk,nkc->nc", g_off, coef[off]) / scale ** d
    return out
