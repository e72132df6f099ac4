"""Discovery: a group-sparse combination of flexible function families for what no named effect explains.

After the named effects, the residual may still carry structure. The discovery describes it as forces
that are smooth functions of measured signals acting at physical points, each a generalized force
derived by virtual power:

* points and directions (:data:`~euc_ros.core.residual.families.POINTS`): **x at the contact**
  (``dQ = [F, 0, 0]``), **x at the rider CoG** and **z at the rider CoG** (``dQ = J_G^T F``, J_G of the
  Appendix-A geometry), and a **torque on the rider's pitch** (``dQ = [0, 0, T]``). The residual sees a
  generalized force only through ``R dQ_x + dQ_gamma + dQ_phi`` (the directions orthogonal to b_d and b_h),
  i.e. a horizontal force at height z above the contact only through its moment ``z F`` about the contact:
  its point of application is weakly resolved (through the pitch angles only), and a force at the hand is
  found as the force at the CoG with the same moment (a rope at d = 0.45 m above the hinge:
  ``k (R - l0 + d) / (R - l0 + h)``);
* functions: the families of :mod:`euc_ros.core.residual.families` (lab-position fields, wheel-angle
  Fourier series, speed laws, per-recording drifts, filtered states), each a group of columns at a few
  complexity levels.

Not in the basis: accelerations and pitch angles themselves (terms in them cancel the residual's own
noise on held-out data: measured, 4 such terms took a no-effect ride's held-out RMSE from 0.34 to 0.03 N m,
below its noise floor; the named parameter candidates test them). **Undetectable by construction**: any
internal torque between wheel, EUC body and rider (motor torque, hinge torque, their ripple or friction)
acts along the input directions b_d, b_h and cancels from M_d1 - M_d2; no family is fitted for it and the
result says so (``discovery.undetectable``).

Selection (:func:`discover_terms`): on the residual's sensitivity to each group (the residual is linear in
an extra force, :func:`~.groups.force_map`), with h projected out, group orthogonal matching pursuit
(:func:`~euc_ros.core.residual.search.group_path`) orders the groups within each fold's training data;
the number of groups is the fewest whose held-out error over the analysis' folds is within one standard
error of the best (:func:`~euc_ros.core.residual.search.fewest_within_one_se`). The selection is repeated
around the h the chosen groups imply when they move it; the chosen groups are then fitted jointly with h
(:class:`~.groups.DiscoveredEffect`, one parameter per column) like any candidate, and reported as functions of
their argument with a 95 % band (:meth:`~.groups.DiscoveredEffect.describe`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from euc_ros.core.model.extended import H_BOUNDS, Model
from euc_ros.core.residual.families import FAMILIES, Families, Family
from euc_ros.core.residual.groups import (
    DiscoveredEffect,
    DiscoveryProblem,
    Group,
    RowSensitivities,
    discovery_problem,
    force_map,
    layout,
    point_gains,
)
from euc_ros.core.residual.search import GroupSearch, independent_columns
from euc_ros.core.residual.selection import HeldOut, admissibility, fit_model, held_out
from euc_ros.core.residual.shrinkage import fit_with_free
from euc_ros.core.residual.significance import AMBIGUITY_ALPHA, paired_block_test
from euc_ros.core.states.contexts import Recording

#: What the discovery cannot fit, by construction (reported with its result).
UNDETECTABLE = ("internal torques between wheel, EUC body and rider (motor torque, hinge torque, their ripple "
                "or friction) act along the input directions and cancel from M_d1 - M_d2: not fitted")


#: Most re-linearisations of the discovery around the h its terms imply (Gauss-Newton on the joint fit).
DISCOVERY_RELINEARISE = 3


#: A change of h [m] below which the discovery's linearisation is kept.
DISCOVERY_H_STEP_M = 1e-3


# ------------------------------------------------------------------------------------------ what it returns
@dataclass(frozen=True, eq=False)
class DiscoveryRecord:
    """What one discovery found: the discovered model (or none), its held-out residuals and its JSON record.

    Parameters
    ----------
    model : Model or None
        The current model plus the discovered effect (None when no number of groups beats none).
    x : ndarray or None
        Its parameters fitted jointly with h on all samples.
    heldout : HeldOut or None
        Its held-out residual (:func:`structure_heldout`, or a plain refit per fold when that does not pair).
    selection_heldout : HeldOut or None
        The held-out residual of the groups chosen within each fold (no leakage of the selection into the
        test); None when nothing was found or when it does not pair with the current model's samples.
    heldout_rmse_by_terms : list of float
        Held-out RMSE [N m] with 0, 1, ... groups chosen within the folds.
    terms : int
        Number of groups (0: none).
    families : list of str
        The basis' families (:attr:`Family.key`), duplicates on these recordings dropped.
    undetectable : str
        What no family can fit, by construction.
    linearised_at_h_m : float
        The h [m] of the linearisation kept.
    linearisations_tried_h_m : list of float
        Every h [m] the selection was linearised at.
    """

    model: Model | None
    x: np.ndarray | None
    heldout: HeldOut | None
    selection_heldout: HeldOut | None
    heldout_rmse_by_terms: list[float]
    terms: int
    families: list[str]
    undetectable: str
    linearised_at_h_m: float
    linearisations_tried_h_m: list[float]

    @property
    def found(self) -> bool:
        """Whether a discovered model was fitted."""
        return self.model is not None

    def to_json(self) -> dict:
        """The discovery's JSON record (``discovery`` of the residual JSON, before the analysis adds its test).

        Returns
        -------
        dict
            ``run``, ``heldout_rmse_by_terms``, ``terms``, ``families``, ``undetectable``,
            ``linearised_at_h_m``, ``linearisations_tried_h_m``.
        """
        return {"run": True, "heldout_rmse_by_terms": list(self.heldout_rmse_by_terms), "terms": self.terms,
                "families": list(self.families), "undetectable": self.undetectable,
                "linearised_at_h_m": self.linearised_at_h_m,
                "linearisations_tried_h_m": list(self.linearisations_tried_h_m)}


def order_groups(problem: DiscoveryProblem, r0: np.ndarray, BT: np.ndarray, hc: np.ndarray, blocks: np.ndarray,
                 slices: list[slice]) -> list[list[int]]:
    """The search on the turned columns as rows ``BT``.

    Here h is projected out of ``BT``, then the search normalises it: both in place.

    Parameters
    ----------
    problem : DiscoveryProblem
    r0 : ndarray
        The residual on the rows.
    BT : ndarray
        The turned columns as rows (:meth:`Layout.rows`); changed in place.
    hc : ndarray
        The residual's derivative in h.
    blocks : ndarray of int
        Each row's block.
    slices : list of slice
        Each group's rows of ``BT``.

    Returns
    -------
    list of list of int
        The best set of groups of each size.
    """
    u = hc / max(np.linalg.norm(hc), 1e-300)
    p = BT @ u
    for a in range(0, BT.shape[0], 64):     # the outer product by rows: no temporary the size of BT
        BT[a:a + 64] -= np.outer(p[a:a + 64], u)
    return problem.search.path(r0 - u * (u @ r0), (BT, [sl.stop - sl.start for sl in slices]), problem.keys,
                               n_eff=problem.n_eff_per_block * float(np.unique(blocks).size), n_fixed=1,
                               kinds=[g.family for g in problem.groups], extra_df=problem.extra_df)


def _independent(chosen: list[int], BpT: np.ndarray, slices: list[slice]) -> np.ndarray:
    """The chosen groups' columns that add a direction (``BpT``: h projected out, as rows, any scale)."""
    cols = np.concatenate([np.arange(slices[j].start, slices[j].stop) for j in chosen])
    return cols[independent_columns(BpT[cols].T)]


