"""Whole-recording work in blocks of frames, so its memory does not grow with copies of the recording.

The state reconstruction of a recording (:func:`~euc_ros.core.euc.kinematics.reconstruct_states`)
needs, per frame, every body's bridged pose and the frame's geometry; neither depends on other
frames beyond the bridging's ``max_gap``. :func:`block_geometry` therefore bridges and evaluates
:func:`~euc_ros.core.euc.kinematics.frame_geometry` block by block (:data:`BLOCK_FRAMES` frames,
each read with ``max_gap + 1`` frames of margin on both sides so every bridged gap sees both its
ends) and keeps only the per-frame outputs the states are made of. The peak memory is the outputs
plus one block's working set, where bridging and evaluating the whole recording at once cost a full
copy of its poses plus the geometry's temporaries (about three times the recording's arrays).

The uncertainty and noise-floor steps reconstruct the recording again with noise added
(SIMEX, :func:`~euc_ros.core.euc.uncertainty.eiv_bias`; the residual's noise floor,
:func:`~euc_ros.core.residual.noise.noise_floor`). :class:`PerturbedSeries` is such a re-noised
recording that never exists whole: it hands out the perturbed poses of any block of frames
(:meth:`PerturbedSeries.pose_block`), made on demand from the base recording. Its noise is
:class:`BlockNoise`: the standard normal draws of block ``k`` (:data:`BLOCK_FRAMES` frames, every
body and component at once) come from their own generator, seeded by one number drawn from the
caller's generator and ``k``, so any block is drawn directly (no walk through the stream before it)
and a block read twice, or out of order, gives the same numbers. The last few blocks are kept, so
reading a recording block after block with margins (:func:`block_geometry`) draws every block once.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from euc_ros.core.mocap import MocapSeries

#: Frames per block of :func:`block_geometry` (and of the noise bookmarks).
BLOCK_FRAMES = 4096
#: Outputs of :func:`~euc_ros.core.euc.kinematics.frame_geometry` the states are made of.
GEOMETRY_KEYS = ("psi", "theta", "gamma", "phi_eq3", "phi_hinge", "C", "G", "has_euc", "has_rider", "n_faults")


def pose_block(series, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(position, quat, tracked)`` of frames ``lo:hi`` of every body: views of a
    :class:`~euc_ros.core.mocap.MocapSeries`, or a :class:`PerturbedSeries`' block."""
    block = getattr(series, "pose_block", None)
    if block is not None:
        return block(lo, hi)
    return series.position[:, lo:hi], series.quat[:, lo:hi], series.tracked[:, lo:hi]


def materialize(series) -> MocapSeries:
    """``series`` as a plain :class:`~euc_ros.core.mocap.MocapSeries` (a :class:`PerturbedSeries` made whole)."""
    make = getattr(series, "materialize", None)
    return make() if make is not None else series


