"""Where the held-out evaluation cuts the recordings.

Folds of segments within runs with guard bands against the filter's correlation (:func:`folds_of`), and the blocks of
the paired test, their length from the residual's measured autocorrelation (:func:`residual_block_length`,
:func:`with_blocks`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import signal

from euc_ros.core.states.contexts import Recording

#: Fewest folds of the held-out evaluation (segments per run = ceil(this / runs), at least 2).
MIN_FOLDS = 6


#: The residual's slow part (an effect's signature) is removed over this many filter windows before its
#: autocorrelation sets the block length (:func:`residual_block_length`).
TREND_WINDOWS = 16.0


#: Shortest block of the paired test, in filter windows. The block is twice the residual noise's integrated
#: correlation time, measured at 0.35-0.47 s on the power rides (1.2 s window); a floor of one whole window would
#: give only 15 blocks in 3 runs of 7 s. Measured on 100 no-effect rides (README, statistical power): the
#: per-candidate p-values stay uniform or conservative from 0.3 s to 1.2 s blocks (lag-1 correlation of the
#: blocks' log ratios -0.04); below half a window a block holds 3-4 correlated samples at the analysis rate and
#: its mean square can come near 0 (log ratios of -10), which costs power.
MIN_BLOCK_WINDOWS = 0.5
#: Effective independent samples per block counted by the discovery's information criterion and shrinkage. A
#: block is twice the residual noise's integrated autocorrelation time, so a series of duration T holds about two
#: effective samples per block; counting two let the discovery fit coloured pose noise (a 1 Hz corner) with a
#: low-passed pitch rate, whose column carries that same noise (test_artefacts_residual.py), so one is counted.
SAMPLES_PER_BLOCK = 1.0


@dataclass
class Fold:
    """One train/test split as sample masks per recording.

    Parameters
    ----------
    train, test : list of ndarray
        Per recording i, bool over its samples: trained on (``train[i]``), held out (``test[i]``).
    name : str
        The held-out segment, ``<recording>[<segment>]``.
    """

    train: list[np.ndarray]
    test: list[np.ndarray]
    name: str = ""


def _guard(t: np.ndarray, test: np.ndarray, guard_s: float) -> np.ndarray:
    """Samples within ``guard_s`` of a test sample (they share raw frames through the filter)."""
    if not test.any():
        return np.zeros_like(test)
    tt = t[test]
    j = np.searchsorted(tt, t)
    left = np.abs(t - tt[np.clip(j - 1, 0, tt.size - 1)])
    right = np.abs(tt[np.clip(j, 0, tt.size - 1)] - t)
    return np.minimum(left, right) < guard_s


def folds_of(recs: Sequence[Recording], n_segments: int = 3, guard_s: float = 0.0) -> list[Fold]:
    """Train/test splits within runs as well as across runs.

    Every run is cut into ``n_segments`` contiguous segments of whole blocks; each fold holds out one
    segment of one run and trains on everything else (the other runs, and the rest of that run minus
    ``guard_s`` on either side of the held-out segment: the derivative filter and coloured noise
    correlate neighbouring samples). So every sample is held out once, and each fold trains on
    ``1 - 1/(runs x segments)`` of the data (leave-one-run-out trained on ``1 - 1/runs``).

    Parameters
    ----------
    recs : sequence of Recording
        The recordings, their samples grouped into blocks (:func:`with_blocks`).
    n_segments : int
        Segments per run (fewer when a run has fewer blocks).
    guard_s : float
        Half-width of the guard band left out of the training samples around a held-out segment [s].

    Returns
    -------
    list of Fold
        One per segment of each run with blocks.
    """
    folds = []
    for i, rec in enumerate(recs):
        ub = np.unique(rec.block)
        if ub.size == 0:
            continue
        k = max(1, min(n_segments, ub.size))
        for j, chunk in enumerate(np.array_split(ub, k)):
            test = np.isin(rec.block, chunk)
            train = [np.ones(r.block.shape, bool) for r in recs]
            train[i] = ~(test | _guard(rec.ctx.t, test, guard_s))
            tests = [np.zeros(r.block.shape, bool) for r in recs]
            tests[i] = test
            folds.append(Fold(train, tests, f"{rec.name}[{j}]"))
    return folds


def residual_block_length(recs: Sequence[Recording], residuals: Sequence[np.ndarray], *, min_s: float,
                          trend_s: float, max_fraction: float = 0.25) -> float:
    """Block length [s] of the paired test from the residual's measured autocorrelation.

    The slow part of the residual (a cubic Savitzky-Golay fit over ``trend_s``: an unexplained effect's signature)
    is removed first, so the blocks follow the correlation of the residual's noise (the derivative filter,
    coloured pose noise), not the effect the test is looking for. Block = twice the noise's integrated
    autocorrelation time (``dt (1 + 2 sum rho_k)`` up to the first zero crossing: ``m dt`` for an m-sample
    moving average), at least ``min_s`` (one filter window), at most ``max_fraction`` of the shortest
    recording.

    Parameters
    ----------
    recs : sequence of Recording
        The recordings (their sample times).
    residuals : sequence of ndarray
        Each recording's residual (n_i,) [N m].
    min_s : float
        Shortest block [s].
    trend_s : float
        Window of the slow part removed [s].
    max_fraction : float
        Longest block as a fraction of the shortest recording's duration.

    Returns
    -------
    float
        The block length [s] (``min_s`` when no recording has 16 samples or a nonzero residual).
    """
    lags = []
    for rec, r in zip(recs, residuals):
        t = rec.ctx.t
        if t.size < 16:
            continue
        dt = float(np.median(np.diff(t)))
        m = min(max(5, int(round(trend_s / dt)) | 1), (t.size - 1) | 1 if t.size % 2 == 0 else t.size)
        trend = signal.savgol_filter(r, m, 3, mode="interp") if m > 3 and m <= r.size else np.full(r.size, r.mean())
        e = r - trend
        e = e - e.mean()
        n = e.size
        f = np.fft.rfft(e, 2 * n)
        acf = np.fft.irfft(f * np.conj(f))[:n]
        if acf[0] <= 0:
            continue
        acf = acf / acf[0]
        below = np.flatnonzero(acf[1:] <= 0)
        zc = below[0] + 1 if below.size else n
        # integrated autocorrelation time up to the first zero crossing: dt (1 + 2 sum rho_k); robust to
        # the crossing's estimation noise (the tail it may cut is where rho is small)
        lags.append(dt * (1.0 + 2.0 * float(np.sum(acf[1:zc]))))
    if not lags:
        return float(min_s)
    shortest = min(float(rec.ctx.t[-1] - rec.ctx.t[0]) for rec in recs if rec.ctx.t.size) if recs else np.inf
    return float(min(max(2.0 * float(np.median(lags)), min_s), max(min_s, max_fraction * shortest)))


def with_blocks(recs: Sequence[Recording], block_s: float) -> list[Recording]:
    """The recordings with their samples grouped into blocks of ``block_s`` seconds.

    Parameters
    ----------
    recs : sequence of Recording
        The recordings.
    block_s : float
        Block length [s].

    Returns
    -------
    list of Recording
        The same contexts, ``block`` the index of each sample's block from the recording's first sample.
    """
    out = []
    for rec in recs:
        t = rec.ctx.t
        block = np.floor((t - (t[0] if t.size else 0.0)) / block_s).astype(int)
        out.append(Recording(rec.name, rec.ctx, block, rec.index))
    return out