def _as_groups(problem: DiscoveryProblem, chosen: list[int], cols: np.ndarray, slices: list[slice],
               phases: list) -> list[Group]:
    out = []
    for j in chosen:
        local = cols[(cols >= slices[j].start) & (cols < slices[j].stop)] - slices[j].start
        if local.size:
            g = problem.groups[j]
            out.append(Group(g.family, g.level, g.point, tuple(int(i) for i in local), phases[j]))
    return out


def group_scales(BT: np.ndarray, slices: list[slice]) -> np.ndarray:
    """Each column's prior scale: the root mean square of its group's columns' norms (``BT``: columns as rows).

    Parameters
    ----------
    BT : ndarray (columns, rows)
    slices : list of slice
        Each group's rows of ``BT``.

    Returns
    -------
    ndarray (columns,)
    """
    sq = np.einsum("ij,ij->i", BT, BT)
    out = np.empty(BT.shape[0])
    for sl in slices:
        out[sl] = np.sqrt(np.mean(sq[sl])) if sl.stop > sl.start else 1.0
    return out


# ----------------------------------------------------------------------------------------- the linearisation
@dataclass(frozen=True, eq=False)
class Linearisation:
    """The current model's residual linearised at one h: residual, sensitivities to a force and to h.

    Parameters
    ----------
    h_lin : float or None
        The h linearised at (None: the current model's own fit, and each fold's own h).
    x_lin : ndarray
        The parameters linearised at.
    force_maps : list of ndarray
        Per recording, the residual's change per unit generalized force (:func:`force_map`).
    base : list of (ndarray, ndarray)
        Per recording, the residual and its usable mask at ``x_lin``.
    hcol : list of ndarray
        Per recording, the residual's derivative in h.
    """

    h_lin: float | None
    x_lin: np.ndarray
    force_maps: list[np.ndarray]
    base: list[tuple[np.ndarray, np.ndarray]]
    hcol: list[np.ndarray]


