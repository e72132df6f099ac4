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
an extra force, :func:`force_map`), with h projected out, group orthogonal matching pursuit
(:func:`~euc_ros.core.residual.families.group_path`) orders the groups within each fold's training data;
the number of groups is the fewest whose held-out error over the analysis' folds is within one standard
error of the best (:func:`~euc_ros.core.residual.families.fewest_within_one_se`). The selection is repeated
around the h the chosen groups imply when they move it; the chosen groups are then fitted jointly with h
(:class:`DiscoveredEffect`, one parameter per column) like any candidate, and reported as functions of
their argument with a 95 % band (:meth:`DiscoveredEffect.describe`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import stats

from euc_ros.core.model.effects import Candidate, ParamInfo, jacobian_G
from euc_ros.core.residual.families import (
    POINT_UNITS,
    POINTS,
    Families,
    align_wheel_phases,
    fewest_within_one_se,
    group_path,
    independent_columns,
    n_levels,
    wheel_phase_mix,
)
from euc_ros.core.residual.folds import SAMPLES_PER_BLOCK
from euc_ros.core.residual.selection import H_BOUNDS, HeldOut, Model, block_offsets, fit_model, held_out
from euc_ros.core.residual.shrinkage import fit_with_free
from euc_ros.core.residual.significance import AMBIGUITY_ALPHA, paired_block_test
from euc_ros.core.states.contexts import Recording

#: Most groups a discovered model may have.
MAX_GROUPS = 3
#: What the discovery cannot fit, by construction (reported with its result).
UNDETECTABLE = ("internal torques between wheel, EUC body and rider (motor torque, hinge torque, their ripple "
                "or friction) act along the input directions and cancel from M_d1 - M_d2: not fitted")


def _where(point: int) -> str:
    coord, at = POINTS[point]
    return f"{coord} at the {at}"


@dataclass(frozen=True)
class Group:
    """One discovered group: family ``family`` (index into ``Families.families``) at ``level``, at ``point``;
    ``keep``: the columns fitted (:func:`~euc_ros.core.residual.families.independent_columns`; None: all)."""

    family: int
    level: int
    point: int
    keep: tuple[int, ...] | None = None
    phases: tuple[float, ...] | None = None

    def mix(self) -> np.ndarray | None:
        """For the aligned wheel family with its phase offsets: the matrix from the family's raw columns to the
        group's (:func:`~euc_ros.core.residual.families.wheel_phase_mix`); else None."""
        return None if self.phases is None else wheel_phase_mix(np.asarray(self.phases, float), self.level + 1)

    def columns(self, basis: Families) -> np.ndarray:
        """Indices of the fitted columns among the group's columns (the family's at this level, or their
        phase-aligned combinations)."""
        if self.keep is not None:
            return np.array(self.keep, int)
        M = self.mix()
        return np.arange(M.shape[1] if M is not None else basis.width(self.family, self.level))

    def of(self, basis: Families, C: np.ndarray) -> np.ndarray:
        """The group's fitted columns from the family's raw columns ``C`` (..., raw)."""
        M = self.mix()
        return (C if M is None else C @ M)[..., self.columns(basis)]


def is_aligned(basis: Families, g: Group) -> bool:
    """True for a group of the wheel family with a phase offset per recording."""
    fam = basis.families[g.family]
    return fam.kind == "wheel" and bool(fam.option)


def _json(a):
    """Nested lists of an array with NaN as None."""
    a = np.asarray(a, float)
    if a.ndim == 0:
        return float(a) if np.isfinite(a) else None
    return [_json(v) for v in a]


def point_gains(ctx, force_map_i: np.ndarray) -> np.ndarray:
    """Residual change per unit force at each point (n, len(POINTS)): ``force_map . dQ`` of a unit force."""
    jx, jz = jacobian_G(ctx, ctx.p())
    return np.stack([force_map_i[:, 0], np.sum(force_map_i * jx, axis=1), np.sum(force_map_i * jz, axis=1),
                     force_map_i[:, 2]], axis=1)


class DiscoveredEffect(Candidate):
    """Discovered groups of family columns, fitted like a named candidate (one free coefficient per column)."""

    name = "discovered"

    def __init__(self, basis: Families, groups: Sequence[Group], scales: Sequence[float], start=None):
        self.basis = basis
        self.groups = list(groups)
        self.widths = [g.columns(basis).size for g in self.groups]
        self._keys = list(dict.fromkeys((g.family, g.level) for g in self.groups))    # the columns it needs
        n = int(sum(self.widths))
        self._start = np.zeros(n) if start is None else np.asarray(start, float)
        params = []
        for k, (g, w) in enumerate(zip(self.groups, self.widths)):
            fam = basis.families[g.family]
            for j in range(w):
                params.append(ParamInfo(f"c{k + 1}.{j + 1} {fam.key} on {_where(g.point)}", self.unit(g), -1e6, 1e6,
                                        0.0, max(float(scales[len(params)]), 1e-9)))
        self.params = tuple(params)

    def unit(self, g: Group) -> str:
        """Unit of the group's function: the point's force or torque per unit of the family's factor."""
        per = self.basis.families[g.family].per_unit
        pu = POINT_UNITS[g.point]
        return pu if per == "1" else f"{pu}/({per})"

    def slices(self) -> list[slice]:
        edges = np.concatenate([[0], np.cumsum(self.widths)]).astype(int)
        return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]

    def starts(self):
        return [self._start.copy()]

    def force(self, ctx, theta):
        cols = self.basis.columns(ctx, self._keys)
        n = ctx.t.shape[0]
        dQ = np.zeros((n, 3))
        jx = jz = None
        for g, sl in zip(self.groups, self.slices()):
            f = g.of(self.basis, cols[(g.family, g.level)]) @ np.asarray(theta[sl], float)
            if g.point == 0:
                dQ[:, 0] += f
            elif g.point == 3:
                dQ[:, 2] += f
            else:
                if jx is None:
                    jx, jz = jacobian_G(ctx, ctx.p())
                dQ += (jx if g.point == 1 else jz) * f[:, None]
        return dQ

    def report(self, theta):
        out = {}
        for k, sl in enumerate(self.slices()):
            for j, c in enumerate(np.asarray(theta[sl], float)):
                out[f"discovered_{k + 1}_{j + 1}"] = float(c)
        return out

    def describe(self, theta, cov: np.ndarray | None = None, dof: int = 0) -> list[dict]:
        """JSON rows, one per group: what it is, where it acts, and its function with a 95 % band.

        Parameters
        ----------
        theta : ndarray
            The fitted coefficients (this effect's part of the model's parameters).
        cov : ndarray, optional
            Their covariance (the block sandwich of the final fit); without it the band is None.
        dof : int
            Degrees of freedom of the band's Student t quantile (blocks minus parameters).

        Returns
        -------
        list of dict
            ``name``, ``formula``, ``family``, ``function``, ``function_unit`` (= ``argument_unit``),
            ``argument``, ``point``, ``coordinate``, ``unit`` (of the function's values), ``grid`` (over the
            argument's observed range), ``values``, ``band_lo``, ``band_hi`` (95 %; for a drift one row per
            recording, named in ``curves``), ``coefficients`` (per column) and ``coefficient`` (the
            function's signed peak over the grid, in ``coefficient_unit`` = ``unit``).
        """
        theta = np.asarray(theta, float)
        q = float(stats.t.ppf(0.975, dof)) if dof > 0 else float("nan")
        out = []
        for k, (g, sl) in enumerate(zip(self.groups, self.slices())):
            fam = self.basis.families[g.family]
            grid, Phi, curves = self.basis.curve(g.family, g.level)
            Phi = g.of(self.basis, Phi)
            c = theta[sl]
            values = Phi @ c
            if cov is not None and np.all(np.isfinite(cov[sl, sl])) and np.isfinite(q):
                S = cov[sl, sl]
                sd = np.sqrt(np.maximum(np.einsum("cgm,mk,cgk->cg", Phi, S, Phi), 0.0))
                lo, hi = values - q * sd, values + q * sd
            else:
                lo = hi = np.full_like(values, np.nan)
            finite = np.where(np.isfinite(values), np.abs(values), -1.0)
            ci, gi = np.unravel_index(int(np.argmax(finite)), values.shape)
            peak = float(values[ci, gi])
            unit = self.unit(g)
            coord, point = POINTS[g.point]
            where = f" of {curves[ci]}" if curves[ci] else ""
            formula = (f"{fam.family} {fam.function} [{unit}] on {_where(g.point)} ({g.level + 1} of "
                       f"{n_levels(fam)} levels, {c.size} columns): peak {peak:+.4g} {unit} at "
                       f"{fam.argument}{where} = {grid[gi]:.3g} {fam.argument_unit}")
            one = len(curves) == 1
            out.append({"name": f"discovered_{k + 1}", "formula": formula, "family": fam.family,
                        "function": fam.function, "function_unit": fam.argument_unit, "argument": fam.argument,
                        "argument_unit": fam.argument_unit, "point": point, "coordinate": coord, "level": g.level + 1,
                        "unit": unit, "grid": _json(grid), "values": _json(values[0] if one else values),
                        "band_lo": _json(lo[0] if one else lo), "band_hi": _json(hi[0] if one else hi),
                        "curves": curves if not one else None, "coefficients": _json(c),
                        "coefficient": peak, "coefficient_unit": unit})
        return out


