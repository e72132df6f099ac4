"""The discovery's groups and what is fitted of them.

A :class:`Group` (a family at a level, acting at a point), the residual's sensitivity to the groups' columns
(:class:`RowSensitivities`, :func:`force_map`) and the discovered effect fitted like a named candidate
(:class:`DiscoveredEffect`); the search space of one discovery (:class:`DiscoveryProblem`) and the groups' columns as
its search sees them (:class:`Layout`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import stats

from euc_ros.core.model.candidate import Candidate, ParamInfo, jacobian_G
from euc_ros.core.model.extended import Model
from euc_ros.core.residual.families import POINT_UNITS, POINTS, Families, n_levels
from euc_ros.core.residual.folds import SAMPLES_PER_BLOCK
from euc_ros.core.residual.search import GroupSearch
from euc_ros.core.residual.selection import HeldOut, block_offsets
from euc_ros.core.residual.wheel_phase import align_wheel_phases, wheel_phase_mix
from euc_ros.core.states.contexts import Recording


def _where(point: int) -> str:
    coord, at = POINTS[point]
    return f"{coord} at the {at}"


@dataclass(frozen=True)
class Group:
    """One discovered group: family ``family`` (index into ``Families.families``) at ``level``, at ``point``.

    Parameters
    ----------
    family : int
        Index of the family in ``Families.families``.
    level : int
        Its complexity level (from 0).
    point : int
        Index of the point of application in :data:`~euc_ros.core.residual.families.POINTS`.
    keep : tuple of int, optional
        The group's columns fitted (:func:`~euc_ros.core.residual.search.independent_columns`; None: all).
    phases : tuple of float, optional
        The aligned wheel family's phase offset per recording [rad] (None for any other group).
    """

    family: int
    level: int
    point: int
    keep: tuple[int, ...] | None = None
    phases: tuple[float, ...] | None = None

    def mix(self) -> np.ndarray | None:
        """For the aligned wheel family with its phase offsets, the matrix from its raw columns to the group's.

        Returns
        -------
        ndarray or None
            :func:`~euc_ros.core.residual.wheel_phase.wheel_phase_mix` of :attr:`phases` (2 K n_runs, 2 K), K the
            level's harmonics; None for any other group.
        """
        return None if self.phases is None else wheel_phase_mix(np.asarray(self.phases, float), self.level + 1)

    def columns(self, basis: Families) -> np.ndarray:
        """Indices of the fitted columns among the group's columns.

        The group's columns: the family's at this level, or their phase-aligned combinations.

        Parameters
        ----------
        basis : Families
            The basis the group is of.

        Returns
        -------
        ndarray of int
            :attr:`keep`, or every column.
        """
        if self.keep is not None:
            return np.array(self.keep, int)
        M = self.mix()
        return np.arange(M.shape[1] if M is not None else basis.width(self.family, self.level))

    def of(self, basis: Families, C: np.ndarray) -> np.ndarray:
        """The group's fitted columns from the family's raw columns.

        Parameters
        ----------
        basis : Families
            The basis the group is of.
        C : ndarray (..., raw)
            The family's raw columns at the group's level.

        Returns
        -------
        ndarray (..., fitted)
            Phase-aligned (:meth:`mix`) when the group has phases, then the fitted columns taken.
        """
        M = self.mix()
        return (C if M is None else C @ M)[..., self.columns(basis)]


def is_aligned(basis: Families, g: Group) -> bool:
    """Whether ``g`` is a group of the wheel family with a phase offset per recording.

    Parameters
    ----------
    basis : Families
        The basis the group is of.
    g : Group
        The group.

    Returns
    -------
    bool
    """
    fam = basis.families[g.family]
    return fam.kind == "wheel" and bool(fam.option)


def _json(a):
    """Nested lists of an array with NaN as None."""
    a = np.asarray(a, float)
    if a.ndim == 0:
        return float(a) if np.isfinite(a) else None
    return [_json(v) for v in a]


def point_gains(ctx, force_map_i: np.ndarray) -> np.ndarray:
    """Residual change per unit force at each point: ``force_map . dQ`` of a unit force.

    Parameters
    ----------
    ctx : ModelContext
        One recording's samples and parameters.
    force_map_i : ndarray (n, 3)
        Its residual's change per unit generalized force along x, gamma and phi (:func:`force_map`).

    Returns
    -------
    ndarray (n, len(POINTS))
        Per point, [N m] per unit force [N] (per unit torque [N m] on the rider's pitch).
    """
    jx, jz = jacobian_G(ctx, ctx.p())
    return np.stack([force_map_i[:, 0], np.sum(force_map_i * jx, axis=1), np.sum(force_map_i * jz, axis=1),
                     force_map_i[:, 2]], axis=1)


class DiscoveredEffect(Candidate):
    """Discovered groups of family columns, fitted like a named candidate (one free coefficient per column).

    Parameters
    ----------
    basis : Families
        The basis the groups are of.
    groups : sequence of Group
        The groups.
    scales : sequence of float
        Each coefficient's typical magnitude (its ``ParamInfo.scale``), the groups' columns one after the other.
    start : array_like, optional
        The coefficients' start (default zeros).
    """

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
        """Unit of the group's function: the point's force or torque per unit of the family's factor.

        Parameters
        ----------
        g : Group
            One of the groups.

        Returns
        -------
        str
            ``N``, ``N m``, or either per the family's ``per_unit`` (e.g. ``N/(m/s)``).
        """
        per = self.basis.families[g.family].per_unit
        pu = POINT_UNITS[g.point]
        return pu if per == "1" else f"{pu}/({per})"

    def slices(self) -> list[slice]:
        """Each group's slice of the parameter vector (``theta[sl]``: the coefficients of its columns).

        Returns
        -------
        list of slice
            One per group, in order, as wide as the group's fitted columns (``widths``).
        """
        edges = np.concatenate([[0], np.cumsum(self.widths)]).astype(int)
        return [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]

    def starts(self):
        """Initial guess of the coefficients: the ``start`` given, else zeros.

        Returns
        -------
        list of numpy.ndarray
            The one start (a copy).
        """
        return [self._start.copy()]

    def force(self, ctx, theta):
        """Extra generalized force (n, 3) of the groups' functions with the coefficients ``theta``.

        Each group's function (its fitted columns on ``ctx`` times its coefficients) acts at its point: along x
        at the contact, along x or z at the rider CoG (through
        :func:`~euc_ros.core.model.effects.jacobian_G`), or as a torque on the rider's pitch.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on.
        theta : numpy.ndarray
            The coefficients, the groups' columns one after the other.

        Returns
        -------
        numpy.ndarray (n, 3)
            The force along x, gamma and phi.
        """
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
        """The coefficients as reported in the JSON.

        Parameters
        ----------
        theta : numpy.ndarray
            The coefficients, the groups' columns one after the other.

        Returns
        -------
        dict of str to float
            ``discovered_<group>_<column>`` (both counted from 1) to its coefficient.
        """
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
    """Every (family, level, point) group: the candidates of the selection.

    Parameters
    ----------
    basis : Families
        The basis.

    Returns
    -------
    list of Group
        Point by point, family by family, level by level.
    """
    return [Group(f, lv, p) for p in range(len(POINTS)) for f in range(len(basis.families))
            for lv in range(n_levels(basis.families[f]))]


def group_sensitivities(basis: Families, ctx, force_map_i: np.ndarray, groups: Sequence[Group]) -> np.ndarray:
    """Change of the residual per unit coefficient of every column of ``groups``, side by side (n, sum m).

    ``force_map_i`` (n, 3): the residual's change per unit extra generalized force along each coordinate
    (the residual is linear in an extra force), so a column's sensitivity is the point's gain times the
    family's function.

    Parameters
    ----------
    basis : Families
        The basis.
    ctx : ModelContext
        One recording's samples and parameters.
    force_map_i : ndarray (n, 3)
        Its force map (:func:`force_map`).
    groups : sequence of Group
        The groups.

    Returns
    -------
    ndarray (n, sum m)
        The groups' raw columns times their point's gain [N m per unit coefficient].
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

    def taken(self, key: tuple[int, int]) -> list[np.ndarray]:
        """The raw columns of one family level at the rows, per recording (what :meth:`block` multiplies).

        Parameters
        ----------
        key : tuple of int
            (family index, level).

        Returns
        -------
        list of ndarray
            Per recording, its columns at its rows (rows_i, width).
        """
        return [c[key].take(rows, axis=0) for c, _, rows in self._parts]

    def block(self, j: int, taken: list[np.ndarray] | None = None) -> np.ndarray:
        """Group ``j``'s sensitivities on the rows (rows, its width).

        Its columns at the rows are taken anew each time, not kept: a copy of every column at the rows would stand
        beside the selection's own.

        Parameters
        ----------
        j : int
            Index of the group.
        taken : list of ndarray, optional
            :meth:`taken` of the group's family level, when the caller has it (the groups of one family level
            at the other points share it).

        Returns
        -------
        ndarray (rows, width)
            The recordings' rows one after the other.
        """
        g = self.groups[j]
        if taken is None:
            taken = self.taken((g.family, g.level))
        out = [gains[:, g.point, None] * t for t, (_, gains, _) in zip(taken, self._parts)]
        return out[0] if len(out) == 1 else np.concatenate(out)


def force_map(model: Model, recs: Sequence[Recording], x: np.ndarray) -> list[np.ndarray]:
    """Per recording, the change of the residual per unit extra generalized force along x, gamma and phi (n, 3).

    The residual is linear in an extra force (``-R m11 (w . dQ) / D``), so three evaluations give the sensitivity of any
    force.

    Parameters
    ----------
    model : Model
        The model.
    recs : sequence of Recording
        The recordings.
    x : ndarray
        The model's parameters ``[h, theta...]``.

    Returns
    -------
    list of ndarray
        Per recording (n_i, 3): [N m] per unit generalized force (N along x, N m along gamma and phi).
    """
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


# ----------------------------------------------------------------------------------------- the search space
@dataclass(frozen=True, eq=False)
class DiscoveryProblem:
    """What every step of one discovery works on: the current model held out, the basis and its groups.

    Parameters
    ----------
    current : Model
        The model whose residual is searched.
    current_x : ndarray
        Its parameters fitted on all samples.
    current_ho : HeldOut
        Its held-out residual (its per-fold parameters start every fold's linearisation).
    recs : sequence of Recording
        The recordings, with their blocks.
    folds : sequence of Fold
        The held-out folds.
    h0 : float
        Start of the joint fits [m].
    basis : Families
        The families' basis over the recordings.
    search : GroupSearch
        The search over the groups.
    groups : list of Group
        Every (family, level, point) group (:func:`candidate_groups`).
    slices : list of slice
        Each group's raw columns among all groups'.
    keys : list of int
        Each group's family: groups of one family exclude each other (the points are weakly resolved).
    offsets : list of int
        Block offsets of the recordings (blocks unique over recordings).
    aligned : list of int
        The groups of the aligned wheel family (a phase offset per recording fitted).
    tops : dict of int to int
        Per point, the aligned group with every harmonic (the one the offsets are fitted with).
    extra_df : list of float
        Parameters each group fits besides its columns (the aligned groups' offsets).
    """

    current: Model
    current_x: np.ndarray
    current_ho: HeldOut
    recs: Sequence[Recording]
    folds: Sequence
    h0: float
    basis: Families
    search: GroupSearch
    groups: list[Group]
    slices: list[slice]
    keys: list[int]
    offsets: list[int]
    aligned: list[int]
    tops: dict[int, int]
    extra_df: list[float]

    @property
    def n_eff_per_block(self) -> float:
        """Samples of a block counted as independent (:data:`~.folds.SAMPLES_PER_BLOCK`)."""
        return SAMPLES_PER_BLOCK


def discovery_problem(current: Model, current_x: np.ndarray, current_ho: HeldOut, recs: Sequence[Recording],
                      folds, h0: float, basis: Families, search: GroupSearch) -> DiscoveryProblem:
    """The search space of one discovery over ``basis`` (its groups, their columns' layout, their keys).

    Parameters
    ----------
    current : Model
    current_x : ndarray
    current_ho : HeldOut
    recs : sequence of Recording
    folds : sequence of Fold
    h0 : float
    basis : Families
    search : GroupSearch

    Returns
    -------
    DiscoveryProblem
    """
    groups = candidate_groups(basis)
    widths = [basis.width(g.family, g.level) for g in groups]
    edges = np.concatenate([[0], np.cumsum(widths)]).astype(int)
    slices = [slice(a, b) for a, b in zip(edges[:-1], edges[1:])]
    n_runs = len(basis.run_names)
    aligned = [j for j, g in enumerate(groups) if is_aligned(basis, g)]
    tops = {groups[j].point: j for j in aligned if groups[j].level == n_levels(basis.families[groups[j].family]) - 1}
    extra_df = [float(n_runs - 1) if j in aligned else 0.0 for j in range(len(groups))]
    return DiscoveryProblem(current, current_x, current_ho, recs, folds, h0, basis, search, groups, slices,
                            [g.family for g in groups], block_offsets(recs), aligned, tops, extra_df)


# ---------------------------------------------------------------------------------------------- the layout
def _without_h(r0: np.ndarray, B: np.ndarray, hc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``r0`` and the columns ``B`` with the h column ``hc`` projected out."""
    u = hc / max(np.linalg.norm(hc), 1e-300)
    return r0 - u * (u @ r0), B - np.outer(u, u @ B)


class Layout:
    """The candidate groups' columns as the selection sees them.

    An aligned wheel group is turned into one function with a phase offset per recording.

    Parameters
    ----------
    slices : list of slice
        Each group's turned columns.
    phases : list
        Each group's phase offsets (None but for the aligned wheel groups).
    mixes : dict of int to ndarray
        The aligned groups' matrices from their raw columns to their turned ones.
    """

    def __init__(self, slices: list[slice], phases: list, mixes: dict[int, np.ndarray]) -> None:
        self.slices, self.phases, self.mixes = slices, phases, mixes

    def rows(self, S: RowSensitivities) -> np.ndarray:
        """The turned columns of the rows of ``S`` as rows (transposed).

        Parameters
        ----------
        S : RowSensitivities
            The groups' raw columns on some rows.

        Returns
        -------
        ndarray (columns, rows)
        """
        out = np.empty((int(self.slices[-1].stop) if self.slices else 0, S.n))
        by_key: dict[tuple[int, int], list[int]] = {}
        for j, g in enumerate(S.groups[:len(self.slices)]):
            by_key.setdefault((g.family, g.level), []).append(j)
        for key, js in by_key.items():           # a family level's columns taken once for its points
            taken = S.taken(key)
            for j in js:
                B = S.block(j, taken)
                out[self.slices[j]] = (B @ self.mixes[j]).T if j in self.mixes else B.T
        return out

    def columns(self, S: RowSensitivities, cols) -> np.ndarray:
        """Only the turned columns ``cols`` of the rows of ``S``.

        Parameters
        ----------
        S : RowSensitivities
            The groups' raw columns on some rows.
        cols : array_like of int
            Indices of turned columns (over all groups, :attr:`slices`).

        Returns
        -------
        ndarray (rows, len(cols))
        """
        out = np.empty((S.n, len(cols)))
        cols = np.asarray(cols, int)
        starts = np.array([to.start for to in self.slices], int)
        stops = np.array([to.stop for to in self.slices], int)
        # each column's group: the last whose slice starts at or before it (a group of no columns is skipped)
        owner = np.searchsorted(starts, cols, side="right") - 1
        inside = (owner >= 0) & (cols < stops[np.clip(owner, 0, None)]) if starts.size else np.zeros(cols.size, bool)
        for j in np.unique(owner[inside]).tolist():
            to = self.slices[j]
            at = np.flatnonzero(inside & (owner == j))
            local = cols[at] - to.start
            out[:, at] = S.block(j) @ self.mixes[j][:, local] if j in self.mixes else S.block(j)[:, local]
        return out


def layout(problem: DiscoveryProblem, r0: np.ndarray, S: RowSensitivities, hc: np.ndarray) -> Layout:
    """The groups' columns (``S``) as the selection sees them.

    An aligned wheel group's raw per-recording columns turned into one function with a phase offset per recording, the
    offsets fitted to ``r0`` (h projected out) at the group's point with every harmonic (the offsets are the recordings'
    tyre angles, the same at every level).

    Parameters
    ----------
    problem : DiscoveryProblem
    r0 : ndarray
        The residual on the rows of ``S``.
    S : RowSensitivities
        The groups' raw columns on those rows.
    hc : ndarray
        The residual's derivative in h on those rows.

    Returns
    -------
    Layout
    """
    groups = problem.groups
    phases: list = [None] * len(groups)
    mixes: dict[int, np.ndarray] = {}
    at_point: dict[int, np.ndarray] = {}
    for j in problem.aligned:
        g = groups[j]
        if g.point not in at_point:
            top = problem.tops[g.point]
            # h projected out of the columns the offsets are fitted on only (the rest are projected by the search)
            r0p, Bp = _without_h(r0, S.block(top), hc)
            at_point[g.point] = align_wheel_phases(Bp, r0p, groups[top].level + 1, len(problem.basis.run_names))
        phases[j] = tuple(float(d) for d in at_point[g.point])
        mixes[j] = wheel_phase_mix(at_point[g.point], g.level + 1)
    widths = [mixes[j].shape[1] if j in mixes else sl.stop - sl.start for j, sl in enumerate(problem.slices)]
    e = np.concatenate([[0], np.cumsum(widths)]).astype(int)
    return Layout([slice(a, b) for a, b in zip(e[:-1], e[1:])], phases, mixes)