def linearise(problem: DiscoveryProblem, h_lin: float | None) -> Linearisation:
    """The current model's residual linearised at ``h_lin`` (None: at its own fit).

    Parameters
    ----------
    problem : DiscoveryProblem
    h_lin : float or None

    Returns
    -------
    Linearisation
    """
    current, recs = problem.current, problem.recs
    x_lin = np.array(problem.current_x, float)
    if h_lin is not None:
        x_lin[0] = h_lin
    L = force_map(current, recs, x_lin)
    base = [current.residual(r, x_lin) for r in recs]
    dh = 1e-3
    x1 = x_lin.copy()
    x1[0] += dh
    hcol = [(current.residual(r, x1)[0] - b[0]) / dh for r, b in zip(recs, base)]
    return Linearisation(h_lin, x_lin, L, base, hcol)


def _sensitivities(problem: DiscoveryProblem, lin: Linearisation, rows) -> RowSensitivities:
    return RowSensitivities(problem.basis, [(problem.recs[i].ctx, lin.force_maps[i], rw) for i, rw in rows],
                            problem.groups)


# --------------------------------------------------------------------------------------------- the selection
@dataclass(frozen=True, eq=False)
class GroupChoice:
    """The groups one linearisation chose: their number by held-out error, then fitted on all rows.

    Parameters
    ----------
    rmse : dict of int to float
        Held-out RMSE [N m] with k groups chosen within the folds.
    best_k : int
        The number of groups (0: none).
    complete : dict of int to ndarray
        The held-out residuals with k groups (every fold).
    chosen : list of Group or None
        The chosen groups, their columns that add a direction (None: none).
    c : ndarray or None
        Their coefficients on the linearised residual.
    dh : float
        The change of h fitted with them.
    """

    rmse: dict[int, float]
    best_k: int
    complete: dict[int, np.ndarray]
    chosen: list[Group] | None
    c: np.ndarray | None
    dh: float


