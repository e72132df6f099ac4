"""Random error of h under correlation: a moving-block bootstrap of the pooled fit.

The Savitzky-Golay filter correlates neighbouring samples over its window, so the formal
curvature-based ``h_std_m`` (independent samples) is far too small (a 25-minute ride gave +-0.4 mm).
:func:`block_bootstrap` resamples whole blocks of consecutive samples (non-overlapping blocks); the
block length comes from the residual's measured autocorrelation (twice its first zero crossing, at
least one filter window). Each block's SSE(h) is computed once on a fine grid, so a replicate is a
weighted sum: 1000 replicates cost one matrix product.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from euc_ros.core.identify.fit import sse_grid

#: Half-width of the fine grid around h* for the bootstrap [m] and its step [m].
LOCAL_HALF_WIDTH_M = 0.3


LOCAL_STEP_M = 5e-4


def residuals_at(coef: np.ndarray, h: float) -> np.ndarray:
    """Per-sample residual ``e(h) = c (a0 + a1 h + a2 h^2) / (d0 + d1 h)`` [N m].

    Parameters
    ----------
    coef : ndarray (6, n)
        Rows ``c, a0, a1, a2, d0, d1`` of :func:`~euc_ros.core.identify.fit.residual_coefficients`.
    h : float
        CoG height [m].

    Returns
    -------
    ndarray (n,)
        ``M_d1 - M_d2`` of every sample at ``h`` [N m].
    """
    c, a0, a1, a2, d0, d1 = coef
    return c * (a0 + h * (a1 + h * a2)) / (d0 + d1 * h)


def first_zero_crossing(e: np.ndarray, max_lag: int) -> int:
    """Lag [samples] where the autocorrelation of ``e`` first drops to zero (``max_lag`` if never).

    Parameters
    ----------
    e : array_like (n,)
        A series (its mean is removed).
    max_lag : int
        Largest lag searched [samples].

    Returns
    -------
    int
        The first lag with a non-positive autocorrelation; ``min(max_lag, n - 1)`` when there is none, 1 for
        fewer than 4 samples or a constant series.
    """
    e = np.asarray(e, dtype=float) - np.mean(e)
    n = e.size
    if n < 4:
        return 1
    m = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.fft.rfft(e, m)
    acf = np.fft.irfft(spec * np.conj(spec), m)[:min(max_lag, n - 1) + 1]
    if acf[0] <= 0:
        return 1
    below = np.flatnonzero(acf <= 0)
    return int(below[0]) if below.size else int(min(max_lag, n - 1))


def block_length(coefs: Sequence[np.ndarray], h: float, window: int) -> int:
    """Block length [samples]: twice the residual's first ACF zero crossing, at least one filter window.

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples in time order.
    h : float
        CoG height the residual is taken at [m].
    window : int
        Savitzky-Golay window [samples].

    Returns
    -------
    int
        Twice the median first zero crossing over the recordings of more than 8 samples (``window`` when
        there is none), and at least ``window``.
    """
    lags = [first_zero_crossing(residuals_at(c, h), 20 * window) for c in coefs if c.shape[1] > 8]
    k0 = int(np.median(lags)) if lags else window
    return max(int(window), 2 * k0)


def block_counts(coefs: Sequence[np.ndarray], length: int) -> list[int]:
    """Per recording, the number of blocks of :func:`_blocks_of` (0 for a recording without samples).

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples.
    length : int
        Block length [samples].

    Returns
    -------
    list of int
        ``max(1, n_i // length)``, 0 when ``n_i`` is 0.
    """
    return [max(1, c.shape[1] // length) if c.shape[1] else 0 for c in coefs]


def _blocks_of(coefs: Sequence[np.ndarray], length: int, counts: Sequence[int] | None = None) -> list[np.ndarray]:
    """The blocks of ``length`` consecutive samples of each recording, or ``counts[i]`` blocks of recording ``i``.

    Without ``counts``, k blocks of ~length per recording, the rest spread; ``counts[i]`` blocks of recording ``i`` when
    ``counts`` is given.
    """
    counts = block_counts(coefs, length) if counts is None else counts
    out = []
    for c, k in zip(coefs, counts, strict=True):
        n = c.shape[1]
        if n == 0 or k == 0:
            continue
        edges = np.linspace(0, n, k + 1).astype(int)
        out += [c[:, a:b] for a, b in zip(edges[:-1], edges[1:])]
    return out


def block_sse(coefs: Sequence[np.ndarray], length: int, grid: np.ndarray) -> np.ndarray:
    """SSE(h) of every block of ``length`` consecutive samples of each recording.

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples in time order.
    length : int
        Block length [samples].
    grid : ndarray (g,)
        CoG heights [m].

    Returns
    -------
    ndarray (n_blocks, g)
        Each block's sum of squared residuals at every grid point [N^2 m^2].
    """
    rows = [sse_grid(c, grid) for c in _blocks_of(coefs, length)]
    return np.array(rows).reshape(-1, grid.size)


#: The bootstrap's coarse grid takes every this many points of the fine grid (:func:`block_bootstrap`).
COARSE_EVERY = 10


def block_bootstrap(coefs: Sequence[np.ndarray], h: float, window: int, dt: float, *, n_boot: int = 1000,
                    seed: int = 0, h_bounds=(0.1, 1.2), counts: Sequence[int] | None = None):
    """Moving-block bootstrap of h: ``(h replicates, block length [samples], n_blocks, grid)``.

    ``counts``: the number of blocks of each recording (default from the block length,
    :func:`block_counts`). Two sets of coefficients of the same samples (e.g. filtered with two
    windows) given the same counts and ``seed`` get the same blocks drawn in every replicate: their
    replicates are paired.

    Replicates whose optimum sits on the fine grid's edge are returned as +-inf (the data do not
    bound h there).

    The replicates' SSE curves are first found on every :data:`COARSE_EVERY`-th point of the fine grid;
    the fine grid is then evaluated only from one coarse step below the lowest replicate optimum to
    one above the highest. A replicate's fine optimum lies within one coarse step of its coarse one
    whenever its SSE curve has a single minimum on the scale of a coarse step (5 mm), so the
    replicates are those of the whole fine grid, at the cost of the span the replicates cover.

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples in time order.
    h : float
        The pooled fit's h [m] (the centre of the fine grid).
    window : int
        Savitzky-Golay window [samples] (the shortest block).
    dt : float
        Sample period [s] (not used: lengths are in samples).
    n_boot : int
        Number of replicates.
    seed : int
        Seed of the block draws.
    h_bounds : tuple of float
        Search range of h [m]; the fine grid spans ``h +- LOCAL_HALF_WIDTH_M`` within it.
    counts : sequence of int, optional
        Blocks per recording (default :func:`block_counts`).

    Returns
    -------
    replicates : ndarray (n_boot,)
        Bootstrap replicates of h [m] (+-inf at the fine grid's edges).
    length : int
        Block length [samples] (:func:`block_length`).
    n_blocks : int
        Number of blocks drawn from.
    grid : ndarray
        The fine grid [m].
    """
    length = block_length(coefs, h, window)
    lo = max(h_bounds[0], h - LOCAL_HALF_WIDTH_M)
    hi = min(h_bounds[1], h + LOCAL_HALF_WIDTH_M)
    grid = np.arange(lo, hi + LOCAL_STEP_M / 2, LOCAL_STEP_M)
    blocks = _blocks_of(coefs, length, counts)
    nb = len(blocks)
    p_blocks = np.full(nb, 1.0 / nb)
    # the replicates' block counts, drawn in chunks of replicates (the same draws as all at once: the
    # generator fills the rows in order) and drawn again for the second pass: 1000 replicates x ~3600
    # blocks of an hour held at once were 58 MB (int64 and its float copy), the residual's memory peak
    chunk = max(1, min(n_boot, (1 << 20) // max(nb, 1)))
    # the counts of the first pass kept for the second as int32 when they fit in 8 MB (4 bytes a count, half
    # the int64 the generator gives; the float copy is a chunk's): the same draws, drawn once
    keep = n_boot * nb * 4 <= (8 << 20)
    kept: list[np.ndarray] = []

    def argmin_of(S: np.ndarray) -> np.ndarray:
        rng = np.random.default_rng(seed) if not kept else None
        out = np.empty(n_boot, dtype=np.int64)
        for j, a in enumerate(range(0, n_boot, chunk)):
            if rng is None:
                counts = kept[j]
            else:
                counts = rng.multinomial(nb, p_blocks, size=min(chunk, n_boot - a))
                if keep:
                    kept.append(counts.astype(np.int32))
            W = counts.astype(float)
            out[a:a + W.shape[0]] = np.argmin(W @ S, axis=1)
        return out

    coarse = np.arange(0, grid.size, COARSE_EVERY)
    if coarse[-1] != grid.size - 1:
        coarse = np.append(coarse, grid.size - 1)
    Sc = np.array([sse_grid(c, grid[coarse]) for c in blocks]).reshape(-1, coarse.size)
    kc = argmin_of(Sc)
    f0 = int(coarse[max(int(kc.min()) - 1, 0)]) if kc.size else 0
    f1 = int(coarse[min(int(kc.max()) + 1, coarse.size - 1)]) if kc.size else grid.size - 1
    S = np.array([sse_grid(c, grid[f0:f1 + 1]) for c in blocks]).reshape(-1, f1 + 1 - f0)
    k = f0 + argmin_of(S)
    hb = grid[k].astype(float)
    hb[k == 0] = -np.inf
    hb[k == grid.size - 1] = np.inf
    return hb, length, nb, grid
