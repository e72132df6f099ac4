"""The forward selection's rules that need no ride: a name holds on every recording's company."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from euc_ros.core.model.extended import Model
from euc_ros.core.residual.selection import HeldOut
from euc_ros.core.residual.selector import ForwardSelector, holds_without_any_recording

BLOCKS, PER_BLOCK = 10, 12


def setup_of(n_recordings: int, segments: int = 1):
    """Recordings of 10 blocks of 12 samples each (their blocks numbered from 0 within each); with one recording,
    folds holding out ``segments`` contiguous segments of it."""
    recs = [SimpleNamespace(block=np.repeat(np.arange(BLOCKS), PER_BLOCK)) for _ in range(n_recordings)]
    parts = np.array_split(np.arange(BLOCKS), segments)
    folds = [SimpleNamespace(test=[np.isin(recs[0].block, p)]) for p in parts] if n_recordings == 1 else []
    return SimpleNamespace(recs=recs, folds=folds)


def heldout(residual: np.ndarray, n_recordings: int) -> HeldOut:
    block = np.repeat(np.arange(n_recordings * BLOCKS), PER_BLOCK)
    return HeldOut(Model(), residual, block, [])


def test_a_cut_every_recording_shares_holds_and_one_recordings_does_not():
    """Three recordings with the same residual scatter. A candidate that halves it in every recording holds with
    any one left out; one that removes all of it in the first recording only cuts the whole RMSE by 18 % (above the
    10 % minimum gain) but nothing once that recording is left out."""
    rng = np.random.default_rng(3)
    n = 3
    r0 = rng.normal(0.0, 1.0, n * BLOCKS * PER_BLOCK)
    first = np.arange(r0.size) < BLOCKS * PER_BLOCK
    rules = ForwardSelector(min_gain=0.1)
    everywhere, one = heldout(0.5 * r0, n), heldout(np.where(first, 0.0, r0), n)
    base = heldout(r0, n)
    assert rules.cuts(one, base) and rules.cuts(everywhere, base)
    assert holds_without_any_recording(setup_of(n), base, everywhere, rules)
    assert not holds_without_any_recording(setup_of(n), base, one, rules)


def test_one_recording_in_one_segment_has_nothing_to_leave_out():
    rng = np.random.default_rng(4)
    r0 = rng.normal(0.0, 1.0, BLOCKS * PER_BLOCK)
    rules = ForwardSelector(min_gain=0.1)
    assert holds_without_any_recording(setup_of(1), heldout(r0, 1), heldout(0.99 * r0, 1), rules)


def test_one_recording_leaves_out_its_held_out_segments_in_turn():
    """One recording held out in two segments: a cut in both halves holds, one that removes the first half's residual
    only (29 % of the RMSE) does not once that half is left out."""
    rng = np.random.default_rng(5)
    r0 = rng.normal(0.0, 1.0, BLOCKS * PER_BLOCK)
    first = np.arange(r0.size) < BLOCKS * PER_BLOCK // 2
    rules = ForwardSelector(min_gain=0.1)
    base, one = heldout(r0, 1), heldout(np.where(first, 0.0, r0), 1)
    assert rules.cuts(one, base)
    assert holds_without_any_recording(setup_of(1, 2), base, heldout(0.5 * r0, 1), rules)
    assert not holds_without_any_recording(setup_of(1, 2), base, one, rules)
