"""Recordings worked on in blocks of frames, so memory does not grow with copies of the recording.

A whole-recording step that needs, per frame, only frames nearby (the bridging, the geometry:
:func:`~euc_ros.core.states.geometry.block_geometry`) reads the poses block by block
(:func:`pose_block`, :data:`READ_FRAMES` frames).

The uncertainty and noise-floor steps reconstruct the recording again with noise added
(SIMEX, :func:`~euc_ros.core.identify.simex.eiv_bias`; the residual's noise floor,
:func:`~euc_ros.core.residual.noise.noise_floor`). :class:`PerturbedSeries` is such a re-noised
recording that never exists whole: it hands out the perturbed poses of any block of frames
(:meth:`PerturbedSeries.pose_block`), made on demand from the base recording. Its noise is
:class:`BlockNoise`: the standard normal draws of block ``k`` (:data:`BLOCK_FRAMES` frames, every
body and component at once) come from their own generator, seeded by one number drawn from the
caller's generator and ``k``, so any block is drawn directly (no walk through the stream before it)
and a block read twice, or out of order, gives the same numbers. The block being read and the end of the
one before are kept, so reading a recording block after block with margins draws every block once.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from euc_ros.core.mocap.series import MocapSeries

#: Frames per block of the noise draws (:class:`BlockNoise`: the draws depend on it).
BLOCK_FRAMES = 4096

#: Frames per block read by :func:`~euc_ros.core.states.geometry.block_geometry` (its results do not depend
#: on it): a block's working set (the perturbed poses and the geometry's temporaries) stays small beside a
#: short recording's arrays. A read may span noise blocks.
READ_FRAMES = 1024


def pose_block(series, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(position, quat, tracked)`` of frames ``lo:hi`` of every body.

    Views of a :class:`~euc_ros.core.mocap.series.MocapSeries`, or a :class:`PerturbedSeries`' block.

    Parameters
    ----------
    series : MocapSeries or PerturbedSeries
        The recording.
    lo, hi : int
        Frame range ``lo:hi``.

    Returns
    -------
    position : numpy.ndarray
        Pivot positions (b, hi - lo, 3) [m].
    quat : numpy.ndarray
        Quaternions (b, hi - lo, 4), (x, y, z, w).
    tracked : numpy.ndarray
        Tracked flags (b, hi - lo).
    """
    block = getattr(series, "pose_block", None)
    if block is not None:
        return block(lo, hi)
    return series.position[:, lo:hi], series.quat[:, lo:hi], series.tracked[:, lo:hi]


def release(series) -> None:
    """Let a :class:`PerturbedSeries` drop what it keeps between block reads, once a pass over its blocks is done.

    What it keeps is its noise's recent blocks; a plain recording has nothing to drop. Reading it again gives
    the same poses.

    Parameters
    ----------
    series : MocapSeries or PerturbedSeries
        The recording.
    """
    drop = getattr(series, "release", None)
    if drop is not None:
        drop()


def materialize(series) -> MocapSeries:
    """``series`` as a plain :class:`~euc_ros.core.mocap.series.MocapSeries` (a :class:`PerturbedSeries` made whole).

    Parameters
    ----------
    series : MocapSeries or PerturbedSeries
        The recording.

    Returns
    -------
    MocapSeries
        ``series`` itself when plain, else its whole perturbed poses.
    """
    make = getattr(series, "materialize", None)
    return make() if make is not None else series