def candidate_groups(basis: Families) -> list[Group]:
    """Every (family, level, point) group: the candidates of the selection."""
    return [Group(f, lv, p) for p in range(len(POINTS)) for f in range(len(basis.families))
            for lv in range(n_levels(basis.families[f]))]


def group_sensitivities(basis: Families, ctx, force_map_i: np.ndarray, groups: Sequence[Group]) -> np.ndarray:
    """Change of the residual per unit coefficient of every column of ``groups``, side by side (n, sum m).

    ``force_map_i`` (n, 3): the residual's change per unit extra generalized force along each coordinate
    (the residual is linear in an extra force), so a column's sensitivity is the point's gain times the
    family's function.
    """
    cols = basis.columns(ctx)
    gains = point_gains(ctx, force_map_i)
    return np.concatenate([gains[:, g.point, None] * cols[(g.family, g.level)] for g in groups], axis=1)


class RowSensitivities:
    """:func:`group_sensitivities` of some rows of some recordings, made one group at a time on demand.

    The whole matrix (analysed samples x every candidate column, some 700) is never made: the selection reads
    it group by group into the layout it works on (the columns as rows), so only that copy exists. Each group's
    block is the same products as :func:`group_sensitivities`' rows (the rows taken first).

    Parameters
    ----------
    basis : Families
    parts : sequence of (ctx, force_map_i, rows)
        Per recording, its context, its force map (n, 3) and the rows (bool (n,)) taken, in order.
    groups : sequence of Group
    """

    def __init__(self, basis: Families, parts, groups: Sequence[Group]) -> None:
        self.groups = list(groups)
        # the rows as indices: taking them is several times faster than a boolean mask, each time a block is read
        self._parts = [(basis.columns(ctx), point_gains(ctx, Li)[rows], np.flatnonzero(rows))
                       for ctx, Li, rows in parts]
        self.n = int(sum(g.shape[0] for _, g, _ in self._parts))

    def block(self, j: int) -> np.ndarray:
        """Group ``j``'s sensitivities on the rows (rows, its width); its columns at the rows taken anew each
        time (not kept: a copy of every column at the rows would stand beside the selection's own)."""
        g = self.groups[j]
        key = (g.family, g.level)
        out = [gains[:, g.point, None] * c[key].take(rows, axis=0) for c, gains, rows in self._parts]
        return out[0] if len(out) == 1 else np.concatenate(out)


