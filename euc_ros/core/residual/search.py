"""The group-sparse search of the discovery: which groups of basis columns explain a residual, and how many.

:func:`group_path` orders the candidate groups (a beam search on the Bayesian information criterion of the
fit), :func:`fewest_within_one_se` chooses their number by held-out error and :func:`independent_columns`
keeps a chosen group's columns that add a direction. :class:`GroupSearch` holds the search's settings and is
what :class:`~euc_ros.core.residual.discovery.GroupSparseDiscovery` takes as its ``search``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

#: A direction a candidate group adds is kept when its singular value (unit-norm columns, after the groups
#: already chosen are projected out) is at least this: thinner directions are collinear with the chosen
#: ones and would fit noise at any scale.
MIN_NEW_DIRECTION = 1e-2
#: Sets of each size kept by the beam search of :func:`group_path`.
BEAM_WIDTH = 4
#: Most groups a discovered model may have.
MAX_GROUPS = 3


def group_path(r0: np.ndarray, groups: Sequence[np.ndarray], keys: Sequence, max_groups: int,
               n_eff: float | None = None, n_fixed: int = 0, beam_width: int | None = None,
               kinds: Sequence | None = None, extra_df: Sequence[float] | None = None) -> list[list[int]]:
    """Group best-subset search by beam: the sets of 1..max_groups groups that best explain ``r0``.

    Group orthogonal matching pursuit when ``beam_width`` is 1; best by the criterion below.

    Parameters
    ----------
    r0 : ndarray (n,)
        The residual to explain (anything fitted always, such as h, projected out).
    groups : sequence of ndarray (n, m_j), or (ndarray (sum m_j, n), widths)
        Candidate groups of columns (a family at one level and one point); as a tuple, the groups' columns as
        the rows of one matrix (transposed, the groups one after the other), which is normalised in place.
    keys : sequence
        Groups with equal keys exclude each other (the levels of one family at one point).
    max_groups : int
        Most steps.
    n_eff : float, optional
        Effective number of independent samples (the residual's blocks); default n.
    n_fixed : int
        Parameters fitted besides the groups (h).
    beam_width : int, optional
        Sets kept at each size (default :data:`BEAM_WIDTH`).
    kinds : sequence, optional
        Each group's family (default: its key): the beam keeps the best set of each combination of
        families, so it is not filled by one family at several points and levels.
    extra_df : sequence of float, optional
        Parameters a group fitted besides its columns (the aligned wheel family's phase offsets), counted in
        its degrees of freedom (default 0).

    Returns
    -------
    list of list of int
        The best set of each size (group indices in the order they were added).

    Notes
    -----
    Each step grows every kept set by every group and keeps the ``beam_width`` sets with the lowest
    Bayesian information criterion of the fit,
    ``n_eff log(rss / n) + df log(n_eff)``, with ``df`` the directions of the set: each group adds an
    orthonormal basis ``U`` of its columns after the set's groups are projected out, directions thinner than
    :data:`MIN_NEW_DIRECTION` dropped. ``n_eff`` counts the residual's blocks, not its samples (the samples
    within a block are correlated: with every sample counted, a 7-column group would need to cut the
    residual by only a few per cent more than a 2-column one). So a group with more columns must explain
    more to be chosen, and a family's complexity level is chosen with the family; the number of steps is
    left to the held-out error. The beam matters where one flexible group explains most of several
    simpler ones together (a per-run drift against a headwind's heading, speed and cross terms in
    accelerating runs): greedy selection takes the flexible group first and never recovers.
    """
    beam_width = BEAM_WIDTH if beam_width is None else max(int(beam_width), 1)
    kinds = list(keys) if kinds is None else list(kinds)
    extra = [0.0] * len(groups) if extra_df is None else [float(e) for e in extra_df]
    r0 = np.asarray(r0, float)
    n = r0.size
    n_eff = float(n if n_eff is None else min(max(n_eff, 2.0), n))
    # every group's columns side by side, unit norm (a column of zeros is dropped), and their Gram blocks, so
    # each candidate is scored in its own m x m space: with Q the chosen directions, the projected Gram is
    # C'C - (Q'C)'(Q'C), its eigenvectors V and singular values sv give the new directions
    # U = (C - Q Q'C) V / sv, and U'r = V'C'r / sv (r is already orthogonal to Q); groups of one width are
    # scored together (batched eigh). Q'C and C'r are carried along the beam: a step adds U'C and takes
    # (U'C)'z off C'r.
    CT, edges, normed, classes = _group_layout(groups, n)
    kind_ids = {k: i for i, k in enumerate(dict.fromkeys(kinds))}
    kind_of = np.array([kind_ids[k] for k in kinds], int)
    extra_a = np.asarray(extra, float)

    # beam of (score, chosen, Q, r, used keys, Q'C, C'r)
    beam = [(0.0, [], np.zeros((n, 0)), r0.copy(), frozenset(), np.zeros((0, CT.shape[0])), CT @ r0)]
    out = []
    for step in range(max_groups):
        grown = {}
        for _, chosen, Q, r, used, QtC, Ctr in beam:
            base_df = Q.shape[1] + sum(extra[i] for i in chosen)
            best_j, best_score = _best_per_kind(classes, keys, kind_of, extra_a, used, QtC, Ctr, float(r @ r),
                                                (base_df, n, n_eff, n_fixed))
            for kd, j in best_j.items():
                key = frozenset(kinds[i] for i in chosen + [j])
                if key not in grown or best_score[kd] < grown[key][0]:
                    grown[key] = (best_score[kd], chosen + [j], Q, r, used, QtC, Ctr)
        if not grown:
            break
        best = sorted(grown.values(), key=lambda e: e[0])[:beam_width]
        if step == max_groups - 1:                  # the last step's directions are not needed
            out.append(list(best[0][1]))
            break
        beam = []
        new = [_directions(normed[e[1][-1]].T, e[5][:, edges[e[1][-1]]:edges[e[1][-1] + 1]], e[2], e[3])
               for e in best]
        # every set's new directions against every column in one pass over the columns
        CtU = CT @ np.concatenate([U for U, _ in new], axis=1)
        at = np.concatenate([[0], np.cumsum([U.shape[1] for U, _ in new])]).astype(int)
        for (sc, ch, Q, r, used, QtC, Ctr), (U, z), a, b in zip(best, new, at[:-1], at[1:]):
            beam.append((sc, ch, np.concatenate([Q, U], axis=1), r - U @ z, used | {keys[ch[-1]]},
                         np.concatenate([QtC, CtU[:, a:b].T], axis=0), Ctr - CtU[:, a:b] @ z))
        out.append(list(beam[0][1]))
    return out


def _directions(C: np.ndarray, A: np.ndarray, Q: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A group's new orthonormal directions ``U`` beyond ``Q`` (its columns ``C``, ``A = Q'C``) and ``U'r``."""
    ev, V = np.linalg.eigh(C.T @ C - A.T @ A)
    sv = np.sqrt(np.maximum(ev, 0.0))
    keep = sv >= MIN_NEW_DIRECTION
    U = ((C - Q @ A) @ V[:, keep]) / sv[keep]
    return U, U.T @ r


def _group_layout(groups, n: int):
    """The groups' columns as unit-norm rows ``CT`` (P, n), each group's row edges and rows, and the groups by width.

    Returns
    -------
    tuple
        ``(CT, edges, normed, classes)``: ``classes`` holds, per width ``m``, the groups' indices, their rows
        (J, m) and their Gram blocks (J, m, m).
    """
    # the columns as rows (P, n): a group's columns are contiguous rows
    if isinstance(groups, tuple):             # (transposed matrix, widths): the groups stacked, the matrix ours
        CT, raw_sizes = np.asarray(groups[0], float), np.asarray(groups[1], int)
    else:
        CT = np.concatenate([np.asarray(C, float).T for C in groups], axis=0) if len(groups) else np.zeros((0, n))
        raw_sizes = np.array([C.shape[1] for C in groups], int)
    nrm = np.sqrt(np.einsum("ij,ij->i", CT, CT))
    live = nrm > 0
    if not live.all():
        CT = CT[live]
    CT /= nrm[live, None]
    sizes = np.array([int(np.count_nonzero(live[a:a + m])) for a, m in
                      zip(np.concatenate([[0], np.cumsum(raw_sizes)[:-1]]).astype(int), raw_sizes)], int)
    edges = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    normed = [CT[edges[j]:edges[j + 1]] for j in range(sizes.size)]          # (m, n) each
    classes = []
    for m in sorted(set(sizes.tolist()) - {0}):
        js = np.flatnonzero(sizes == m)
        cols = np.concatenate([np.arange(edges[j], edges[j + 1]) for j in js]).reshape(js.size, m)
        classes.append((js, cols, np.stack([normed[j] @ normed[j].T for j in js])))
    return CT, edges, normed, classes


def _best_per_kind(classes, keys, kind_of: np.ndarray, extra_a: np.ndarray, used, QtC: np.ndarray,
                   Ctr: np.ndarray, rss: float, counts: tuple) -> tuple[dict, dict]:
    """Per family (kind), the group that grows a beam set best and its criterion (:func:`group_path`).

    ``counts`` is ``(the set's degrees of freedom, n, n_eff, n_fixed)``.
    """
    base_df, n, n_eff, n_fixed = counts
    best_j, best_score = {}, {}
    for js, cols, grams in classes:
        ok = np.array([keys[j] not in used for j in js], bool)
        if not ok.any():
            continue
        js, cols, grams = js[ok], cols[ok], grams[ok]
        A = QtC[:, cols].transpose(1, 0, 2)                          # (J, q, m)
        ev, V = np.linalg.eigh(grams - np.einsum("jqm,jqk->jmk", A, A))
        sv = np.sqrt(np.maximum(ev, 0.0))
        keep = sv >= MIN_NEW_DIRECTION
        proj = np.einsum("jmk,jm->jk", V, Ctr[cols]) / np.where(keep, sv, 1.0)
        zz = np.sum(np.where(keep, proj * proj, 0.0), axis=1)
        df = base_df + keep.sum(axis=1) + extra_a[js]
        valid = keep.any(axis=1) & (n - df - n_fixed > 0)
        score = n_eff * np.log(np.maximum(rss - zz, 1e-300) / n) + df * np.log(n_eff)
        for i in np.flatnonzero(valid):
            kd = int(kind_of[js[i]])
            if kd not in best_score or score[i] < best_score[kd]:
                best_score[kd], best_j[kd] = float(score[i]), int(js[i])
    return best_j, best_score


#: Relative difference of two columns' remaining norms below which :func:`independent_columns` takes them as
#: equal and pivots on the first (unit-norm columns tie exactly where they are orthogonal, e.g. spline pieces
#: with disjoint support; a pivot chosen by round-off would make the kept subset, and the fit, machine-dependent).
PIVOT_TIE = 1e-9


def independent_columns(A: np.ndarray, tol: float = MIN_NEW_DIRECTION) -> np.ndarray:
    """Indices (sorted) of a well-conditioned subset of the columns of ``A``.

    Column-pivoted Gram-Schmidt of the unit-norm columns (pivoted Cholesky of their Gram matrix; ties within
    :data:`PIVOT_TIE` go to the first column), kept while ``|R_kk|`` (the part of a column outside the span of those
    before it) is at least ``tol`` times the first. A chosen group's columns that add no direction on these recordings
    (a spline piece the data hardly visit, a filter collinear with its neighbours) are left out of the fit, so no
    coefficient is fitted along a direction the selection did not see.

    Parameters
    ----------
    A : ndarray (n, m)
        The columns (any scale; a column of zeros is never kept).
    tol : float
        Smallest ``|R_kk|`` kept, relative to the first pivot's.

    Returns
    -------
    ndarray of int
        The kept columns' indices, ascending (empty when every column is zero).
    """
    A = np.asarray(A, float)
    nrm = np.sqrt(np.einsum("ij,ij->j", A, A))
    ok = np.flatnonzero(nrm > 0)
    if ok.size == 0:
        return ok
    X = A[:, ok] / nrm[ok]
    G = X.T @ X
    m = G.shape[0]
    d = np.diag(G).copy()                      # the columns' squared norms outside the span chosen so far
    L = np.zeros((m, m))
    free = np.ones(m, bool)
    kept: list[int] = []
    first = None
    for k in range(m):
        top = float(np.max(np.where(free, d, -np.inf)))
        if first is None:
            first = top
        if not top > 0 or np.sqrt(top) < tol * np.sqrt(first):
            break
        j = int(np.flatnonzero(free & (d >= top * (1.0 - PIVOT_TIE)))[0])
        col = (G[:, j] - L[:, :k] @ L[j, :k]) / np.sqrt(d[j])
        L[:, k] = col
        free[j] = False
        d = d - col * col
        kept.append(j)
    return np.sort(ok[np.array(kept, int)])


def fewest_within_one_se(errors: dict[int, np.ndarray], blocks: np.ndarray) -> int:
    """The smallest k whose held-out mean square is within one standard error of the best one's.

    The standard error is that of the paired difference of the mean squares, from the block sums (the blocks
    are nearly independent): the one-standard-error rule of cross-validation, so a further group must improve
    the held-out error by more than its own sampling uncertainty.

    Parameters
    ----------
    errors : dict of int to ndarray
        ``errors[k]``: the held-out residuals of the model with k groups, on the same samples in the same order.
    blocks : ndarray of int
        Each sample's block.

    Returns
    -------
    int
        That k (the best one's when none fewer is within one standard error).
    """
    ks = sorted(errors)
    mse = {k: float(np.mean(errors[k] ** 2)) for k in ks}
    best = min(ks, key=lambda k: (mse[k], k))
    _, ids = np.unique(blocks, return_inverse=True)
    nb = int(ids.max()) + 1 if ids.size else 0
    n = errors[best].size
    for k in ks:
        if k >= best:
            return best
        d = errors[k] ** 2 - errors[best] ** 2
        sums = np.bincount(ids, weights=d, minlength=nb)
        counts = np.bincount(ids, minlength=nb)
        mean = d.mean()
        se = np.sqrt(nb / max(nb - 1, 1) * np.sum((sums - counts * mean) ** 2)) / max(n, 1)
        if mse[k] - mse[best] <= se:
            return k
    return best


@dataclass(frozen=True)
class GroupSearch:
    """The discovery's search: a beam search over the groups, their number by the one-standard-error rule.

    Parameters
    ----------
    max_groups : int
        Most groups of a discovered model.
    beam_width : int
        Sets kept at each size by :func:`group_path` (1: group orthogonal matching pursuit).
    """

    max_groups: int = MAX_GROUPS
    beam_width: int = BEAM_WIDTH

    def path(self, r0: np.ndarray, groups, keys: Sequence, *, n_eff: float | None = None, n_fixed: int = 0,
             kinds: Sequence | None = None, extra_df: Sequence[float] | None = None) -> list[list[int]]:
        """The best set of each size, 1 to :attr:`max_groups` (:func:`group_path`).

        Parameters
        ----------
        r0 : ndarray (n,)
            The residual to explain (what is always fitted projected out).
        groups : sequence of ndarray, or (ndarray, widths)
            The candidate groups' columns (see :func:`group_path`).
        keys : sequence
            Groups with equal keys exclude each other.
        n_eff : float, optional
            Effective number of independent samples.
        n_fixed : int
            Parameters fitted besides the groups.
        kinds : sequence, optional
            Each group's family (the beam keeps the best set of each combination of families).
        extra_df : sequence of float, optional
            Parameters a group fits besides its columns.

        Returns
        -------
        list of list of int
            The group indices of the best set of each size.
        """
        return group_path(r0, groups, keys, self.max_groups, n_eff=n_eff, n_fixed=n_fixed,
                          beam_width=self.beam_width, kinds=kinds, extra_df=extra_df)

    def size(self, errors: dict[int, np.ndarray], blocks: np.ndarray) -> int:
        """How many groups: the fewest within one standard error of the best held-out error.

        Parameters
        ----------
        errors : dict of int to ndarray
            The held-out residuals of the model with k groups (k = 0 without any), on the same samples.
        blocks : ndarray of int
            Each sample's block.

        Returns
        -------
        int
            The number of groups (:func:`fewest_within_one_se`).
        """
        return fewest_within_one_se(errors, blocks)