class PerturbedSeries:
    """A recording with its poses perturbed, made block by block on demand (see the module docstring).

    Every attribute but ``position`` and ``quat`` is the base recording's. ``pose_block(lo, hi)``
    gives the perturbed poses of frames ``lo:hi``; ``position``, ``quat`` and :meth:`materialize`
    build the whole (for code that needs all frames at once, e.g. the skeleton CoG).

    Parameters
    ----------
    base : MocapSeries
    perturb : callable
        ``perturb(lo, hi) -> (position, quat)``: new arrays (b, hi - lo, 3) and (b, hi - lo, 4).
    forget : callable, optional
        Drops what ``perturb`` keeps between calls (:meth:`release`), without changing what it gives.
    """

    def __init__(self, base, perturb: Callable[[int, int], tuple[np.ndarray, np.ndarray]],
                 forget: Callable[[], None] | None = None) -> None:
        self._base = base
        self._perturb = perturb
        self._forget = forget

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._base, name)

    def pose_block(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(position, quat, tracked)`` of frames ``lo:hi``, perturbed (new arrays but ``tracked``).

        Parameters
        ----------
        lo, hi : int
            Frame range ``lo:hi``.

        Returns
        -------
        position : numpy.ndarray
            Pivot positions (b, hi - lo, 3) [m].
        quat : numpy.ndarray
            Quaternions (b, hi - lo, 4), (x, y, z, w).
        tracked : numpy.ndarray
            Tracked flags (b, hi - lo), a view of the base recording's.
        """
        pos, quat = self._perturb(lo, hi)
        return pos, quat, self._base.tracked[:, lo:hi]

    def release(self) -> None:
        """Drop what the perturbation keeps between block reads (see :func:`release`)."""
        if self._forget is not None:
            self._forget()

    @property
    def position(self) -> np.ndarray:
        """Perturbed positions (b, n, 3) of the whole recording (made on each read)."""
        return self._perturb(0, self._base.n_frames)[0]

    @property
    def quat(self) -> np.ndarray:
        """Perturbed quaternions (b, n, 4) of the whole recording (made on each read)."""
        return self._perturb(0, self._base.n_frames)[1]

    def materialize(self) -> MocapSeries:
        """The whole perturbed recording as a :class:`~euc_ros.core.mocap.series.MocapSeries`.

        Returns
        -------
        MocapSeries
            The base recording with the perturbed positions and quaternions.
        """
        pos, quat = self._perturb(0, self._base.n_frames)
        return replace(materialize(self._base), position=pos, quat=quat)


class BlockNoise:
    """Standard normal draws for a recording of ``n`` frames, made block by block on demand.

    Block ``k`` (frames ``k BLOCK_FRAMES`` to ``(k + 1) BLOCK_FRAMES``) holds an array
    ``(rows, frames in the block, width)`` drawn by its own PCG64 generator, seeded from one integer
    drawn from ``rng`` on construction (the caller's generator advances by that one draw) and ``k``:
    the blocks are independent, any of them is made directly, and the same block is always the same
    numbers. Drawn in float32 (about twice as fast as float64; the draws scale noise of ~1e-4 m and
    ~1e-2 rad, where float32's relative 6e-8 is far below anything the analysis resolves) and
    returned as float64. At most ``cache`` blocks are kept; when a block is drawn, the block before it
    keeps only its last :data:`READ_FRAMES` frames (a forward pass whose reads have margins steps back
    over a block's edge by less than a read) and earlier ones are dropped, so a pass holds about one block.

    Parameters
    ----------
    rng : numpy.random.Generator
        Generator of the one seed drawn.
    n : int
        Frames of the recording.
    rows : int
        Rows of each draw (bodies).
    width : int
        Components per row and frame.
    cache : int
        Blocks kept at most.
    """

    def __init__(self, rng: np.random.Generator, n: int, rows: int, width: int, *, cache: int = 3) -> None:
        self._entropy = int(rng.integers(0, 2**63 - 1))
        self.n, self.rows, self.width = int(n), int(rows), int(width)
        self._cache: dict[int, tuple[int, np.ndarray]] = {}   # block -> (its first frame kept, draws from there)
        self._cache_size = int(cache)

    def _part(self, k: int, a: int) -> np.ndarray:
        """The draws of block ``k`` from its frame ``a`` (counted from the block's first) on."""
        hit = self._cache.get(k)
        if hit is not None and hit[0] <= a:
            return hit[1][:, a - hit[0]:]
        tail = min(READ_FRAMES, BLOCK_FRAMES)
        for j in [j for j in self._cache if j < k]:
            first, z = self._cache[j]
            if j < k - 1:
                del self._cache[j]
            elif z.shape[1] > tail:         # a copy of the last frames: the whole block is let go
                self._cache[j] = (first + z.shape[1] - tail, z[:, -tail:].copy())
            del z
        frames = min(self.n, (k + 1) * BLOCK_FRAMES) - k * BLOCK_FRAMES
        g = np.random.Generator(np.random.PCG64(np.random.SeedSequence(self._entropy, spawn_key=(k,))))
        z = g.standard_normal((self.rows, frames, self.width), dtype=np.float32)
        self._cache.pop(k, None)
        while len(self._cache) >= self._cache_size:
            self._cache.pop(next(iter(self._cache)))
        self._cache[k] = (0, z)
        return z[:, a:]

    def forget(self) -> None:
        """Drop the kept blocks (a block asked for again is drawn again: the same numbers)."""
        self._cache.clear()

    def draw(self, lo: int, hi: int, dtype=float) -> np.ndarray:
        """The draws of frames ``lo:hi``.

        An array (rows, hi - lo, width), float64 (``dtype`` None: as drawn, float32, possibly a view of a kept
        block).

        Parameters
        ----------
        lo, hi : int
            Frame range ``lo:hi``.
        dtype : type or None
            Type of the result; None: float32 as drawn.

        Returns
        -------
        numpy.ndarray
            Standard normal draws (rows, hi - lo, width).
        """
        k0, k1 = block_span(lo, hi)
        first = k0 * BLOCK_FRAMES
        if k1 - k0 == 1:
            z = self._part(k0, lo - first)[:, :hi - lo]
            return z if dtype is None else z.astype(dtype)
        # several blocks: each one's part written into the result (no concatenated copy of the blocks)
        out = np.empty((self.rows, hi - lo, self.width), dtype=np.float32 if dtype is None else dtype)
        for k in range(k0, k1):
            a, b = max(lo, k * BLOCK_FRAMES), min(hi, (k + 1) * BLOCK_FRAMES)
            out[:, a - lo:b - lo] = self._part(k, a - k * BLOCK_FRAMES)[:, :b - a]
        return out


def block_span(lo: int, hi: int, block: int | None = None) -> tuple[int, int]:
    """Blocks ``k0 .. k1 - 1`` (of :data:`BLOCK_FRAMES` frames) covering frames ``lo:hi``.

    Parameters
    ----------
    lo, hi : int
        Frame range ``lo:hi``.
    block : int, optional
        Frames per block; default :data:`BLOCK_FRAMES`.

    Returns
    -------
    k0, k1 : int
        First block and one past the last.
    """
    block = block or BLOCK_FRAMES
    return lo // block, -(-hi // block)


def block_counts(n: int, block: int | None = None) -> np.ndarray:
    """Frames in each block (of :data:`BLOCK_FRAMES` frames) of a recording of ``n`` frames.

    Parameters
    ----------
    n : int
        Frames of the recording.
    block : int, optional
        Frames per block; default :data:`BLOCK_FRAMES`.

    Returns
    -------
    numpy.ndarray
        Frames per block (ceil(n / block),), the last possibly shorter.
    """
    block = block or BLOCK_FRAMES
    starts = np.arange(0, n, block)
    return np.minimum(starts + block, n) - starts