def fold_errors(problem: DiscoveryProblem, lin: Linearisation) -> tuple[dict[int, list[np.ndarray]], list]:
    """Per number of groups k, each fold's held-out residual with the k groups the search chose on its training rows.

    On those rows h and the groups' coefficients are fitted, the coefficients shrunk.

    Parameters
    ----------
    problem : DiscoveryProblem
    lin : Linearisation

    Returns
    -------
    per_k : dict of int to list of ndarray
        Per k, the folds' held-out residuals (k = 0: without groups).
    test_blocks : list of ndarray
        Per fold, the held-out rows' blocks.
    """
    recs, h_lin = problem.recs, lin.h_lin
    offsets, hcol = problem.offsets, lin.hcol
    per_k: dict[int, list[np.ndarray]] = {}
    test_blocks = []
    for fold, x_fold in zip(problem.folds, problem.current_ho.params):
        x_fold = np.array(x_fold, float)
        if h_lin is not None:
            x_fold[0] = h_lin
        fres = [problem.current.residual(r, x_fold) if np.any(te) or np.any(tr) else None
                for r, tr, te in zip(recs, fold.train, fold.test)]
        idx = [i for i, f in enumerate(fres) if f is not None]
        tr_rows = [(i, np.asarray(fold.train[i], bool) & fres[i][1]) for i in idx]
        r0 = np.concatenate([fres[i][0][rw] for i, rw in tr_rows])
        hc = np.concatenate([hcol[i][rw] for i, rw in tr_rows])
        Braw = _sensitivities(problem, lin, tr_rows)
        lay = layout(problem, r0, Braw, hc)
        blocks = np.concatenate([recs[i].block[rw] + offsets[i] for i, rw in tr_rows])
        BT = lay.rows(Braw)
        # the prior's scale: a group's columns alike (a spline piece the training rows hardly visit is held
        # to the size of its neighbours, not to its own few samples)
        scale = group_scales(BT, lay.slices)
        sets = order_groups(problem, r0, BT, hc, blocks, lay.slices)
        te_rows = [(i, np.asarray(fold.test[i], bool) & fres[i][1]) for i in idx if np.any(fold.test[i])]
        r0t = np.concatenate([fres[i][0][rw] for i, rw in te_rows])
        Braw_t = _sensitivities(problem, lin, te_rows)
        hct = np.concatenate([hcol[i][rw] for i, rw in te_rows])
        test_blocks.append(np.concatenate([recs[i].block[rw] + offsets[i] for i, rw in te_rows]))
        if h_lin is None:
            per_k.setdefault(0, []).append(r0t)
        else:
            c0 = -(hc @ r0) / max(hc @ hc, 1e-300)
            per_k.setdefault(0, []).append(r0t + hct * c0)
        for k, chosen in enumerate(sets, start=1):
            cols = _independent(chosen, BT, lay.slices)
            c = fit_with_free(hc, lay.columns(Braw, cols), -r0,
                              n_eff=problem.n_eff_per_block * float(np.unique(blocks).size), norms=scale[cols])
            per_k.setdefault(k, []).append(r0t + hct * c[0] + lay.columns(Braw_t, cols) @ c[1:])
        del BT, Braw, Braw_t        # not held while the next fold's are made
    return per_k, test_blocks


