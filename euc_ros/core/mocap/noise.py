"""The pose-noise model of a recording.

The white noise of every body's poses, estimated from the recording itself, and recordings with such noise
added again.

Two estimators, each serving its own consumer:

* :func:`estimate_pose_noise`: third differences of positions and of the rotation increments (per
  body, a position sigma per axis [m] and a rotation sigma per axis [rad]); :func:`pose_noise_series`
  adds noise of that size (a rotation vector applied in the body frame). The h interval's SIMEX
  (:mod:`euc_ros.core.identify.simex`) is built on them.
* :func:`pose_noise`: fourth differences of positions and of quaternion components, quaternion signs
  made continuous first (the fourth difference of a smooth signal sampled at 100+ Hz is negligible,
  that of white noise has variance ``70 sigma^2``; a unit quaternion's noise has 3 directions,
  perpendicular to it, a position's 3); :func:`renoised` adds noise of that size to the components.
  The residual's noise floor without a SIMEX replicate (:func:`euc_ros.core.residual.noise.noise_floor`)
  uses them.

A re-noised recording is a :class:`~euc_ros.core.mocap.blocks.PerturbedSeries`: made block by block on
demand, never whole. Robust throughout: the median absolute deviation.
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.mocap.blocks import BlockNoise, PerturbedSeries
from euc_ros.core.robust import median


def _mad_pooled(v: np.ndarray) -> float:
    """1.4826 x the median absolute deviation of rows (k, m) from their own medians, pooled over the rows."""
    return float(1.4826 * median(np.abs(v - median(v, axis=1, keepdims=True))))


def _increments(quat: np.ndarray, ok: np.ndarray, block: int = 1 << 14) -> np.ndarray:
    """Rotation vectors (3, n - 1) of ``conj(q_k) q_{k+1}`` (body-frame increments), identity where not ``ok``.

    :func:`~euc_ros.core.rotations.quat_multiply` and :func:`~euc_ros.core.rotations.rotvec_from_quat`
    written out on component rows (the same arithmetic), block by block into the output (the
    temporaries are one block's).
    """
    n = quat.shape[0]
    out = np.empty((3, max(n - 1, 0)))
    ident = np.array([0.0, 0.0, 0.0, 1.0])
    for lo in range(0, n - 1, block):
        hi = min(n, lo + block + 1)                  # block + 1 orientations give block increments
        q = np.where(ok[lo:hi, None], quat[lo:hi], ident).T
        q = q / np.sqrt(np.einsum("in,in->n", q, q))
        ax, ay, az, aw = q[:, :-1]
        bx, by, bz, bw = q[:, 1:]
        # conj(a) b = (aw bv - bw av - av x bv, aw bw + av . bv)
        x = aw * bx - bw * ax - (ay * bz - az * by)
        y = aw * by - bw * ay - (az * bx - ax * bz)
        z = aw * bz - bw * az - (ax * by - ay * bx)
        w = aw * bw + (ax * bx + ay * by + az * bz)
        flip = np.where(w < 0, -1.0, 1.0)            # the rotation of angle <= pi
        x, y, z, w = x * flip, y * flip, z * flip, w * flip
        nrm = np.sqrt(x * x + y * y + z * z + w * w)
        x, y, z, w = x / nrm, y / nrm, z / nrm, w / nrm
        s = np.sqrt(x * x + y * y + z * z)
        angle = 2.0 * np.arctan2(s, w)
        k = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0 / np.maximum(w, 1e-300))
        out[0, lo:hi - 1], out[1, lo:hi - 1], out[2, lo:hi - 1] = k * x, k * y, k * z
    return out


def estimate_pose_noise(series) -> tuple[np.ndarray, np.ndarray]:
    """Per-body white pose noise estimated from the recording.

    Returns (position sigma per axis [m], rotation sigma per axis [rad]), each (b,).

    Third differences of a smooth motion sampled at 100+ Hz are tiny; those of white noise have
    variance 20 sigma^2. Rotation: the increments between consecutive orientations (a first
    difference of the noise) differenced twice more. Robust: the median absolute deviation.

    Parameters
    ----------
    series : MocapSeries
        The recording.

    Returns
    -------
    sigma_pos : numpy.ndarray
        Position noise per axis (b,) [m]; NaN with too few consecutive tracked frames.
    sigma_rot : numpy.ndarray
        Rotation noise per axis (b,) [rad]; NaN likewise.
    """
    b = len(series.bodies)
    sp, sr = np.full(b, np.nan), np.full(b, np.nan)
    consecutive = np.diff(series.frame) == 1
    for i in range(b):
        ok = series.tracked[i] & np.all(np.isfinite(series.position[i]), axis=1)
        pair = ok[1:] & ok[:-1] & consecutive
        if pair.sum() < 20:
            continue
        good3 = pair[2:] & pair[1:-1] & pair[:-2]
        if good3.sum() < 10:
            continue
        # components as rows (3, n): the differences and medians run over contiguous memory
        d3 = np.diff(series.position[i].T, n=3, axis=1)[:, good3]
        sp[i] = _mad_pooled(d3) / np.sqrt(20)
        d2 = np.diff(_increments(series.quat[i], ok), n=2, axis=1)[:, good3]
        sr[i] = _mad_pooled(d2) / np.sqrt(20)
    return sp, sr


def add_pose_noise(series, sigma_pos: np.ndarray, sigma_rot: np.ndarray, rng):
    """A copy of ``series`` with white noise of the given per-body sigmas added to every pose.

    Parameters
    ----------
    series : MocapSeries
        The recording.
    sigma_pos : numpy.ndarray
        Position noise per body (b,) [m].
    sigma_rot : numpy.ndarray
        Rotation noise per body and axis (b,) [rad].
    rng : numpy.random.Generator
        Source of the seed.

    Returns
    -------
    MocapSeries
        The noisy copy.
    """
    return pose_noise_series(series, sigma_pos, sigma_rot, rng).materialize()


def pose_noise_series(series, sigma_pos: np.ndarray, sigma_rot: np.ndarray, rng=None, *, noise=None,
                      sign: float = 1.0):
    """:func:`add_pose_noise` as a :class:`~euc_ros.core.mocap.blocks.PerturbedSeries`.

    Per body: position noise ``N(0, sigma_pos)`` on every frame, and a rotation of ``N(0, sigma_rot)``
    per axis (a rotation vector) applied in the body frame to every finite quaternion (a NaN sigma:
    that part untouched). The poses are made block by block on demand (all bodies at once) from the
    draws of a :class:`~euc_ros.core.mocap.blocks.BlockNoise` (seeded by one draw of ``rng``), so the
    noisy recording never exists whole.

    ``noise`` (from :func:`pose_noise_draws`) and ``sign`` give antithetic recordings: the same draws
    with ``sign=-1`` are the mirrored noise (``-z``: the opposite positions and the inverse rotations).

    Parameters
    ----------
    series : MocapSeries
        The recording.
    sigma_pos : numpy.ndarray
        Position noise per body (b,) [m]; NaN: none.
    sigma_rot : numpy.ndarray
        Rotation noise per body and axis (b,) [rad]; NaN: none.
    rng : numpy.random.Generator, optional
        Source of the seed when ``noise`` is None.
    noise : BlockNoise, optional
        The draws to scale.
    sign : float
        Factor of the draws (-1: the antithetic recording).

    Returns
    -------
    PerturbedSeries
        The noisy recording, made on demand.
    """
    if noise is None:
        noise = pose_noise_draws(series, rng)
    sp = np.asarray(sigma_pos, dtype=float)
    sr = np.asarray(sigma_rot, dtype=float)
    has_p, has_r = np.isfinite(sp), np.isfinite(sr)
    pos_scale = float(sign) * np.where(has_p, sp, 0.0)           # per body, the sign of the antithetic draw in
    rot_scale = float(sign) * np.where(has_r, sr, 0.0)

    from euc_ros.core.mocap.noise_compiled import perturb_poses  # numba: on first use only

    position = np.ascontiguousarray(series.position, dtype=float)
    quat = np.ascontiguousarray(series.quat, dtype=float)

    def perturb(lo: int, hi: int):
        z = noise.draw(lo, hi, dtype=None)                       # (b, m, 6): position, rotation (as drawn)
        # the recording's whole arrays and the draws, contiguous: one compiled specialisation, no copies
        return perturb_poses(position, quat, np.ascontiguousarray(z), pos_scale, rot_scale, has_r, lo)

    return PerturbedSeries(series, perturb, noise.forget)


def pose_noise_draws(series, rng):
    """The draws :func:`pose_noise_series` scales (one per body, frame and component, made by block).

    Parameters
    ----------
    series : MocapSeries
        The recording.
    rng : numpy.random.Generator
        Source of the seed.

    Returns
    -------
    BlockNoise
        Draws (b, n, 6).
    """
    return BlockNoise(rng, series.position.shape[1], series.position.shape[0], 6)


#: Variance of the fourth difference of unit white noise: 1 + 16 + 36 + 16 + 1.
_D4_VAR = 70.0


def pose_noise(series) -> tuple[np.ndarray, np.ndarray]:
    """Per body, the white pose noise ``(position sigma [m], quaternion-component sigma [-])``.

    Parameters
    ----------
    series : MocapSeries
        The recording.

    Returns
    -------
    sigma_pos : numpy.ndarray
        Position noise per body (b,) [m]; 0 with fewer than 20 valid frames.
    sigma_quat : numpy.ndarray
        Quaternion-component noise per body (b,) [-]; 0 likewise.
    """
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
    """Quaternions (n, 4) with signs made continuous (q and -q are one rotation).

    Each sample flipped when the product of sign changes since the first sample says so.
    """
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
    """The recording with a second, independent realisation of its own white pose noise added.

    Parameters
    ----------
    series : MocapSeries
        The recording.
    rng : numpy.random.Generator
        Source of the seed.

    Returns
    -------
    MocapSeries
        The re-noised copy.
    """
    return renoised(series, rng).materialize()


def renoised(series, rng: np.random.Generator):
    """:func:`renoise` as a :class:`~euc_ros.core.mocap.blocks.PerturbedSeries`.

    The same poses (the draws of one :class:`~euc_ros.core.mocap.blocks.BlockNoise` seeded by one draw of
    ``rng``), made block by block on demand (every body at once), so the re-noised recording never exists
    whole.

    Parameters
    ----------
    series : MocapSeries
        The recording.
    rng : numpy.random.Generator
        Source of the seed.

    Returns
    -------
    PerturbedSeries
        The re-noised recording, made on demand.
    """
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

    return PerturbedSeries(series, perturb, noise.forget)