def force_map(model: Model, recs: Sequence[Recording], x: np.ndarray) -> list[np.ndarray]:
    """Per recording, the change of the residual per unit extra generalized force along x, gamma and phi
    (n, 3): the residual is linear in an extra force (``-R m11 (w . dQ) / D``), so three evaluations give
    the sensitivity of any force."""
    out = []
    for r in recs:
        n = r.ctx.t.shape[0]
        r0 = model.residual(r, x)[0]
        cols = []
        for j in range(3):
            e = np.zeros((n, 3))
            e[:, j] = 1.0
            cols.append(model.residual(r, x, e)[0] - r0)
        out.append(np.stack(cols, axis=1))
    return out


#: Most re-linearisations of the discovery around the h its terms imply (Gauss-Newton on the joint fit).
DISCOVERY_RELINEARISE = 3


#: A change of h [m] below which the discovery's linearisation is kept.
DISCOVERY_H_STEP_M = 1e-3


def discover_terms(current: Model, current_x: np.ndarray, recs: Sequence[Recording], folds, h0: float,
                   current_ho: HeldOut, h_geometric: float = float("nan")) -> dict:
    """The discovery step (:mod:`euc_ros.core.residual.discovery`): groups of family columns by group
    orthogonal matching pursuit within each fold's training data, their number by held-out error (the fewest
    within one standard error of the best), then the chosen groups fitted jointly with h.

    The residual is linear in the groups' coefficients but not in h (the rider's inertia m h^2): the selection
    works on the residual linearised in h. When the effect to discover biased the current model's h far from
    the truth (a rope: 0.26-0.33 m against 0.61), that linearisation is poor and spare groups make up for the
    missing curvature in h. So the selection is also made linearised at the segments' geometric h
    (``h_geometric``, measured, the same the admissibility test uses) and then around the h the chosen groups
    imply (re-linearised at the h of the full fit, at most :data:`DISCOVERY_RELINEARISE` times while h moves
    by more than :data:`DISCOVERY_H_STEP_M`; h is refitted within each fold's training data at every
    linearisation but the first). The discovered models of the linearisations are compared by their held-out
    error after the full (non-linear) fit: a tie (paired block test at :data:`AMBIGUITY_ALPHA`) goes to the
    one with fewer columns. The first linearisation is the current model's own, so a ride where no other
    fits better held-out is unchanged.

    Returns ``{"model", "x", "heldout", "info"}`` (model None when no number of groups beats none;
    ``info["terms"]``: the number of groups).
    """

    basis = Families([r.ctx for r in recs])
    groups = candidate_groups(basis)
    widths = [basis.width(g.family, g.level) for g in groups]
    edges = np.concatenate([[0], np.cumsum(widths)]).astype(int)
    slices = [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]
    keys = [g.family for g in groups]    # one point per family: the points are weakly resolved
    offsets = block_offsets(recs)
    # the aligned wheel family: its groups' phases are fitted (one offset per recording but the first)
    n_runs = len(basis.run_names)
    aligned = [j for j, g in enumerate(groups) if is_aligned(basis, g)]
    tops = {groups[j].point: j for j in aligned if groups[j].level == n_levels(basis.families[groups[j].family]) - 1}
    extra_df = [float(n_runs - 1) if j in aligned else 0.0 for j in range(len(groups))]

    def with_h(r0, B, hc):
        # h is always in the model: the groups are chosen for, and fitted with, the h column projected out
        u = hc / max(np.linalg.norm(hc), 1e-300)
        return r0 - u * (u @ r0), B - np.outer(u, u @ B)

    def layout(r0, S, hc):
        """The candidate groups' columns (``S``: their :class:`RowSensitivities`) as the selection sees them: an
        aligned wheel group's raw per-recording columns turned into one function with a phase offset per
        recording, the offsets fitted to ``r0`` (h projected out) at the group's point with every harmonic (the
        offsets are the recordings' tyre angles, the same at every level). Returns ``(slices', phases per group
        or None, turn_t, turn_cols)``: ``turn_t(S)`` the turned columns of the rows of ``S`` as rows
        (transposed), ``turn_cols(S, cols)`` only the turned columns ``cols``."""
        phases: list = [None] * len(groups)
        mixes: dict[int, np.ndarray] = {}
        at_point: dict[int, np.ndarray] = {}
        for j in aligned:
            g = groups[j]
            if g.point not in at_point:
                top = tops[g.point]
                # h projected out of the columns the offsets are fitted on only (the rest are projected by path)
                r0p, Bp = with_h(r0, S.block(top), hc)
                at_point[g.point] = align_wheel_phases(Bp, r0p, groups[top].level + 1, n_runs)
            phases[j] = tuple(float(d) for d in at_point[g.point])
            mixes[j] = wheel_phase_mix(at_point[g.point], g.level + 1)

        widths_ = [mixes[j].shape[1] if j in mixes else sl.stop - sl.start for j, sl in enumerate(slices)]
        e = np.concatenate([[0], np.cumsum(widths_)]).astype(int)
        new = [slice(a, b) for a, b in zip(e[:-1], e[1:])]

        def turn_t(X):
            out = np.empty((int(e[-1]), X.n))
            for j, to in enumerate(new):
                out[to] = (X.block(j) @ mixes[j]).T if j in mixes else X.block(j).T
            return out

        def turn_cols(X, cols):
            out = np.empty((X.n, len(cols)))
            cols = np.asarray(cols, int)
            for j, to in enumerate(new):
                at = np.flatnonzero((cols >= to.start) & (cols < to.stop))
                if at.size:
                    local = cols[at] - to.start
                    out[:, at] = X.block(j) @ mixes[j][:, local] if j in mixes else X.block(j)[:, local]
            return out

        return new, phases, turn_t, turn_cols

    def path(r0, BT, hc, blocks, sls):
        """The group search on the turned columns as rows ``BT`` (h projected out here, then normalised by
        group_path: both in place)."""
        u = hc / max(np.linalg.norm(hc), 1e-300)
        p = BT @ u
        for a in range(0, BT.shape[0], 64):     # the outer product by rows: no temporary the size of BT
            BT[a:a + 64] -= np.outer(p[a:a + 64], u)
        return group_path(r0 - u * (u @ r0), (BT, [sl.stop - sl.start for sl in sls]), keys, MAX_GROUPS,
                          n_eff=SAMPLES_PER_BLOCK * float(np.unique(blocks).size), n_fixed=1,
                          kinds=[g.family for g in groups], extra_df=extra_df)

    def cols_of(chosen, BpT, sls):
        # the chosen groups' columns that add a direction (h projected out; BpT: as rows, any scale)
        cols = np.concatenate([np.arange(sls[j].start, sls[j].stop) for j in chosen])
        return cols[independent_columns(BpT[cols].T)]

    def as_groups(chosen, cols, sls, phases):
        out = []
        for j in chosen:
            local = cols[(cols >= sls[j].start) & (cols < sls[j].stop)] - sls[j].start
            if local.size:
                out.append(Group(groups[j].family, groups[j].level, groups[j].point, tuple(int(i) for i in local),
                                 phases[j]))
        return out

    def group_scales(BT, sls):
        # a group's columns alike: the root mean square of its columns' norms (BT: the columns as rows)
        sq = np.einsum("ij,ij->i", BT, BT)
        out = np.empty(BT.shape[0])
        for sl in sls:
            out[sl] = np.sqrt(np.mean(sq[sl])) if sl.stop > sl.start else 1.0
        return out

    def select(h_lin: float | None):
        # h_lin None: linearised at the current model's fit (in each fold its own h); else at h_lin, with h
        # refitted within each fold's training data (also without groups)
        x_lin = np.array(current_x, float)
        if h_lin is not None:
            x_lin[0] = h_lin
        L = force_map(current, recs, x_lin)

        def sens(rows):
            return RowSensitivities(basis, [(recs[i].ctx, L[i], rw) for i, rw in rows], groups)

        base = [current.residual(r, x_lin) for r in recs]
        dh = 1e-3
        x1 = x_lin.copy()
        x1[0] += dh
        hcol = [(current.residual(r, x1)[0] - b[0]) / dh for r, b in zip(recs, base)]
        per_k: dict[int, list[np.ndarray]] = {}
        test_blocks = []

        for fold, x_fold in zip(folds, current_ho.params):
            x_fold = np.array(x_fold, float)
            if h_lin is not None:
                x_fold[0] = h_lin
            fres = [current.residual(r, x_fold) if np.any(te) or np.any(tr) else None
                    for r, tr, te in zip(recs, fold.train, fold.test)]
            idx = [i for i, f in enumerate(fres) if f is not None]
            tr_rows = [(i, np.asarray(fold.train[i], bool) & fres[i][1]) for i in idx]
            r0 = np.concatenate([fres[i][0][rw] for i, rw in tr_rows])
            hc = np.concatenate([hcol[i][rw] for i, rw in tr_rows])
            Braw = sens(tr_rows)
            sls, _, turn_t, turn_cols = layout(r0, Braw, hc)
            blocks = np.concatenate([recs[i].block[rw] + offsets[i] for i, rw in tr_rows])
            BT = turn_t(Braw)
            # the prior's scale: a group's columns alike (a spline piece the training rows hardly visit is held
            # to the size of its neighbours, not to its own few samples)
            scale = group_scales(BT, sls)
            sets = path(r0, BT, hc, blocks, sls)
            te_rows = [(i, np.asarray(fold.test[i], bool) & fres[i][1]) for i in idx if np.any(fold.test[i])]
            r0t = np.concatenate([fres[i][0][rw] for i, rw in te_rows])
            Braw_t = sens(te_rows)
            hct = np.concatenate([hcol[i][rw] for i, rw in te_rows])
            test_blocks.append(np.concatenate([recs[i].block[rw] + offsets[i] for i, rw in te_rows]))
            if h_lin is None:
                per_k.setdefault(0, []).append(r0t)
            else:
                c0 = -(hc @ r0) / max(hc @ hc, 1e-300)
                per_k.setdefault(0, []).append(r0t + hct * c0)
            for k, chosen in enumerate(sets, start=1):
                cols = cols_of(chosen, BT, sls)
                c = fit_with_free(hc, turn_cols(Braw, cols), -r0,
                                  n_eff=SAMPLES_PER_BLOCK * float(np.unique(blocks).size), norms=scale[cols])
                per_k.setdefault(k, []).append(r0t + hct * c[0] + turn_cols(Braw_t, cols) @ c[1:])
            del BT, Braw, Braw_t        # not held while the next fold's are made
        complete = {k: np.concatenate(v) for k, v in per_k.items() if len(v) == len(folds)}
        rmse = {k: float(np.sqrt(np.mean(v ** 2))) for k, v in complete.items()}
        # parsimony: the fewest groups within one standard error of the best held-out error
        best_k = fewest_within_one_se(complete, np.concatenate(test_blocks))
        if best_k == 0:
            return rmse, 0, complete, None, None, 0.0
        rows = [b[1] for b in base]
        r0 = np.concatenate([b[0][m] for b, m in zip(base, rows)])
        hc = np.concatenate([h[m] for h, m in zip(hcol, rows)])
        Braw = sens(list(enumerate(rows)))
        sls, phases, turn_t, turn_cols = layout(r0, Braw, hc)
        blocks = np.concatenate([r.block[m] + o for r, m, o in zip(recs, rows, offsets)])
        BT = turn_t(Braw)
        sets = path(r0, BT, hc, blocks, sls)
        if not sets:
            return rmse, 0, complete, None, None, 0.0
        chosen = sets[min(best_k, len(sets)) - 1]
        cols = cols_of(chosen, BT, sls)
        c, *_ = np.linalg.lstsq(np.column_stack([hc, turn_cols(Braw, cols)]), -r0, rcond=None)
        return rmse, best_k, complete, as_groups(chosen, cols, sls, phases), c[1:], float(c[0])

    def finalize(sel, h_lin):
        """The chosen groups fitted jointly with h and all parameters, and their held-out residual."""
        rmse, best_k, complete, chosen, c, dhh = sel
        if best_k == 0:
            return None
        eff = DiscoveredEffect(basis, chosen, [max(abs(v), 1e-6) for v in c], start=c)
        model = Model(current.effects + [eff])
        start = np.concatenate([current_x, c])
        start[0] = float(np.clip(h_lin + dhh, *H_BOUNDS))
        full = fit_model(model, recs, h0, start=start)
        ho = structure_heldout(model, chosen, float(np.clip(full.x[0], *H_BOUNDS)))
        return {"model": model, "x": full.x, "heldout": ho if ho is not None else held_out(model, recs, h0, folds,
                                                                                            start=full.x),
                "sel": sel, "h_lin": h_lin, "k": int(c.size)}

    def structure_heldout(model: Model, chosen: list[Group], h_lin: float) -> HeldOut | None:
        """Held-out residual of the chosen groups as the selection judged them: in each fold h and the groups'
        coefficients fitted on the training rows (linearised at ``h_lin``, the coefficients shrunk,
        :func:`~euc_ros.core.residual.shrinkage.fit_with_free`). A plain refit of many flexible columns in
        each fold (Gauss-Newton from the fit on all data) is as ill-determined as the selection's would be
        without the prior: a lab field's spline piece a fold hardly visits gets any size. None when the
        samples do not pair with the current model's held-out ones."""
        x_lin = np.array(current_x, float)
        x_lin[0] = h_lin
        L = force_map(current, recs, x_lin)
        cols = []
        for r, Li in zip(recs, L):
            gains = point_gains(r.ctx, Li)
            raw = basis.columns(r.ctx, [(g.family, g.level) for g in chosen])
            cols.append(np.concatenate([g.of(basis, gains[:, g.point, None] * raw[(g.family, g.level)])
                                        for g in chosen], axis=1))
        width = [g.columns(basis).size for g in chosen]
        res = []
        for fold, x_fold in zip(folds, current_ho.params):
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
            blocks = np.concatenate([recs[i].block[rw] + offsets[i] for i, rw in tr_rows])
            e = np.concatenate([[0], np.cumsum(width)]).astype(int)
            scale = group_scales(B.T, [slice(a, b) for a, b in zip(e[:-1], e[1:])])
            c = fit_with_free(hc, B, -r0, n_eff=SAMPLES_PER_BLOCK * float(np.unique(blocks).size), norms=scale)
            r0t = np.concatenate([fres[i][0][rw] for i, rw in te_rows])
            hct = np.concatenate([hcol[i][rw] for i, rw in te_rows])
            Bt = np.concatenate([cols[i][rw] for i, rw in te_rows])
            res.append(r0t + hct * c[0] + Bt @ c[1:])
        residual = np.concatenate(res) if res else np.zeros(0)
        if residual.shape != current_ho.residual.shape:
            return None
        return HeldOut(model, residual, current_ho.block, [], current_ho.index)

    def preferred(a, b):
        """The better of two discovered models by held-out error; a tie (the better not significantly better,
        paired block test at AMBIGUITY_ALPHA) goes to the one with fewer columns."""
        if a is None or b is None:
            return a if b is None else b
        lo, hi = (a, b) if a["heldout"].rmse <= b["heldout"].rmse else (b, a)
        if hi["k"] < lo["k"] and paired_block_test(hi["heldout"], lo["heldout"]) >= AMBIGUITY_ALPHA:
            return hi
        return lo

    h_cur = float(current_x[0])
    first = select(None)
    best = finalize(first, h_cur)
    h_path = [h_cur]
    if math.isfinite(h_geometric) and abs(h_geometric - h_cur) > DISCOVERY_H_STEP_M:
        h_g = float(np.clip(h_geometric, *H_BOUNDS))
        h_path.append(h_g)
        best = preferred(best, finalize(select(h_g), h_g))
    for _ in range(DISCOVERY_RELINEARISE):
        if best is None:
            break
        h_fit = float(np.clip(best["x"][0], *H_BOUNDS))
        if abs(h_fit - best["h_lin"]) < DISCOVERY_H_STEP_M:
            break
        h_path.append(h_fit)
        nxt = preferred(best, finalize(select(h_fit), h_fit))
        if nxt is best:
            break
        best = nxt
    sel = first if best is None else best["sel"]
    rmse, best_k, complete = sel[0], sel[1], sel[2]
    info = {"run": True, "heldout_rmse_by_terms": [rmse[k] for k in sorted(rmse)], "terms": best_k,
            "families": sorted({f.key for f in basis.families}), "undetectable": UNDETECTABLE,
            "linearised_at_h_m": h_cur if best is None else best["h_lin"], "linearisations_tried_h_m": h_path}
    if best is None:
        basis.retain([])
        return {"model": None, "x": None, "heldout": None, "info": info}
    # the basis goes on with the model: only the chosen groups' columns are kept (the rest are some 700
    # columns of every analysed sample)
    basis.retain([(g.family, g.level) for g in best["model"].effects[-1].groups])
    # the held-out residual of the groups chosen within each fold (no leakage of the selection into the test)
    if complete[best_k].shape == current_ho.residual.shape:
        info["selection_heldout"] = HeldOut(current, complete[best_k], current_ho.block, [], current_ho.index)
    return {"model": best["model"], "x": best["x"], "heldout": best["heldout"], "info": info}