def select(problem: DiscoveryProblem, h_lin: float | None, most: int | None = None) -> GroupChoice:
    """The groups chosen linearised at ``h_lin``.

    ``h_lin`` None: at the current model's fit, in each fold its own h; else at ``h_lin``, h refitted within each fold's
    training data, also without groups. Their number is chosen by the held-out error of :func:`fold_errors` (the
    search's parsimony rule), the groups themselves by the search on all rows.

    Parameters
    ----------
    problem : DiscoveryProblem
    h_lin : float or None
    most : int, optional
        At most this many groups (the search path's first ones).

    Returns
    -------
    GroupChoice
    """
    recs = problem.recs
    lin = linearise(problem, h_lin)
    per_k, test_blocks = fold_errors(problem, lin)
    complete = {k: np.concatenate(v) for k, v in per_k.items() if len(v) == len(problem.folds)}
    rmse = {k: float(np.sqrt(np.mean(v ** 2))) for k, v in complete.items()}
    # parsimony: the fewest groups within one standard error of the best held-out error
    best_k = problem.search.size(complete, np.concatenate(test_blocks))
    if most is not None:
        best_k = min(best_k, int(most))
    if best_k == 0:
        return GroupChoice(rmse, 0, complete, None, None, 0.0)
    rows = [b[1] for b in lin.base]
    r0 = np.concatenate([b[0][m] for b, m in zip(lin.base, rows)])
    hc = np.concatenate([h[m] for h, m in zip(lin.hcol, rows)])
    Braw = _sensitivities(problem, lin, list(enumerate(rows)))
    lay = layout(problem, r0, Braw, hc)
    blocks = np.concatenate([r.block[m] + o for r, m, o in zip(recs, rows, problem.offsets)])
    BT = lay.rows(Braw)
    sets = order_groups(problem, r0, BT, hc, blocks, lay.slices)
    if not sets:
        return GroupChoice(rmse, 0, complete, None, None, 0.0)
    chosen = sets[min(best_k, len(sets)) - 1]
    cols = _independent(chosen, BT, lay.slices)
    c, *_ = np.linalg.lstsq(np.column_stack([hc, lay.columns(Braw, cols)]), -r0, rcond=None)
    return GroupChoice(rmse, best_k, complete, _as_groups(problem, chosen, cols, lay.slices, lay.phases), c[1:],
                       float(c[0]))


# ------------------------------------------------------------------------------------------------ the refit
@dataclass(frozen=True, eq=False)
class Refit:
    """A choice of groups fitted jointly with h and every parameter, and its held-out residual.

    Parameters
    ----------
    model : Model
        The current model plus the discovered effect.
    x : ndarray
        Its parameters fitted on all samples.
    heldout : HeldOut
        Its held-out residual (:func:`structure_heldout`, or a plain refit per fold).
    choice : GroupChoice
        The choice fitted.
    h_lin : float
        The h the choice was linearised at.
    k : int
        The discovered columns.
    """

    model: Model
    x: np.ndarray
    heldout: HeldOut
    choice: GroupChoice
    h_lin: float
    k: int


def refit(problem: DiscoveryProblem, choice: GroupChoice, h_lin: float) -> Refit | None:
    """The chosen groups fitted jointly with h and all parameters, and their held-out residual.

    Parameters
    ----------
    problem : DiscoveryProblem
    choice : GroupChoice
    h_lin : float
        The h the choice was linearised at.

    Returns
    -------
    Refit or None
        None when the choice has no group.
    """
    if choice.best_k == 0:
        return None
    c = choice.c
    eff = DiscoveredEffect(problem.basis, choice.chosen, [max(abs(v), 1e-6) for v in c], start=c)
    model = Model(problem.current.effects + [eff])
    start = np.concatenate([problem.current_x, c])
    start[0] = float(np.clip(h_lin + choice.dh, *H_BOUNDS))
    full = fit_model(model, problem.recs, problem.h0, start=start)
    ho = structure_heldout(problem, model, choice.chosen, float(np.clip(full.x[0], *H_BOUNDS)))
    if ho is None:
        ho = held_out(model, problem.recs, problem.h0, problem.folds, start=full.x)
    return Refit(model, full.x, ho, choice, h_lin, int(c.size))