def block_geometry(series, session, max_gap: int, *, block: int | None = None) -> tuple[dict, int, int]:
    """Bridged per-frame geometry of a whole recording (segments CoG), evaluated block by block.

    Returns
    -------
    geo : dict of ndarray
        :data:`GEOMETRY_KEYS` over all frames, as ``frame_geometry`` of the bridged recording gives them.
    bridged_samples, bridged_frames : int
        Body-frames bridged, and frames with at least one body bridged (as
        :func:`~euc_ros.core.bridging.bridge_series` reports them for the whole recording).
    """
    from euc_ros.core.bridging import bridge_series
    from euc_ros.core.euc.kinematics import frame_geometry

    block = block or BLOCK_FRAMES
    n = int(series.n_frames)
    margin = max(int(max_gap), 0) + 1
    frame = np.asarray(series.frame)
    out: dict[str, np.ndarray] = {}
    n_samples = n_frames = 0
    for a in range(0, max(n, 1), block):
        b = min(n, a + block)
        lo, hi = max(0, a - margin), min(n, b + margin)
        pos, quat, trk = pose_block(series, lo, hi)
        piece = MocapSeries(t=series.t[lo:hi], frame=frame[lo:hi], bodies=list(series.bodies), position=pos,
                            quat=quat, tracked=trk, mean_marker_error=np.empty((len(series.bodies), 0)))
        bridged_piece, bridged = bridge_series(piece, max_gap)
        core = slice(a - lo, b - lo)
        geo = frame_geometry(bridged_piece.position[:, core], bridged_piece.quat[:, core],
                             bridged_piece.tracked[:, core], session, series.bodies)
        del bridged_piece, pos, quat, trk
        for key in GEOMETRY_KEYS:
            v = np.asarray(geo[key])
            if key not in out:
                out[key] = np.empty((n,) + v.shape[1:], dtype=v.dtype)
            out[key][a:b] = v
        n_samples += int(bridged[:, core].sum())
        n_frames += int(bridged[:, core].any(axis=0).sum())
    return out, n_samples, n_frames


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
    """

    def __init__(self, base, perturb: Callable[[int, int], tuple[np.ndarray, np.ndarray]]) -> None:
        self._base = base
        self._perturb = perturb

    def __getattr__(self, name):
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._base, name)

    def pose_block(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(position, quat, tracked)`` of frames ``lo:hi``, perturbed (new arrays but ``tracked``)."""
        pos, quat = self._perturb(lo, hi)
        return pos, quat, self._base.tracked[:, lo:hi]

    @property
    def position(self) -> np.ndarray:
        return self._perturb(0, self._base.n_frames)[0]

    @property
    def quat(self) -> np.ndarray:
        return self._perturb(0, self._base.n_frames)[1]

    def materialize(self) -> MocapSeries:
        """The whole perturbed recording as a :class:`~euc_ros.core.mocap.MocapSeries`."""
        from dataclasses import replace

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
    returned as float64. The ``cache`` most recent blocks are kept.
    """

    def __init__(self, rng: np.random.Generator, n: int, rows: int, width: int, *, cache: int = 3) -> None:
        self._entropy = int(rng.integers(0, 2**63 - 1))
        self.n, self.rows, self.width = int(n), int(rows), int(width)
        self._cache: dict[int, np.ndarray] = {}
        self._cache_size = int(cache)

    def _block(self, k: int) -> np.ndarray:
        hit = self._cache.get(k)
        if hit is not None:
            return hit
        frames = min(self.n, (k + 1) * BLOCK_FRAMES) - k * BLOCK_FRAMES
        g = np.random.Generator(np.random.PCG64(np.random.SeedSequence(self._entropy, spawn_key=(k,))))
        z = g.standard_normal((self.rows, frames, self.width), dtype=np.float32)
        if len(self._cache) >= self._cache_size:
            self._cache.pop(next(iter(self._cache)))
        self._cache[k] = z
        return z

    def draw(self, lo: int, hi: int) -> np.ndarray:
        """The draws of frames ``lo:hi``: (rows, hi - lo, width) float64."""
        k0, k1 = block_span(lo, hi)
        first = k0 * BLOCK_FRAMES
        if k1 - k0 == 1:
            z = self._block(k0)
        else:
            z = np.concatenate([self._block(k) for k in range(k0, k1)], axis=1)
        return z[:, lo - first:hi - first].astype(float)


def block_span(lo: int, hi: int, block: int | None = None) -> tuple[int, int]:
    """Blocks ``k0 .. k1 - 1`` (of :data:`BLOCK_FRAMES` frames) covering frames ``lo:hi``."""
    block = block or BLOCK_FRAMES
    return lo // block, -(-hi // block)


def block_counts(n: int, block: int | None = None) -> np.ndarray:
    """Frames in each block (of :data:`BLOCK_FRAMES` frames) of a recording of ``n`` frames."""
    block = block or BLOCK_FRAMES
    starts = np.arange(0, n, block)
    return np.minimum(starts + block, n) - starts
