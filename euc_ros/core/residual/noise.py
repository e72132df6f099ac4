"""The residual's noise floor: the pose noise of the recording propagated through the whole chain.

``M_d1 - M_d2`` of a perfect model is not zero: the poses carry noise, the derivative filter turns
it into noisy accelerations, and the two torque expressions weigh them differently. Its size is
measured on the data itself, not assumed:

1. the pose noise of every body is estimated from the recording: the fourth difference of a smooth
   signal sampled at 100+ Hz is negligible, that of white noise has variance ``70 sigma^2``
   (robust: median absolute deviation per component; a unit quaternion's noise has 3 directions,
   perpendicular to it, a position's 3), quaternion signs made continuous first;
2. the recording is reconstructed once more with a second, independent noise of that size added
   (same filter, same session), and the residual of the same model recomputed. The residual
   analysis takes for this the first replicate of the h interval's SIMEX
   (:func:`euc_ros.core.euc.uncertainty.first_replicate`: the noise estimated from third
   differences, rotations per body axis), so the one reconstruction serves both;
3. the RMS of the change is the contribution of one realisation of the recording's own noise: the
   noise floor of the residual.

Limits: noise that is coloured (slow marker sliding) has little fourth-difference energy, so it is
under-estimated here and shows as structure instead; the discovery step and the cross-run test
(:mod:`.discovery`) are what judge that.
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

#: Variance of the fourth difference of unit white noise: 1 + 16 + 36 + 16 + 1.
_D4_VAR = 70.0


def pose_noise(series) -> tuple[np.ndarray, np.ndarray]:
    """Per body, the white pose noise ``(position sigma [m], quaternion-component sigma [-])``."""
    out_p, out_q = [], []
    for b in range(series.position.shape[0]):
        ok = np.all(np.isfinite(series.position[b]), axis=1) & np.all(np.isfinite(series.quat[b]), axis=1)
        if ok.sum() < 20:
            out_p.append(0.0)
            out_q.append(0.0)
            continue
        # consecutive valid frames only: differences across a gap are not noise
        d4p = np.diff(np.where(ok[:, None], series.position[b], np.nan), n=4, axis=0)
        q = _same_hemisphere(series.quat[b])
        d4q = np.diff(np.where(ok[:, None], q, np.nan), n=4, axis=0)
        out_p.append(_mad_sigma(d4p, dof=3))
        out_q.append(_mad_sigma(d4q, dof=3))
    return np.array(out_p), np.array(out_q)


def _same_hemisphere(q: np.ndarray) -> np.ndarray:
    """Quaternions (n, 4) with signs made continuous (q and -q are one rotation): each sample flipped
    when the product of sign changes since the first sample says so."""
    dots = np.sum(q[1:] * q[:-1], axis=1)
    flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0, -1.0, 1.0))])
    return q * flips[:, None]


def _mad_sigma(d4: np.ndarray, dof: int) -> float:
    """Per-component sigma of isotropic noise with ``dof`` free directions, from fourth differences.

    Each component's sigma robustly (MAD); then ``sqrt(sum sigma_k^2 / dof)``: for a unit quaternion
    the noise lives in the 3 directions perpendicular to q (normalising removes the radial one), so
    pooling the 4 components alike would under-estimate it (by ~0.64 on a test track).
    """
    v = d4[np.all(np.isfinite(d4), axis=1)]
    if v.size == 0:
        return 0.0
    sig = 1.4826 * np.median(np.abs(v - np.median(v, axis=0)), axis=0) / np.sqrt(_D4_VAR)
    return float(np.sqrt(np.sum(sig ** 2) / dof))


def renoise(series, rng: np.random.Generator):
    """The recording with a second, independent realisation of its own white pose noise added."""
    return renoised(series, rng).materialize()


def renoised(series, rng: np.random.Generator):
    """:func:`renoise` as a :class:`~euc_ros.core.euc.blockwise.PerturbedSeries`: the same poses (the
    draws of one :class:`~euc_ros.core.euc.blockwise.BlockNoise` seeded by one draw of ``rng``), made
    block by block on demand (every body at once), so the re-noised recording never exists whole."""
    from euc_ros.core.euc.blockwise import BlockNoise, PerturbedSeries

    sp, sq = pose_noise(series)
    b, n = series.position.shape[0], series.position.shape[1]
    noise = BlockNoise(rng, n, b, 7)
    sp_col, sq_col = sp[:, None, None], sq[:, None, None]

    def perturb(lo: int, hi: int):
        z = noise.draw(lo, hi)                                   # (b, m, 7): position, quaternion
        pos = series.position[:, lo:hi] + z[..., :3] * sp_col
        quat = series.quat[:, lo:hi] + z[..., 3:] * sq_col
        quat /= np.linalg.norm(quat, axis=2, keepdims=True)
        return pos, quat

    return PerturbedSeries(series, perturb)


def noise_floor(series_list: Sequence, states: Sequence, session, residual_of, *, seed: int = 0,
                window_s: float | None = None, polyorder: int | None = None, noisy: Sequence | None = None) -> float:
    """RMS [N m] of the residual's change when the recordings' own pose noise is added once more.

    ``residual_of(states_list) -> list of (residual, mask)`` computes the residual of a fixed model
    (e.g. the selected one) on reconstructed states; ``states`` are the states of ``series_list``.
    ``noisy``: the re-noised recordings' states, made by the caller (the residual's floor takes the
    first SIMEX replicate, :func:`euc_ros.core.euc.uncertainty.first_replicate`); without them the
    recordings are re-noised here (:func:`renoised`, ``seed``) and reconstructed.
    """
    from euc_ros.core.euc.kinematics import reconstruct_states

    if noisy is None:
        rng = np.random.default_rng(seed)
        noisy = []
        for series, st in zip(series_list, states):
            kw = {}
            if window_s is not None:
                kw["window_s"] = window_s
            if polyorder is not None:
                kw["polyorder"] = polyorder
            # the same rider CoG method as the states (the skeleton's links re-estimated on the re-noised run)
            noisy.append(reconstruct_states(renoised(series, rng), session, phi_definition=st.phi_definition,
                                            cog_method=getattr(st, "cog_method", "segments"), **kw))
    diffs = []
    for (r0, m0), (r1, m1) in zip(residual_of(states), residual_of(noisy)):
        n = min(len(r0), len(r1))
        m = m0[:n] & m1[:n]
        diffs.append((r1[:n] - r0[:n])[m])
    d = np.concatenate(diffs) if diffs else np.zeros(0)
    return float(np.sqrt(np.mean(d ** 2))) if d.size else float("nan")