def structure_heldout(problem: DiscoveryProblem, model: Model, chosen: list[Group], h_lin: float
                      ) -> HeldOut | None:
    """Held-out residual of the chosen groups as the selection judged them.

    In each fold h and the groups' coefficients fitted on the training rows (linearised at ``h_lin``, the coefficients
    shrunk, :func:`~euc_ros.core.residual.shrinkage.fit_with_free`).

    A plain refit of many flexible columns in each fold (Gauss-Newton from the fit on all data) is as
    ill-determined as the selection's would be without the prior: a lab field's spline piece a fold hardly
    visits gets any size.

    Parameters
    ----------
    problem : DiscoveryProblem
    model : Model
        The current model plus the discovered effect.
    chosen : list of Group
    h_lin : float

    Returns
    -------
    HeldOut or None
        None when the samples do not pair with the current model's held-out ones.
    """
    current, recs, basis, current_ho = problem.current, problem.recs, problem.basis, problem.current_ho
    x_lin = np.array(problem.current_x, float)
    x_lin[0] = h_lin
    L = force_map(current, recs, x_lin)
    cols = []
    for r, Li in zip(recs, L):
        gains = point_gains(r.ctx, Li)
        raw = basis.columns(r.ctx, [(g.family, g.level) for g in chosen])
        cols.append(np.concatenate([g.of(basis, gains[:, g.point, None] * raw[(g.family, g.level)])
                                    for g in chosen], axis=1))
    width = [g.columns(basis).size for g in chosen]
    e = np.concatenate([[0], np.cumsum(width)]).astype(int)
    slices = [slice(a, b) for a, b in zip(e[:-1], e[1:])]
    res = []
    for fold, x_fold in zip(problem.folds, current_ho.params):
        x_fold = np.array(x_fold, float)
        x_fold[0] = h_lin
        x1 = x_fold.copy()
        x1[0] += 1e-3
        fres = [current.residual(r, x_fold) for r in recs]
        hcol = [(current.residual(r, x1)[0] - f[0]) / 1e-3 for r, f in zip(recs, fres)]
        tr_rows = [(i, np.asarray(fold.train[i], bool) & fres[i][1]) for i in range(len(recs))]
        te_rows = [(i, np.asarray(fold.test[i], bool) & fres[i][1]) for i in range(len(recs))
                   if np.any(fold.test[i])]
        r0 = np.concatenate([fres[i][0][rw] for i, rw in tr_rows])
        hc = np.concatenate([hcol[i][rw] for i, rw in tr_rows])
        B = np.concatenate([cols[i][rw] for i, rw in tr_rows])
        blocks = np.concatenate([recs[i].block[rw] + problem.offsets[i] for i, rw in tr_rows])
        c = fit_with_free(hc, B, -r0, n_eff=problem.n_eff_per_block * float(np.unique(blocks).size),
                          norms=group_scales(B.T, slices))
        r0t = np.concatenate([fres[i][0][rw] for i, rw in te_rows])
        hct = np.concatenate([hcol[i][rw] for i, rw in te_rows])
        Bt = np.concatenate([cols[i][rw] for i, rw in te_rows])
        res.append(r0t + hct * c[0] + Bt @ c[1:])
    residual = np.concatenate(res) if res else np.zeros(0)
    if residual.shape != current_ho.residual.shape:
        return None
    return HeldOut(model, residual, current_ho.block, [], current_ho.index)


def preferred(a: Refit | None, b: Refit | None) -> Refit | None:
    """The better of two discovered models by held-out error; a tie goes to the one with fewer columns.

    A tie: the better not significantly better (paired block test at :data:`~.significance.AMBIGUITY_ALPHA`).

    Parameters
    ----------
    a, b : Refit or None

    Returns
    -------
    Refit or None
    """
    if a is None or b is None:
        return a if b is None else b
    lo, hi = (a, b) if a.heldout.rmse <= b.heldout.rmse else (b, a)
    if hi.k < lo.k and paired_block_test(hi.heldout, lo.heldout) >= AMBIGUITY_ALPHA:
        return hi
    return lo


def preferred_admissible(tried: Sequence[Refit | None], best: Refit | None, h_geometric: float) -> Refit | None:
    """``best`` when it is admissible; else the preferred admissible model of every linearisation tried, if any.

    A re-linearisation can follow groups that trade with h out of the rider's geometric window (a force
    proportional to the pitch acceleration acts like a change of inertia); a model whose h is not admissible
    explains nothing about this rider, so an admissible one from another linearisation is kept before it.

    Parameters
    ----------
    tried : sequence of Refit or None
        The discovered model of each linearisation.
    best : Refit or None
        The preferred of them (:func:`preferred`).
    h_geometric : float
        The segments' geometric h [m] (NaN: h is not compared with it).

    Returns
    -------
    Refit or None
    """
    if best is None or admissibility(best.model, best.x, h_geometric) is None:
        return best
    out = None
    for r in tried:
        if r is not None and admissibility(r.model, r.x, h_geometric) is None:
            out = preferred(out, r)
    return best if out is None else out


