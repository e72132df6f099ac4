"""The family-wise correction of a selection step (max-T over sign flips of whole blocks).

References computed independently here: the exact sign-flip distribution by enumerating every flip with
itertools (not the bit trick of the implementation), Bonferroni's bound, and the family-wise error on
simulated null data with its binomial bound.
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy import stats

from euc_ros.core.model.extended import Model
from euc_ros.core.residual.selection import HeldOut
from euc_ros.core.residual.significance import max_t_adjusted, paired_block_test


def _held_out(per_block_ms, samples=4, rng=None):
    """A HeldOut whose block b has ``samples`` residuals with mean square exactly ``per_block_ms[b]``."""
    res, blk = [], []
    for b, ms in enumerate(per_block_ms):
        r = np.full(samples, np.sqrt(ms))
        r[::2] *= -1
        res.append(r)
        blk.append(np.full(samples, b))
    return HeldOut(Model(), np.concatenate(res), np.concatenate(blk), [])


def _t(d):
    return d.mean() / (d.std(ddof=1) / np.sqrt(d.size))


def test_single_candidate_is_the_exact_sign_flip_test():
    rng = np.random.default_rng(5)
    nb = 9
    base_ms = rng.uniform(0.5, 2.0, nb)
    d = rng.normal(0.4, 0.5, nb)                       # log(base / cand) per block
    base, cand = _held_out(base_ms), _held_out(base_ms * np.exp(-d))
    t_obs = _t(d)
    flips = [_t(np.array(s) * d) for s in itertools.product([1, -1], repeat=nb)]
    expected = np.mean(np.array(flips) >= t_obs - 1e-9)
    assert max_t_adjusted(base, [cand])[0] == pytest.approx(expected, abs=1e-12)
    # and close to the t-test it replaces in the step (same statistic, its exact null instead of Student's)
    assert abs(np.log(expected) - np.log(paired_block_test(base, cand))) < np.log(3.0)


def test_identical_candidates_pay_no_multiplicity_and_independent_ones_pay_at_most_bonferroni():
    rng = np.random.default_rng(6)
    nb = 12
    base_ms = rng.uniform(0.5, 2.0, nb)
    d = rng.normal(0.5, 0.6, nb)
    base, cand = _held_out(base_ms), _held_out(base_ms * np.exp(-d))
    single = max_t_adjusted(base, [cand])[0]
    five = max_t_adjusted(base, [cand] * 5)
    assert np.allclose(five, single)                   # Bonferroni would ask alpha / 5 of each
    # unrelated candidates: the adjusted p lies between the single one and Bonferroni's k * p
    others = [_held_out(base_ms * np.exp(-rng.normal(0.0, 0.6, nb))) for _ in range(4)]
    p = max_t_adjusted(base, [cand] + others)[0]
    assert single - 1e-12 <= p <= 5 * single + 1e-12


def test_family_wise_error_at_most_alpha_on_null_data():
    """Five correlated candidates, 30 blocks, no effect (log ratios symmetric about 0): over 400 sets the
    rate of any adjusted p below alpha stays within the binomial 99.9 % bound of alpha."""
    rng = np.random.default_rng(7)
    nb, k, sets, alpha = 30, 5, 400, 0.1
    hits = 0
    for _ in range(sets):
        base_ms = rng.uniform(0.5, 2.0, nb)
        common = rng.normal(0.0, 0.5, nb)
        cands = [_held_out(base_ms * np.exp(-(common + rng.normal(0.0, 0.3, nb)))) for _ in range(k)]
        hits += bool(np.any(max_t_adjusted(_held_out(base_ms), cands, n_flips=4096) < alpha))
    assert hits <= stats.binom.ppf(0.999, sets, alpha), hits
    # and it is not trivially conservative: the family-wise rate is near alpha, not near 0
    assert hits >= stats.binom.ppf(0.001, sets, alpha), hits


def test_blocks_a_candidate_lacks_are_left_out_of_its_statistic():
    rng = np.random.default_rng(8)
    nb = 10
    base_ms = rng.uniform(0.5, 2.0, nb)
    d = rng.normal(0.5, 0.4, nb)
    base, full = _held_out(base_ms), _held_out(base_ms * np.exp(-d))
    keep = full.block != 3                              # e.g. masked edge samples of a time shift
    part = HeldOut(Model(), full.residual[keep], full.block[keep], [])
    dd = np.delete(d, 3)
    t_obs = _t(dd)
    expected = np.mean([_t(np.array(s) * dd) >= t_obs - 1e-9 for s in itertools.product([1, -1], repeat=nb - 1)])
    assert max_t_adjusted(base, [part])[0] == pytest.approx(expected, abs=1e-12)


def test_paired_block_test_matches_a_block_by_block_t_test():
    # blocks of uneven size in shuffled order, a block the candidate lacks and one where it is exactly 0
    rng = np.random.default_rng(11)
    nb = 60
    sizes = rng.integers(3, 12, nb)
    block = rng.permutation(np.repeat(np.arange(nb) * 7 + 3, sizes))
    base = HeldOut(Model(), rng.standard_normal(block.size) * 1.3, block, [])
    res = rng.standard_normal(block.size)
    res[block == block[0]] = 0.0
    keep = block != block[1]
    cand = HeldOut(Model(), res[keep], block[keep], [])
    d = []
    for b in np.unique(block):
        if not np.any(cand.block == b):
            continue
        mb, mc = np.mean(base.residual[base.block == b] ** 2), np.mean(cand.residual[cand.block == b] ** 2)
        if mb > 0 and mc > 0:
            d.append(np.log(mb / mc))
    assert len(d) == nb - 2
    want = stats.ttest_1samp(d, 0.0, alternative="greater").pvalue
    assert paired_block_test(base, cand) == pytest.approx(want, rel=1e-9)
