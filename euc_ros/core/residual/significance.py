"""Whether a held-out improvement is real.

A one-sided paired test over blocks of the held-out residual (:func:`paired_block_test`), and the max-T correction over
the candidates of one selection step (:func:`max_t_adjusted`, sign flips of whole blocks).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from scipy import stats

from euc_ros.core.residual.selection import HeldOut

#: Sign flips of the max-T correction over the candidates of a selection step (:func:`max_t_adjusted`); exact
#: enumeration when the blocks are at most log2 of this.
MAX_T_FLIPS = 1 << 15


#: Another candidate is reported as ambiguous with the selected one unless the selected one is better
#: than it at this one-sided level (paired block test).
AMBIGUITY_ALPHA = 0.05


def paired_block_test(base: HeldOut, cand: HeldOut) -> float:
    """One-sided p-value that the candidate's held-out squared residual is smaller than the base's.

    Samples within a block (~1 s) are correlated by the derivative filter, so blocks are the units:
    per block the log ratio of the mean squared residuals, tested with a one-sided t-test for a mean
    above 0. The log ratio weighs every block alike, so a few loud blocks cannot dominate, and is
    symmetric under exchange of the two models.

    Parameters
    ----------
    base : HeldOut
        The reference model's held-out residual; its blocks are the units.
    cand : HeldOut
        The candidate's, on the same blocks (a block it lacks is left out).

    Returns
    -------
    float
        The p-value; 1 with fewer than 3 usable blocks or log ratios all 0.
    """
    d = _block_log_ratios(base, [cand])[0]
    d = d[np.isfinite(d)]
    if d.size < 3 or np.allclose(d, 0):
        return 1.0
    return float(stats.ttest_1samp(d, 0.0, alternative="greater").pvalue)


def _block_log_ratios(base: HeldOut, cands: Sequence[HeldOut]) -> np.ndarray:
    """Per candidate and block of ``base``: log of the base's over the candidate's held-out mean square.

    NaN where the candidate has no sample of that block or a mean square is 0.
    """
    ub, inv = np.unique(base.block, return_inverse=True)
    mb = np.bincount(inv, base.residual ** 2, ub.size) / np.maximum(np.bincount(inv, None, ub.size), 1)
    D = np.full((len(cands), ub.size), np.nan)
    for j, c in enumerate(cands):
        pos = np.searchsorted(ub, c.block)
        inside = (pos < ub.size) & (ub[np.minimum(pos, ub.size - 1)] == c.block)
        cnt = np.bincount(pos[inside], None, ub.size)
        mc = np.bincount(pos[inside], c.residual[inside] ** 2, ub.size) / np.maximum(cnt, 1)
        ok = (cnt > 0) & (mb > 0) & (mc > 0)
        D[j, ok] = np.log(mb[ok] / mc[ok])
    return D


def max_t_adjusted(base: HeldOut, cands: Sequence[HeldOut], n_flips: int = MAX_T_FLIPS, seed: int = 0) -> np.ndarray:
    """Family-wise adjusted one-sided p-values of the candidates of one selection step (max-T, sign flips).

    Per block the log ratio of the held-out mean squares (as :func:`paired_block_test`); per candidate the
    t statistic of their mean. Under the null hypothesis (no candidate explains anything) the blocks' log
    ratios are symmetric about 0 or shifted below it (a fitted candidate overfits its training data), and
    blocks are independent units: flipping the signs of whole blocks, the same flips for every candidate,
    draws from the joint null distribution of the statistics, so the correlation between candidates (the
    twins of the library fit nearly the same signature) is kept. The adjusted p of a candidate is the
    fraction of flips whose largest statistic over all candidates reaches its own (Westfall and Young's
    single-step max-T): the family-wise error is at most alpha, like Bonferroni's, but Bonferroni's
    alpha / (number of candidates) holds under any dependence and so is conservative for correlated tests.
    Exact over all 2^blocks flips when they are at most ``n_flips``, otherwise ``n_flips`` random ones
    (fixed ``seed``, the identity included).

    Parameters
    ----------
    base : HeldOut
        The current model's held-out residual; its blocks are the units.
    cands : sequence of HeldOut
        Each candidate's held-out residual.
    n_flips : int
        Most sign flips.
    seed : int
        Seed of the random flips.

    Returns
    -------
    ndarray (len(cands),)
        The adjusted p-values; 1 for a candidate with fewer than 3 usable blocks or log ratios all 0.
    """
    if not cands:
        return np.zeros(0)
    D = _block_log_ratios(base, cands)
    ok = np.isfinite(D)
    n = ok.sum(axis=1)
    D0 = np.where(ok, D, 0.0)
    nb = D.shape[1]
    if nb == 0:
        return np.ones(len(cands))
    ss = np.sum(D0 ** 2, axis=1)                      # invariant under sign flips
    nn = np.maximum(n, 2).astype(float)

    def t_of(mean):
        var = np.maximum(ss - nn * mean ** 2, 0.0) / (nn - 1)
        return mean / np.sqrt(np.maximum(var, 1e-300) / nn)

    t_obs = t_of(D0.sum(axis=1) / nn)
    exact = 2 ** nb <= n_flips
    total = 2 ** nb if exact else n_flips
    # the flips drawn in chunks of ~2^21 signs (int8: a 60-minute recording has ~6000 blocks, and all 2^15
    # flips at once were 1.5 GB), evaluated in parts of ~2^17 signs (their float signs and statistics are a
    # part's: a fixed few MB, however many blocks and candidates)
    chunk = max(1, (1 << 21) // nb)
    part = max(1, (1 << 17) // nb)
    rng = None if exact else np.random.default_rng(seed)
    t_max = np.empty(total)
    for lo in range(0, total, chunk):
        hi = min(lo + chunk, total)
        if exact:
            bits = (np.arange(lo, hi)[:, None] >> np.arange(nb)[None, :]) & 1
        else:
            bits = rng.integers(0, 2, size=(hi - lo, nb), dtype=np.int8)
            if lo == 0:
                bits[0] = 0                           # the identity
        for a in range(0, hi - lo, part):
            S = 1.0 - 2.0 * bits[a:a + part]
            T = t_of((S @ D0.T) / nn)                 # (flips, candidates)
            T[:, n < 3] = -np.inf
            t_max[lo + a:lo + a + S.shape[0]] = T.max(axis=1)
            del S, T
    t_max.sort()
    exceed = t_max.size - np.searchsorted(t_max, t_obs - 1e-12 * np.abs(t_obs), side="left")
    # (the random flips include the identity: exceed / flips is (1 + others) / (1 + other flips), a valid p)
    p = np.minimum(exceed / t_max.size, 1.0)
    p[(n < 3) | np.all(np.isclose(D0, 0.0), axis=1)] = 1.0
    return p