def admissible_subset(problem: DiscoveryProblem, best: Refit | None, first: GroupChoice,
                      h_geometric: float) -> Refit | None:
    """``best``, or the largest of its search path's smaller sets whose joint fit is admissible.

    A group that moves h with the force it stands for (a vertical force at the rider's CoG acts like a weight) can
    carry the joint fit's h out of the rider's geometric window
    (:func:`~euc_ros.core.residual.selection.admissibility`) while the groups before it on the search path
    explain the structure with an h inside it: those are refitted, one group fewer at a time, and the first
    admissible one is the discovered model (its held-out error is judged as any other's).

    Parameters
    ----------
    problem : DiscoveryProblem
    best : Refit or None
        The discovered model.
    first : GroupChoice
        The choice linearised at the current model's own fit (its smaller sets are chosen there too).
    h_geometric : float
        The segments' geometric h [m] (NaN: h is not compared with it).

    Returns
    -------
    Refit or None
        ``best`` when it is None or admissible, has one group, or no smaller set is admissible; else the
        largest admissible smaller set.
    """
    if best is None or admissibility(best.model, best.x, h_geometric) is None:
        return best
    h_arg = None if best.choice is first else best.h_lin
    for k in range(best.choice.best_k - 1, 0, -1):
        smaller = refit(problem, select(problem, h_arg, most=k), best.h_lin)
        if smaller is not None and admissibility(smaller.model, smaller.x, h_geometric) is None:
            return smaller
    return best


# ---------------------------------------------------------------------------------------------- the driver
def discover_terms(current: Model, current_x: np.ndarray, recs: Sequence[Recording], folds, h0: float,
                   current_ho: HeldOut, h_geometric: float = float("nan"), *,
                   families: Sequence[Family] = FAMILIES, search: GroupSearch | None = None) -> DiscoveryRecord:
    """The discovery step (:mod:`euc_ros.core.residual.discovery`).

    Groups of family columns chosen by the search within each fold's training data, their number by held-out error (the
    fewest within one standard error of the best), then the chosen groups fitted jointly with h.

    The residual is linear in the groups' coefficients but not in h (the rider's inertia m h^2): the selection
    works on the residual linearised in h. When the effect to discover biased the current model's h far from
    the truth (a rope: 0.26-0.33 m against 0.61), that linearisation is poor and spare groups make up for the
    missing curvature in h. So the selection is also made linearised at the segments' geometric h
    (``h_geometric``, measured, the same the admissibility test uses) and then around the h the chosen groups
    imply (re-linearised at the h of the full fit, at most :data:`DISCOVERY_RELINEARISE` times while h moves
    by more than :data:`DISCOVERY_H_STEP_M`; h is refitted within each fold's training data at every
    linearisation but the first). The discovered models of the linearisations are compared by their held-out
    error after the full (non-linear) fit (:func:`preferred`). The first linearisation is the current model's
    own, so a ride where no other fits better held-out is unchanged.

    Parameters
    ----------
    current : Model
        The model whose residual is searched.
    current_x : ndarray
        Its parameters fitted on all samples.
    recs : sequence of Recording
    folds : sequence of Fold
    h0 : float
        Start of the joint fits [m].
    current_ho : HeldOut
        The current model's held-out residual.
    h_geometric : float
        The segments' geometric h [m] (NaN: not linearised there).
    families : sequence of Family
        The basis' families (default :data:`~.families.FAMILIES`).
    search : GroupSearch, optional
        The search (default :class:`~.search.GroupSearch` with its defaults).

    Returns
    -------
    DiscoveryRecord
    """
    basis = Families([r.ctx for r in recs], families)
    problem = discovery_problem(current, current_x, current_ho, recs, folds, h0, basis,
                                search if search is not None else GroupSearch())
    h_cur = float(current_x[0])
    first = select(problem, None)
    best = refit(problem, first, h_cur)
    tried = [best]
    h_path = [h_cur]
    if math.isfinite(h_geometric) and abs(h_geometric - h_cur) > DISCOVERY_H_STEP_M:
        h_g = float(np.clip(h_geometric, *H_BOUNDS))
        h_path.append(h_g)
        tried.append(refit(problem, select(problem, h_g), h_g))
        best = preferred(best, tried[-1])
    for _ in range(DISCOVERY_RELINEARISE):
        if best is None:
            break
        h_fit = float(np.clip(best.x[0], *H_BOUNDS))
        if abs(h_fit - best.h_lin) < DISCOVERY_H_STEP_M:
            break
        h_path.append(h_fit)
        tried.append(refit(problem, select(problem, h_fit), h_fit))
        nxt = preferred(best, tried[-1])
        if nxt is best:
            break
        best = nxt
    best = preferred_admissible(tried, best, h_geometric)
    best = admissible_subset(problem, best, first, h_geometric)
    choice = first if best is None else best.choice
    record = dict(heldout_rmse_by_terms=[choice.rmse[k] for k in sorted(choice.rmse)], terms=choice.best_k,
                  families=sorted({f.key for f in basis.families}), undetectable=UNDETECTABLE,
                  linearised_at_h_m=h_cur if best is None else best.h_lin, linearisations_tried_h_m=h_path)
    if best is None:
        basis.retain([])
        return DiscoveryRecord(None, None, None, None, **record)
    # the basis goes on with the model: only the chosen groups' columns are kept (the rest are some 700
    # columns of every analysed sample)
    basis.retain([(g.family, g.level) for g in best.model.effects[-1].groups])
    # the held-out residual of the groups chosen within each fold (no leakage of the selection into the test)
    sel = None
    if choice.complete[choice.best_k].shape == current_ho.residual.shape:
        sel = HeldOut(current, choice.complete[choice.best_k], current_ho.block, [], current_ho.index)
    return DiscoveryRecord(best.model, best.x, best.heldout, sel, **record)


