"""What the selection compares and how.

The base model plus candidate effects (:class:`Model`, its parameters ``[h, theta...]``), its joint fit with h
(:func:`fit_model`), its held-out residual over folds (:func:`held_out`), whether a candidate can show in the residual
at all (:func:`detectability`) and whether a fitted model is physically admissible (:func:`admissibility`).

The residual of a model is ``M_d1 - M_d2 = R m11 (w . (M q_ddot + h - Q_g - dQ)) / D``
(:mod:`euc_ros.core.model.torque`), so an extra force with ``w . dQ = 0`` cannot change it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import optimize, stats

from euc_ros.core.model.candidate import Candidate
from euc_ros.core.model.extended import HELD_H, Model
from euc_ros.core.model.terms import bias_terms, consistency_weights, gravity_forces, mass_matrix
from euc_ros.core.residual.folds import folds_of
from euc_ros.core.states.contexts import Recording

#: Relative tolerance of the least-squares fits: a cost change of 1e-6 moves a parameter by ~1e-3 of its
#: standard error, far below what the selection can resolve (scipy's default 1e-8 took ~40 evaluations).
FIT_TOL = 1e-6


#: An effect is undetectable when its generalized force projects on w = [R, 1, 1] by less than this
#: fraction of its size (it lies in the span of the input directions).
DETECTABILITY_TOL = 1e-6


#: Plausible rider CoG heights above the ankle hinge [m] (adult riders standing on pedals: the paper's
#: 0.61 m, +-0.3 m for build, posture and session geometry); a model whose h leaves it is not selected.
H_PLAUSIBLE = (0.3, 1.2)


#: A model's h may differ from the geometric one (median |G - A| of the segment CoG over the hinge, from
#: the session's mass fractions and CoM positions) by at most this much [m]. Measured: with an effect in
#: the data the base model's h can be 0.5 m off (a 4 deg slope: 0.12 m for a true 0.61 m), so the base
#: model is no reference; the segments' geometry is (session CoM errors of 1-3 cm move it by < 0.05 m).
H_MAX_GEOMETRIC_DEV_M = 0.15


#: A parameter closer than this fraction of its range to a bound is "on the bound".
AT_BOUND_FRACTION = 1e-3


@dataclass
class Fit:
    """A model fitted on some recordings.

    Parameters
    ----------
    model : Model
        The model.
    x : ndarray
        Its fitted parameters ``[h, theta...]`` (h [m]).
    rmse : float
        The residual's RMS over the usable samples [N m].
    n : int
        Usable samples.
    """

    model: Model
    x: np.ndarray
    rmse: float
    n: int

    @property
    def h(self) -> float:
        """Fitted CoG height [m]."""
        return float(self.x[0])


def _stack_residual(model: Model, recs: Sequence[Recording], x: np.ndarray) -> np.ndarray:
    parts = [model.residual(r, x)[0] for r in recs]
    return np.concatenate(parts) if parts else np.zeros(0)


def fit_model(model: Model, recs: Sequence[Recording], h0: float, fixed: np.ndarray | None = None,
              start: np.ndarray | None = None) -> Fit:
    """Least-squares fit of h and the effects' parameters to zero residual on ``recs``.

    Several starting points (multi-modal parameters such as a period) are tried and the best is kept,
    unless one ``start`` is given (e.g. the fit on all data, as the start of a fold's fit).

    Parameters
    ----------
    model : Model
        The model.
    recs : sequence of Recording
        The recordings fitted.
    h0 : float
        Starting h [m] when ``fixed`` is None.
    fixed : ndarray, optional
        A previous fit (h and the effects before the new ones), the head of every start.
    start : ndarray, optional
        The one starting point (instead of the model's starts).

    Returns
    -------
    Fit
        The best fit over the starts (clipped inside the bounds).

    Raises
    ------
    RuntimeError
        When the fit fails from every start.
    """
    lo, hi = model.bounds()
    best = None
    for x0 in ([start] if start is not None else model.starts(h0, fixed)):
        x0 = np.clip(x0, lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
        try:
            sol = optimize.least_squares(lambda x: _stack_residual(model, recs, x), x0, bounds=(lo, hi),
                                         x_scale=model.scales(), method="trf", max_nfev=200 * len(x0),
                                         ftol=FIT_TOL, xtol=FIT_TOL, gtol=FIT_TOL)
        except ValueError:
            continue
        cost = float(np.sum(sol.fun ** 2))
        if best is None or cost < best[0]:
            best = (cost, sol.x)
    if best is None:
        raise RuntimeError(f"fit of model {model.name} failed from every start")
    masks = [model.residual(r, best[1])[1] for r in recs]
    n = int(sum(int(m.sum()) for m in masks))
    return Fit(model, best[1], math.sqrt(best[0] / max(n, 1)), n)


#: Coarse grid of :func:`fit_base_h` [m].
BASE_H_GRID = np.linspace(0.1, 1.2, 45)


def h_freed(recs: Sequence[Recording]) -> list[Recording]:
    """The recordings with h free again: copies without a held h (:data:`~euc_ros.core.model.extended.HELD_H`).

    Parameters
    ----------
    recs : sequence of Recording
        The prepared recordings (their arrays are shared, never modified).

    Returns
    -------
    list of Recording
    """
    out = []
    for rec in recs:
        ctx = rec.ctx.copy()
        ctx.extras = {k: v for k, v in ctx.extras.items() if k != HELD_H}
        out.append(Recording(rec.name, ctx, rec.block, rec.index))
    return out


def fit_base_h(recs: Sequence[Recording], h_grid=BASE_H_GRID) -> float:
    """Grid-then-refine estimate of h with the base model (a good start for every joint fit).

    Parameters
    ----------
    recs : sequence of Recording
        The recordings.
    h_grid : array_like
        The coarse grid [m], ascending; the refinement is bounded by the best point's neighbours.

    Returns
    -------
    float
        h [m] of least squared residual.
    """
    base = Model()
    sse = [float(np.sum(_stack_residual(base, recs, np.array([h])) ** 2)) for h in h_grid]
    k = int(np.argmin(sse))
    lo, hi = h_grid[max(k - 1, 0)], h_grid[min(k + 1, len(h_grid) - 1)]
    res = optimize.minimize_scalar(lambda h: float(np.sum(_stack_residual(base, recs, np.array([h])) ** 2)),
                                   bounds=(lo, hi), method="bounded")
    return float(res.x)


def detectability(candidate: Candidate, recs: Sequence[Recording], h: float) -> float:
    """Fraction of the candidate's generalized force that is visible in M_d1 - M_d2.

    The generalized-force equivalent of a unit-scale parameter change is compared with its
    projection on ``w = [R, 1, 1]`` (which annihilates b_d and b_d): 0 means it lies in
    span(b_d, b_h) and cannot show in the residual.

    Parameters
    ----------
    candidate : Candidate
        The candidate, at its first start plus one scale of each parameter.
    recs : sequence of Recording
        The recordings.
    h : float
        The CoG height it is evaluated at [m].

    Returns
    -------
    float
        The visible fraction, 0 to 1 (0 when the candidate adds no force).
    """
    model = Model([candidate])
    num = den = 0.0
    for rec in recs:
        x0 = np.concatenate([[h], candidate.starts()[0]])
        x1 = x0.copy()
        x1[1:] += np.array([q.scale for q in candidate.params])
        dQ = _equivalent_force(model, rec, x1) - _equivalent_force(model, rec, x0)
        w = consistency_weights(rec.ctx.params)
        proj = dQ @ np.asarray(w, float) / np.linalg.norm(w)
        num += float(np.nansum(proj ** 2))
        den += float(np.nansum(dQ ** 2))
    return math.sqrt(num / den) if den > 0 else 0.0


def _equivalent_force(model: Model, rec: Recording, x: np.ndarray) -> np.ndarray:
    """Generalized force a model adds, in the base model's terms: f_base - f_model (n, 3)."""
    h, thetas = model.split(x)
    ctx = rec.ctx.copy()
    ctx.params = ctx.params.with_h(h)
    for c, th in zip(model.effects, thetas):
        c.modify(ctx, th)
    for c, th in zip(model.effects, thetas):
        dQ = c.force(ctx, th)
        if dQ is not None:
            ctx.add_force(dQ)
    n = ctx.t.shape[0]
    q = np.stack([np.zeros(n), ctx.gamma, ctx.phi], 1)
    qd = np.stack([ctx.x_dot, ctx.gamma_dot, ctx.phi_dot], 1)
    qdd = np.stack([ctx.x_ddot, ctx.gamma_ddot, ctx.phi_ddot], 1)
    p = ctx.p()
    f = np.einsum("nij,nj->ni", np.broadcast_to(mass_matrix(q, p), (n, 3, 3)), qdd) + bias_terms(q, qd, p) \
        - gravity_forces(q, p)
    if ctx.extra_Q is not None:
        f = f - ctx.extra_Q
    return -f


def model_jacobian(model: Model, recs: Sequence[Recording], x: np.ndarray, res0=None
                   ) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Per recording: residual at ``x``, its usable mask and d(residual)/dx by forward differences.

    Steps of 1e-4 of each parameter's typical scale, inward at a bound.

    Parameters
    ----------
    model : Model
        The model.
    recs : sequence of Recording
        The recordings.
    x : ndarray (p,)
        The parameters ``[h, theta...]``.
    res0 : list of tuple, optional
        Per recording, ``model.residual`` at ``x`` (residual, mask), when already computed.

    Returns
    -------
    residuals : list of ndarray
        Per recording, the residual at ``x`` (n_i,) [N m].
    masks : list of ndarray
        Per recording, its usable samples (bool, n_i).
    jacobians : list of ndarray
        Per recording, d(residual)/dx (n_i, p).
    """
    res0 = res0 or [model.residual(r, x) for r in recs]
    lo, hi = model.bounds()
    steps = 1e-4 * model.scales()
    J = [np.empty((r.ctx.t.shape[0], x.size)) for r in recs]
    for k in range(x.size):
        x1 = np.array(x, float)
        step = steps[k] if x1[k] + steps[k] <= hi[k] else -steps[k]
        x1[k] += step
        for i, r in enumerate(recs):
            J[i][:, k] = (model.residual(r, x1)[0] - res0[i][0]) / step
    return [a for a, _ in res0], [m for _, m in res0], J


def held_out(model: Model, recs: Sequence[Recording], h0: float, folds=None,
             fixed: np.ndarray | None = None, start: np.ndarray | None = None) -> HeldOut:
    """Fit on each fold's training samples, collect the residual on its held-out samples.

    The fold fits are Gauss-Newton steps from the fit on all data (``start``; fitted here without it):
    the model's Jacobian is evaluated once, each fold's parameters are ``x + dx`` with ``dx`` the
    linear least-squares step on its training rows (clipped to the bounds), and the held-out residual is
    the model evaluated at those parameters. The fold optima lie close to the full one (each fold drops a
    small part of the data), where one step of Gauss-Newton is the standard approximate leave-out fit;
    ``test_heldout.py`` compares it with refitting every fold from scratch.

    Parameters
    ----------
    model : Model
        The model.
    recs : sequence of Recording
        The recordings, with their blocks.
    h0 : float
        Starting h of the fit on all data [m] (without ``start``).
    folds : list of Fold, optional
        The folds (default :func:`~.folds.folds_of` with its defaults).
    fixed : ndarray, optional
        A previous fit, the head of the starts of the fit on all data (without ``start``).
    start : ndarray, optional
        The fit on all data.

    Returns
    -------
    HeldOut
        The held-out residual over all folds.
    """
    folds = folds or folds_of(recs)
    if start is None:
        start = fit_model(model, recs, h0, fixed).x
    x = np.asarray(start, float)
    r_all, m_all, J = model_jacobian(model, recs, x)
    lo, hi = model.bounds()
    sc = model.scales()
    offsets = block_offsets(recs)
    starts = np.concatenate([[0], np.cumsum([r.ctx.t.shape[0] for r in recs])])
    res, blocks, params, index = [], [], [], []
    for fold in folds:
        rows = [np.asarray(tr, bool) & m for tr, m in zip(fold.train, m_all)]
        A = np.concatenate([Ji[rw] for Ji, rw in zip(J, rows)]) * sc
        b = -np.concatenate([ri[rw] for ri, rw in zip(r_all, rows)])
        ok = np.all(np.isfinite(A), axis=0)
        dx = np.zeros(x.size)
        if ok.any():
            dx[ok] = np.linalg.lstsq(A[:, ok], b, rcond=None)[0] * sc[ok]
        xf = np.clip(x + dx, lo, hi)
        params.append(xf)
        for i, (r, te) in enumerate(zip(recs, fold.test)):
            if not np.any(te):
                continue
            rr, mask = model.residual(r, xf)
            keep = np.asarray(te, bool) & mask
            res.append(rr[keep])
            blocks.append(r.block[keep] + offsets[i])
            index.append(np.flatnonzero(keep) + starts[i])
    return HeldOut(model, np.concatenate(res) if res else np.zeros(0),
                   np.concatenate(blocks) if blocks else np.zeros(0, int), params,
                   np.concatenate(index) if index else np.zeros(0, int))


def admissibility(model: Model, x: np.ndarray, h_geometric: float) -> str | None:
    """Why a fitted model cannot be selected (None when it can).

    A parameter on its physical bound explains nothing, an h outside :data:`H_PLAUSIBLE` or further than
    :data:`H_MAX_GEOMETRIC_DEV_M` from the segments' geometric h is not this rider.

    Parameters
    ----------
    model : Model
        The model.
    x : ndarray
        Its fitted parameters ``[h, theta...]``.
    h_geometric : float
        The segments' geometric h [m] (NaN: not compared).

    Returns
    -------
    str or None
        The reason, in words; None when admissible.
    """
    lo, hi = model.bounds()
    span = hi - lo
    k = 1
    for c in model.effects:
        for q in c.params:
            v = float(x[k])
            if q.reported and (v - q.low <= AT_BOUND_FRACTION * span[k] or q.high - v <= AT_BOUND_FRACTION * span[k]):
                # a lower bound of 0 reached means "no effect", an upper bound "more than physical"
                return f"{c.name}: {q.name} = {v:.4g} {q.unit} on its physical bound [{q.low:g}, {q.high:g}]"
            k += 1
    h = float(x[0])
    if not H_PLAUSIBLE[0] <= h <= H_PLAUSIBLE[1]:
        return f"h = {h:.3f} m outside the plausible range [{H_PLAUSIBLE[0]}, {H_PLAUSIBLE[1]}] m"
    if math.isfinite(h_geometric) and abs(h - h_geometric) > H_MAX_GEOMETRIC_DEV_M:
        return (f"h = {h:.3f} m is {abs(h - h_geometric):.3f} m from the segments' geometric {h_geometric:.3f} m "
                f"(more than {H_MAX_GEOMETRIC_DEV_M} m)")
    return None


@dataclass(frozen=True)
class Confounding:
    """How far two fitted extensions of one model can be told apart on these recordings.

    Parameters
    ----------
    cosine : float
        Cosine between the two fitted contributions to the residual, each with the current model's
        parameters (h among them) projected out: 1 is the same shape.
    chi2 : float
        What the data hold against the second as a stand-in for the first: the part of the first's
        contribution the second cannot reproduce, ``|d_1|^2 (1 - cosine^2)``, over the residual's variance
        per block (the blocks of the paired test: the residual's correlation length).
    tied : bool
        ``chi2`` below the chi-square(1) quantile at ``1 - level``: the data cannot tell them apart.
    """

    cosine: float
    chi2: float
    tied: bool


def contribution(base: Model, x_base: np.ndarray, extended: Model, x_ext: np.ndarray,
                 recs: Sequence[Recording]) -> tuple[np.ndarray, np.ndarray]:
    """What the last effect of ``extended`` does to the residual of ``base`` with the base parameters kept.

    ``x_ext``'s own first entries are replaced by ``x_base`` (h and the base effects held at the base fit);
    returns ``(r_base - r_extended, usable mask)`` over all recordings.

    Parameters
    ----------
    base : Model
        The current model.
    x_base : ndarray
        Its fitted parameters.
    extended : Model
        ``base`` with one effect added.
    x_ext : ndarray
        Its fitted parameters (only the added effect's are used).
    recs : sequence of Recording
        The recordings.

    Returns
    -------
    d : ndarray
        ``r_base - r_extended`` over all recordings' samples [N m].
    ok : ndarray of bool
        Where both residuals are usable.
    """
    x = np.concatenate([np.asarray(x_base, float), np.asarray(x_ext, float)[np.asarray(x_base).size:]])
    d, ok = [], []
    for r in recs:
        r0, m0 = base.residual(r, x_base)
        r1, m1 = extended.residual(r, x)
        d.append(r0 - r1)
        ok.append(m0 & m1)
    return np.concatenate(d), np.concatenate(ok)


def confounding(base: Model, x_base: np.ndarray, first: tuple[Model, np.ndarray], second: tuple[Model, np.ndarray],
                recs: Sequence[Recording], sigma: float, level: float) -> Confounding:
    """Whether two candidates added to ``base`` are confounded on ``recs`` (:class:`Confounding`).

    Each candidate's fitted contribution (:func:`contribution`) is taken with the base model's sensitivities
    (to h and the current parameters) projected out, which the joint fit absorbs. ``sigma`` is the RMS of
    the residual once ``first`` is fitted [N m]; one block of the paired test counts as one independent
    sample (its length follows the residual's correlation), so the chi-square is per block. ``level`` is
    the test's one-sided level (the paired block test's :data:`~.significance.AMBIGUITY_ALPHA`).

    Parameters
    ----------
    base : Model
        The current model.
    x_base : ndarray
        Its fitted parameters.
    first, second : tuple of (Model, ndarray)
        The two extended models with their fitted parameters.
    recs : sequence of Recording
        The recordings, with the blocks of the paired test.
    sigma : float
        RMS of the residual with ``first`` fitted [N m].
    level : float
        One-sided level of the test.

    Returns
    -------
    Confounding
        NaN measures and not tied when a contribution vanishes or ``sigma`` is not positive.
    """
    d1, m1 = contribution(base, x_base, *first, recs)
    d2, m2 = contribution(base, x_base, *second, recs)
    _, masks, J = model_jacobian(base, recs, np.asarray(x_base, float))
    keep = m1 & m2 & np.concatenate(masks)
    A = np.concatenate(J)[keep]
    A = A[:, np.all(np.isfinite(A), axis=0)]
    Q = np.linalg.qr(A)[0] if A.size else np.zeros((int(keep.sum()), 0))
    p1, p2 = d1[keep] - Q @ (Q.T @ d1[keep]), d2[keep] - Q @ (Q.T @ d2[keep])
    n1, n2 = float(np.linalg.norm(p1)), float(np.linalg.norm(p2))
    if n1 == 0.0 or n2 == 0.0 or not sigma > 0:
        return Confounding(float("nan"), float("nan"), False)
    cos = float(np.clip(p1 @ p2 / (n1 * n2), -1.0, 1.0))
    n_blocks = sum(int(np.unique(r.block).size) for r in recs)
    per_block = keep.sum() / max(n_blocks, 1)
    chi2 = n1 ** 2 * (1.0 - cos ** 2) / (sigma ** 2 * per_block)
    return Confounding(cos, float(chi2), bool(chi2 < stats.chi2.ppf(1.0 - level, 1)))


def plausibility(model: Model, x: np.ndarray) -> list[dict]:
    """The fitted parameters of ``model`` outside their plausible range (:attr:`ParamInfo.plausible`).

    A model with one of them is not named as the explanation, whatever its fit: a quadratic drag at the
    tyre contact fits as the rider's aero_drag with a drag area 2-3 times a standing rider's, a name no
    rider's physics supports.

    Parameters
    ----------
    model : Model
        The model.
    x : ndarray
        Its fitted parameters ``[h, theta...]``.

    Returns
    -------
    list of dict
        The records of :meth:`Candidate.implausible` (empty: plausible).
    """
    _, thetas = model.split(x)
    return [r for c, th in zip(model.effects, thetas) for r in c.implausible(th)]


def refusal(records: list[dict]) -> str | None:
    """One line for refused names: ``refused aero_drag: cda_m2=1.36 outside plausible [0.2, 1]``.

    Parameters
    ----------
    records : list of dict
        Records of :meth:`Candidate.implausible`.

    Returns
    -------
    str or None
        The records joined by ``;`` (None: no record).
    """
    if not records:
        return None
    return "; ".join(f"refused {r['effect']}: {r['parameter']}={r['value']:.4g} outside plausible "
                     f"[{r['plausible'][0]:g}, {r['plausible'][1]:g}]" + (f" {r['unit']}" if r["unit"] != "-" else "")
                     for r in records)


def implausibility(candidate: Candidate, theta) -> float:
    """Size of a candidate's reported-scale parameters in units of their typical magnitude.

    Parameters
    ----------
    candidate : Candidate
        The candidate.
    theta : array_like
        Its parameters (n_params,).

    Returns
    -------
    float
        The norm of the reported parameters over their scales (a periodic h's amplitude over its scale; 0
        without a reported parameter).
    """
    th = np.asarray(theta, float)
    scales = np.array([q.scale for q in candidate.params], float)
    keep = np.array([q.reported for q in candidate.params], bool)
    if hasattr(candidate, "PERIOD_STARTS"):      # time_varying_h: amplitude of (a_sin, a_cos)
        return float(np.hypot(th[0], th[1]) / scales[0])
    return float(np.sqrt(np.sum((th[keep] / scales[keep]) ** 2))) if keep.any() else 0.0


@dataclass
class HeldOut:
    """Held-out residuals of a model over all folds, with their blocks (unique over recordings).

    Parameters
    ----------
    model : Model
        The model.
    residual : ndarray
        The held-out residuals of every fold, fold after fold [N m].
    block : ndarray of int
        Each residual's block, numbered across the recordings (:func:`block_offsets`).
    params : list of ndarray
        Each fold's fitted parameters ``[h, theta...]``.
    index : ndarray of int, optional
        Each residual's sample over the recordings in order.
    """

    model: Model
    residual: np.ndarray
    block: np.ndarray
    params: list[np.ndarray]
    #: Sample of each residual over the recordings in order (None: unknown).
    index: np.ndarray | None = None

    def restricted(self, keep: np.ndarray) -> "HeldOut":
        """The residuals at the positions ``keep``.

        Parameters
        ----------
        keep : ndarray
            Positions in :attr:`residual` (indices or a bool mask).

        Returns
        -------
        HeldOut
            The same model and fold parameters.
        """
        return HeldOut(self.model, self.residual[keep], self.block[keep], self.params,
                       None if self.index is None else self.index[keep])

    @property
    def rmse(self) -> float:
        """Held-out RMSE [N m]."""
        return float(np.sqrt(np.mean(self.residual ** 2))) if self.residual.size else float("nan")


def common_samples(a: HeldOut, b: HeldOut) -> tuple[HeldOut, HeldOut] | None:
    """Two held-out residuals on the samples both have (a time offset drops samples at the runs' ends).

    Parameters
    ----------
    a, b : HeldOut
        The two held-out residuals.

    Returns
    -------
    tuple of HeldOut or None
        ``(a, b)`` restricted to their common samples in the same order, or None when they cannot be paired
        (different lengths and no sample index).
    """
    if a.index is not None and b.index is not None and not (
            a.index.shape == b.index.shape and np.array_equal(a.index, b.index)):
        _, ia, ib = np.intersect1d(a.index, b.index, assume_unique=True, return_indices=True)
        return a.restricted(ia), b.restricted(ib)
    return (a, b) if a.residual.shape == b.residual.shape else None


def block_offsets(recs: Sequence[Recording]) -> list[int]:
    """Per recording, the offset that numbers its blocks after those of the recordings before it.

    Parameters
    ----------
    recs : sequence of Recording

    Returns
    -------
    list of int
        Added to a recording's ``block`` indices, they make the blocks unique across the recordings (a recording
        without samples adds none).
    """
    out, off = [], 0
    for r in recs:
        out.append(off)
        off += int(r.block.max()) + 1 if r.block.size else 0
    return out