# ------------------------------------------------------------------------------------------ the strategies
class Discovery:
    """What the analysis asks of a discovery: forces for structure left in a model's residual.

    Subclasses implement :meth:`discover`; :class:`GroupSparseDiscovery` is the analysis' default.
    """

    def discover(self, current: Model, current_x: np.ndarray, recs: Sequence[Recording], folds, h0: float,
                 current_ho: HeldOut, h_geometric: float = float("nan")) -> DiscoveryRecord:
        """Search the residual of ``current`` for structure (see :func:`discover_terms` for the arguments).

        Parameters
        ----------
        current : Model
        current_x : ndarray
        recs : sequence of Recording
        folds : sequence of Fold
        h0 : float
        current_ho : HeldOut
        h_geometric : float

        Returns
        -------
        DiscoveryRecord
        """
        raise NotImplementedError


@dataclass(frozen=True)
class GroupSparseDiscovery(Discovery):
    """Group-sparse discovery over function families (:func:`discover_terms`).

    Parameters
    ----------
    families : sequence of Family
        The basis (default :data:`~.families.FAMILIES`, or a selection of it).
    search : GroupSearch
        The search over the groups (:class:`~.search.GroupSearch`).
    """

    families: tuple[Family, ...] = FAMILIES
    search: GroupSearch = GroupSearch()

    def discover(self, current: Model, current_x: np.ndarray, recs: Sequence[Recording], folds, h0: float,
                 current_ho: HeldOut, h_geometric: float = float("nan")) -> DiscoveryRecord:
        """:func:`discover_terms` over :attr:`families` with :attr:`search`.

        Parameters
        ----------
        current : Model
        current_x : ndarray
        recs : sequence of Recording
        folds : sequence of Fold
        h0 : float
        current_ho : HeldOut
        h_geometric : float

        Returns
        -------
        DiscoveryRecord
        """
        return discover_terms(current, current_x, recs, folds, h0, current_ho, h_geometric,
                              families=tuple(self.families), search=self.search)
