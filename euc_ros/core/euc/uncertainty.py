"""How well the data determine h: a confidence interval that respects correlation, identifiability,
and an uncertainty budget over the session's nominal values.

Three sources of error, three tools:

* **Random error, correlated.** The Savitzky-Golay filter correlates neighbouring samples over its
  window, so the formal curvature-based ``h_std_m`` (independent samples) is far too small (a
  25-minute ride gave +-0.4 mm). :func:`block_bootstrap` resamples whole blocks of consecutive
  samples (a moving-block bootstrap with non-overlapping blocks); the block length comes from the
  residual's measured autocorrelation (twice its first zero crossing, at least one filter window).
  Each block's SSE(h) is computed once on a fine grid, so a replicate is a weighted sum: 1000
  replicates cost one matrix product.
* **Errors in variables.** Pose noise reaches the accelerations the regressors are built from, which
  biases h (low: a noisy CoG looks lower), independently of the recording's length. The bias is
  proportional to the noise variance, so simulation-extrapolation (SIMEX) measures it on the data:
  the noise of every body is estimated from the recording itself (third differences of positions
  and of rotation increments), the same amount is added again, and the change of h is the bias of
  the data as recorded (:func:`eiv_bias`). The interval is widened to contain the bias-corrected h.
* **Nominal values no residual can check.** Masses, inertias, l0, h0 and the segment CoM offsets
  enter the model as given; h moves with them while the residual stays at its floor.
  :func:`budget` measures dh/dp for each (re-identifying with the value perturbed) and the h range
  that stated tolerances imply.

h is **not identifiable** (``identifiable: false`` with a reason) when the recording is too short,
the RMSE curve too flat (too little excitation), or the interval reaches the edge of the search
range or is wider than :data:`MAX_CI_WIDTH_M`.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.rotations import quat_conjugate, quat_from_rotvec, quat_multiply, rotvec_from_quat

#: Shortest total duration of valid samples for an identifiable h [s].
MIN_DURATION_S = 4.0
#: Smallest sharpness (relative RMSE rise at h* +- 0.1 m) for an identifiable h. Measured on the
#: simulator (noise 0.2 mm, 0.5 deg): deceleration and acceleration rides 1.2-1.3, constant speed
#: 0.5-0.7 (their h is biased by 1-2 cm by the filter and errors in variables, beyond any interval).
MIN_SHARPNESS = 0.8
#: Largest RMS centripetal acceleration x_dot psi_dot for the planar model to hold [m/s^2].
MAX_TURNING_MS2 = 0.5
#: Widest 95 % interval still reported as an identification [m].
MAX_CI_WIDTH_M = 0.15
#: Half-width of the fine grid around h* for the bootstrap [m] and its step [m].
LOCAL_HALF_WIDTH_M = 0.3
LOCAL_STEP_M = 5e-4
#: Re-noised reconstructions of every recording in :func:`eiv_bias`: 2 antithetic pairs. Measured on
#: 6 simulated 7 s runs (seed 7), the bias' scatter over 8 seeds: 6 independent replicates 0.99 mm
#: (reported standard error 0.85 mm); 1 pair 0.31 mm, 2 pairs 0.38 mm, 3 pairs 0.38 mm (reported
#: 0.15-0.20 mm); the mean bias -3.60 +- 0.35 mm independent, -3.38 +- 0.13 mm antithetic.
SIMEX_REPLICATES = 4
#: Seed of :func:`eiv_bias` (its first replicate is also the residual's noise floor: :class:`SimexShare`).
SIMEX_SEED = 1

#: Default tolerances of the session's nominal values for the h range (user-overridable).
DEFAULT_TOLERANCES = {
    "rider.mass": 1.0,                 # kg
    "rider.inertia_pitch": "10%",
    "euc.body_mass": 1.0,              # kg
    "euc.body_inertia": "10%",
    "euc.wheel_mass": 0.2,             # kg
    "euc.wheel_inertia": "10%",
    "euc.wheel_radius": 0.002,         # m
    "euc.h0": 0.005,                   # m
    "euc.l0": 0.005,                   # m
    "rider.segments.com_offset": 0.01,  # m, every segment's CoM offset along its body z axis
}


@dataclass
class Interval:
    """The 95 % interval of h and what it is made of.

    Attributes
    ----------
    h_m : float
        The identified h [m].
    ci95_m : tuple of float
        The interval [m] (bootstrap percentiles, widened to contain ``h_m - eiv_bias_m``).
    bootstrap_ci95_m : tuple of float
        The bootstrap percentiles alone [m].
    block_s : float
        Block length [s].
    n_blocks : int
    eiv_bias_m : float
        Errors-in-variables bias of h measured by SIMEX [m] (NaN when not measured).
    identifiable : bool
    reason : str
        Why not ("" when identifiable).
    sharpness : float
        Relative RMSE rise at h* +- 0.1 m.
    """

    h_m: float
    ci95_m: tuple
    bootstrap_ci95_m: tuple
    block_s: float
    n_blocks: int
    eiv_bias_m: float
    identifiable: bool
    reason: str
    sharpness: float
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        f = _f
        return {"h_ci95_m": [f(v) for v in self.ci95_m], "identifiable": bool(self.identifiable),
                "identifiability_reason": self.reason or None,
                "uncertainty": {"bootstrap_ci95_m": [f(v) for v in self.bootstrap_ci95_m], "block_s": f(self.block_s),
                                "n_blocks": int(self.n_blocks), "eiv_bias_m": f(self.eiv_bias_m),
                                "sharpness": f(self.sharpness), **self.extra}}


def _f(v):
    return None if v is None or not np.isfinite(v) else float(v)


def residuals_at(coef: np.ndarray, h: float) -> np.ndarray:
    """Per-sample residual ``e(h) = c (a0 + a1 h + a2 h^2) / (d0 + d1 h)`` [N m]."""
    c, a0, a1, a2, d0, d1 = coef
    return c * (a0 + h * (a1 + h * a2)) / (d0 + d1 * h)


def first_zero_crossing(e: np.ndarray, max_lag: int) -> int:
    """Lag [samples] where the autocorrelation of ``e`` first drops to zero (``max_lag`` if never)."""
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
    """Block length [samples]: twice the residual's first ACF zero crossing, at least one filter window."""
    lags = [first_zero_crossing(residuals_at(c, h), 20 * window) for c in coefs if c.shape[1] > 8]
    k0 = int(np.median(lags)) if lags else window
    return max(int(window), 2 * k0)


def _blocks_of(coefs: Sequence[np.ndarray], length: int) -> list[np.ndarray]:
    """The blocks of ``length`` consecutive samples of each recording (k blocks of ~length, the rest spread)."""
    out = []
    for c in coefs:
        n = c.shape[1]
        if n == 0:
            continue
        k = max(1, n // length)
        edges = np.linspace(0, n, k + 1).astype(int)
        out += [c[:, a:b] for a, b in zip(edges[:-1], edges[1:])]
    return out


def block_sse(coefs: Sequence[np.ndarray], length: int, grid: np.ndarray) -> np.ndarray:
    """SSE(h) of every block of ``length`` consecutive samples of each recording: (n_blocks, g)."""
    from euc_ros.core.euc.identify import _sse_grid

    rows = [_sse_grid(c, grid) for c in _blocks_of(coefs, length)]
    return np.array(rows).reshape(-1, grid.size)


#: The bootstrap's coarse grid takes every this many points of the fine grid (:func:`block_bootstrap`).
COARSE_EVERY = 10


def block_bootstrap(coefs: Sequence[np.ndarray], h: float, window: int, dt: float, *, n_boot: int = 1000,
                    seed: int = 0, h_bounds=(0.1, 1.2)):
    """Moving-block bootstrap of h: ``(h replicates, block length [samples], n_blocks, grid)``.

    Replicates whose optimum sits on the fine grid's edge are returned as +-inf (the data do not
    bound h there).

    The replicates' SSE curves are first found on every :data:`COARSE_EVERY`-th point of the fine grid;
    the fine grid is then evaluated only from one coarse step below the lowest replicate optimum to
    one above the highest. A replicate's fine optimum lies within one coarse step of its coarse one
    whenever its SSE curve has a single minimum on the scale of a coarse step (5 mm), so the
    replicates are those of the whole fine grid, at the cost of the span the replicates cover.
    """
    from euc_ros.core.euc.identify import _sse_grid

    length = block_length(coefs, h, window)
    lo = max(h_bounds[0], h - LOCAL_HALF_WIDTH_M)
    hi = min(h_bounds[1], h + LOCAL_HALF_WIDTH_M)
    grid = np.arange(lo, hi + LOCAL_STEP_M / 2, LOCAL_STEP_M)
    blocks = _blocks_of(coefs, length)
    nb = len(blocks)
    p_blocks = np.full(nb, 1.0 / nb)
    # the replicates' block counts, drawn in chunks of replicates (the same draws as all at once: the
    # generator fills the rows in order) and drawn again for the second pass: 1000 replicates x ~3600
    # blocks of an hour held at once were 58 MB (int64 and its float copy), the residual's memory peak
    chunk = max(1, min(n_boot, (1 << 20) // max(nb, 1)))

    def argmin_of(S: np.ndarray) -> np.ndarray:
        rng = np.random.default_rng(seed)
        out = np.empty(n_boot, dtype=np.int64)
        for a in range(0, n_boot, chunk):
            W = rng.multinomial(nb, p_blocks, size=min(chunk, n_boot - a)).astype(float)
            out[a:a + W.shape[0]] = np.argmin(W @ S, axis=1)
        return out

    coarse = np.arange(0, grid.size, COARSE_EVERY)
    if coarse[-1] != grid.size - 1:
        coarse = np.append(coarse, grid.size - 1)
    Sc = np.array([_sse_grid(c, grid[coarse]) for c in blocks]).reshape(-1, coarse.size)
    kc = argmin_of(Sc)
    f0 = int(coarse[max(int(kc.min()) - 1, 0)]) if kc.size else 0
    f1 = int(coarse[min(int(kc.max()) + 1, coarse.size - 1)]) if kc.size else grid.size - 1
    S = np.array([_sse_grid(c, grid[f0:f1 + 1]) for c in blocks]).reshape(-1, f1 + 1 - f0)
    k = f0 + argmin_of(S)
    hb = grid[k].astype(float)
    hb[k == 0] = -np.inf
    hb[k == grid.size - 1] = np.inf
    return hb, length, nb, grid


def _mad_pooled(v: np.ndarray) -> float:
    """1.4826 x the median absolute deviation of rows (k, m) from their own medians, pooled over the rows."""
    return float(1.4826 * np.median(np.abs(v - np.median(v, axis=1, keepdims=True))))


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
    """Per-body white pose noise estimated from the recording: (position sigma per axis [m],
    rotation sigma per axis [rad]), each (b,).

    Third differences of a smooth motion sampled at 100+ Hz are tiny; those of white noise have
    variance 20 sigma^2. Rotation: the increments between consecutive orientations (a first
    difference of the noise) differenced twice more. Robust: the median absolute deviation.
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
    """A copy of ``series`` with white noise of the given per-body sigmas added to every pose."""
    return pose_noise_series(series, sigma_pos, sigma_rot, rng).materialize()


def pose_noise_series(series, sigma_pos: np.ndarray, sigma_rot: np.ndarray, rng=None, *, noise=None,
                      sign: float = 1.0):
    """:func:`add_pose_noise` as a :class:`~euc_ros.core.euc.blockwise.PerturbedSeries`.

    Per body: position noise ``N(0, sigma_pos)`` on every frame, and a rotation of ``N(0, sigma_rot)``
    per axis (a rotation vector) applied in the body frame to every finite quaternion (a NaN sigma:
    that part untouched). The poses are made block by block on demand (all bodies at once) from the
    draws of a :class:`~euc_ros.core.euc.blockwise.BlockNoise` (seeded by one draw of ``rng``), so the
    noisy recording never exists whole.

    ``noise`` (from :func:`pose_noise_draws`) and ``sign`` give antithetic recordings: the same draws
    with ``sign=-1`` are the mirrored noise (``-z``: the opposite positions and the inverse rotations).
    """
    from euc_ros.core.euc.blockwise import PerturbedSeries

    if noise is None:
        noise = pose_noise_draws(series, rng)
    sp = np.asarray(sigma_pos, dtype=float)
    sr = np.asarray(sigma_rot, dtype=float)
    has_p, has_r = np.isfinite(sp), np.isfinite(sr)
    sp_col = (float(sign) * np.where(has_p, sp, 0.0))[:, None, None]
    sr_col = (float(sign) * np.where(has_r, sr, 0.0))[:, None, None]

    def perturb(lo: int, hi: int):
        z = noise.draw(lo, hi)                                   # (b, m, 6): position, rotation
        pos = series.position[:, lo:hi] + sp_col * z[..., :3]
        q = np.asarray(series.quat[:, lo:hi], dtype=float)
        return pos, _rotate_by_rotvec(q, sr_col * z[..., 3:], has_r)

    return PerturbedSeries(series, perturb)


def _rotate_by_rotvec(q: np.ndarray, r: np.ndarray, apply: np.ndarray) -> np.ndarray:
    """``q dq`` (b, m, 4) with ``dq`` the unit quaternion of the rotation vectors ``r`` (b, m, 3), ``q``
    normalised first, for the bodies in ``apply`` (b,) and the finite quaternions; the others as given.

    :func:`~euc_ros.core.rotations.quat_from_rotvec` and :func:`~euc_ros.core.rotations.quat_multiply`
    written out per component (the same arithmetic without the intermediate (b, m, 4) stacks).
    """
    rx, ry, rz = r[..., 0], r[..., 1], r[..., 2]
    angle = np.sqrt(rx * rx + ry * ry + rz * rz)
    half = 0.5 * angle
    small = angle <= 1e-6
    k = np.where(small, 0.5 - angle * angle / 48.0, np.sin(half) / np.where(small, 1.0, angle))
    bx, by, bz, bw = k * rx, k * ry, k * rz, np.cos(half)
    norm = np.sqrt(np.einsum("...i,...i->...", q, q))
    x, y, zq, w = (q[..., i] / norm for i in range(4))
    out = np.empty_like(q)
    out[..., 0] = w * bx + bw * x + (y * bz - zq * by)
    out[..., 1] = w * by + bw * y + (zq * bx - x * bz)
    out[..., 2] = w * bz + bw * zq + (x * by - y * bx)
    out[..., 3] = w * bw - (x * bx + y * by + zq * bz)
    keep = ~(np.all(np.isfinite(q), axis=-1) & apply[:, None])
    if keep.any():
        out[keep] = q[keep]
    return out


def pose_noise_draws(series, rng):
    """The draws :func:`pose_noise_series` scales (one per body, frame and component, made by block)."""
    from euc_ros.core.euc.blockwise import BlockNoise

    return BlockNoise(rng, series.position.shape[1], series.position.shape[0], 6)


class SimexShare:
    """The first replicate of :func:`eiv_bias` (pair 1, ``+z``), made once for two uses.

    The residual's noise floor (:func:`euc_ros.core.residual.analysis.make_noise_floor`) is one
    re-noised reconstruction of the recordings, which is what a SIMEX replicate is. Made by
    :func:`first_replicate`, its h is kept here (with the noise estimate and what it was made with),
    and :func:`eiv_bias` given the same object and the same settings takes that h instead of
    reconstructing the recordings once more. Only floats are kept, not the states.
    """

    def __init__(self) -> None:
        self.series: list | None = None
        self.noise: list | None = None
        self.key: tuple | None = None
        self.h_m: float | None = None

    def noise_of(self, series_list) -> list:
        """Per recording, :func:`estimate_pose_noise` (computed once per set of recordings)."""
        if self.series is None or len(self.series) != len(series_list) or \
                any(a is not b for a, b in zip(self.series, series_list)):
            self.series, self.noise, self.key, self.h_m = list(series_list), None, None, None
        if self.noise is None:
            self.noise = [estimate_pose_noise(s) for s in series_list]
        return self.noise

    def lookup(self, series_list, key: tuple) -> float | None:
        if self.h_m is None or self.key != key or self.series is None or len(self.series) != len(series_list) \
                or any(a is not b for a, b in zip(self.series, series_list)):
            return None
        return self.h_m


def _share_key(series_list, window_s, polyorder, phi_definition, cog_method, seed, params) -> tuple:
    """What a replicate's h depends on besides the recordings (the window in samples: ``window_s`` of
    1.2 s and of 145 / 120 s are one filter)."""
    from euc_ros.core.filters.derivatives import window_samples

    windows = tuple(window_samples(1.0 / s.rate_hz, window_s=window_s, polyorder=polyorder) for s in series_list)
    return windows, int(polyorder), phi_definition, cog_method, int(seed), params


def _replicate_states(series_list, noise, draws, sign, session, *, window_s, polyorder, phi_definition, cog_method):
    from euc_ros.core.euc.kinematics import reconstruct_states

    # the noisy recordings are made block by block as the states are reconstructed (never whole)
    return [reconstruct_states(pose_noise_series(s, sp, sr, noise=z, sign=sign), session,
                               phi_definition=phi_definition, window_s=window_s, polyorder=polyorder,
                               cog_method=cog_method)
            for s, (sp, sr), z in zip(series_list, noise, draws)]


def first_replicate(series_list, session, params, *, window_s: float, polyorder: int, phi_definition: str = "hinge",
                    cog_method: str = "segments", seed: int = SIMEX_SEED, share: SimexShare | None = None,
                    use=None):
    """The states of :func:`eiv_bias`'s first replicate (the recordings with their estimated white pose
    noise added once more: pair 1, ``+z``), or None when the noise cannot be estimated. With ``share``
    its h is kept for :func:`eiv_bias`.

    ``use(states)``: what the caller does with the states (e.g. the residual's noise floor); then
    ``use``'s result is returned instead of the states, and the h is fitted after it with the states
    dropped (reduced to their residual coefficients first: :func:`~euc_ros.core.euc.identify.pooled_h_of_states`),
    so the states and the fit's working set are never held together. ``use`` is not called (None is
    returned) when the noise cannot be estimated."""
    from euc_ros.core.euc.identify import pooled_h_of_states

    share = share if share is not None else SimexShare()
    noise = share.noise_of(series_list)
    if all(not np.isfinite(sp).any() for sp, _ in noise):
        return None
    rng = np.random.default_rng(seed)
    draws = [pose_noise_draws(s, rng) for s in series_list]
    states = _replicate_states(series_list, noise, draws, 1.0, session, window_s=window_s, polyorder=polyorder,
                               phi_definition=phi_definition, cog_method=cog_method)
    share.key = _share_key(series_list, window_s, polyorder, phi_definition, cog_method, seed, params)
    if use is None:
        share.h_m = pooled_h_of_states(list(states), params)      # a copy of the list: the states are returned
        return states
    out = use(states)
    share.h_m = pooled_h_of_states(states, params)
    return out


def eiv_bias(series_list, session, params, h: float, *, window_s: float, polyorder: int,
             phi_definition: str = "hinge", replicates: int = SIMEX_REPLICATES, seed: int = SIMEX_SEED,
             with_error: bool = False, cog_method: str = "segments", antithetic: bool = True,
             share: SimexShare | None = None):
    """Errors-in-variables bias of h by SIMEX [m]: ``mean(h with the noise doubled) - h``.

    The noise of the recordings as given is estimated (:func:`estimate_pose_noise`); adding the same
    again doubles its variance, and the bias is linear in the variance, so the change of h equals
    the bias already in ``h``. NaN when the noise cannot be estimated. Each replicate draws its own
    noise, so the estimate carries a random error: with ``with_error`` the return value is
    ``(bias, standard error)``.

    ``antithetic`` (default): the replicates come in pairs with mirrored noise ``+z`` and ``-z``
    (``replicates`` reconstructions, ``replicates // 2`` pairs). h responds to the added noise to first
    order linearly (a random shift of zero mean, the replicates' main scatter) and to second order
    quadratically (the bias); the pair's mean cancels the linear part exactly, so it carries only
    the quadratic part's own scatter. The standard error is that of the pair means (independent).
    ``share``: a :class:`SimexShare` whose first replicate (made by :func:`first_replicate` with the
    same settings) is used instead of being made again.
    """
    from euc_ros.core.euc.identify import pooled_h_of_states

    share = share if share is not None else SimexShare()
    noise = share.noise_of(series_list)
    if all(not np.isfinite(sp).any() for sp, _ in noise):
        return (float("nan"), float("nan")) if with_error else float("nan")
    rng = np.random.default_rng(seed)
    known = share.lookup(series_list, _share_key(series_list, window_s, polyorder, phi_definition, cog_method, seed,
                                                 params))

    def h_of(draws, sign):
        states = _replicate_states(series_list, noise, draws, sign, session, window_s=window_s, polyorder=polyorder,
                                   phi_definition=phi_definition, cog_method=cog_method)
        # identify_h's pooled 3-DoF h, the states dropped once reduced to their coefficients
        return pooled_h_of_states(states, params)

    hs = []
    pairs = antithetic and replicates >= 2
    for k in range(replicates // 2 if pairs else replicates):
        draws = [pose_noise_draws(s, rng) for s in series_list]
        first = known if (k == 0 and known is not None) else h_of(draws, 1.0)
        hs.append(0.5 * (first + h_of(draws, -1.0)) if pairs else first)
    bias = float(np.nanmean(hs) - h)
    err = float(np.nanstd(hs, ddof=1) / np.sqrt(len(hs))) if len(hs) > 1 else float("nan")
    return (bias, err) if with_error else bias


def turning_rms(states) -> float:
    """RMS centripetal acceleration ``x_dot psi_dot`` over the valid samples [m/s^2]."""
    from euc_ros.core.filters.derivatives import savgol_derivatives

    vals = []
    for st in states:
        psi = np.asarray(st.psi, dtype=float)
        ok = np.asarray(st.valid, bool) & np.isfinite(psi)
        if ok.sum() < st.window:
            continue
        psi_dot = savgol_derivatives(st.t, psi, window=st.window, polyorder=3, frame=st.frame).y_dot
        ok &= np.isfinite(psi_dot)
        vals.append((st.x_dot * psi_dot)[ok])
    v = np.concatenate(vals) if vals else np.array([])
    return float(np.sqrt(np.mean(v ** 2))) if v.size else 0.0


def interval(coefs: Sequence[np.ndarray], fit, *, window: int, dt: float, eiv_bias_m: float = float("nan"),
             h_bounds=(0.1, 1.2), n_boot: int = 1000, seed: int = 0, turning_ms2: float = 0.0,
             eiv_bias_err_m: float = 0.0) -> Interval:
    """The 95 % interval of ``fit.h_m`` and its identifiability (see the module docstring).

    Parameters
    ----------
    coefs : sequence of ndarray (6, n_i)
        Per recording, the residual coefficients of its valid samples in time order.
    fit : ModelFit
        The pooled fit (``h_m``, ``sharpness``).
    window : int
        Savitzky-Golay window [samples] (the shortest block).
    dt : float
        Sample period [s].
    eiv_bias_m : float
        SIMEX bias (NaN: not included).
    """
    h = float(fit.h_m)
    n = sum(c.shape[1] for c in coefs)
    duration = n * dt
    reasons = []
    if not np.isfinite(h):
        return Interval(h, (np.nan, np.nan), (np.nan, np.nan), np.nan, 0, eiv_bias_m, False, "no valid sample",
                        float("nan"))
    if duration < MIN_DURATION_S:
        reasons.append(f"too short: {duration:.1f} s of usable states (at least {MIN_DURATION_S:g} s needed)")
    hb, length, nb, grid = block_bootstrap(coefs, h, window, dt, n_boot=n_boot, seed=seed, h_bounds=h_bounds)
    if nb >= 2:
        with np.errstate(invalid="ignore"):      # unbounded replicates (+-inf) make the percentile infinite
            lo, hi = np.percentile(hb, [2.5, 97.5])
        lo, hi = (-np.inf if np.isnan(lo) else lo), (np.inf if np.isnan(hi) else hi)
    else:
        lo, hi = -np.inf, np.inf
    boot = (float(lo), float(hi))
    # few blocks: percentiles undercover; widen as Student's t does against the normal quantile
    from scipy.stats import t as student

    k = float(student.ppf(0.975, max(nb - 1, 1)) / 1.959964) if nb >= 2 else 1.0
    lo2, hi2 = h - k * (h - boot[0]), h + k * (boot[1] - h)
    if np.isfinite(eiv_bias_m):
        # the interval contains the estimate and the bias-corrected estimate, each with the bias'
        # own random error (two standard errors)
        e = 2.0 * (eiv_bias_err_m if np.isfinite(eiv_bias_err_m) else 0.0)
        lo2, hi2 = min(lo2, lo2 - eiv_bias_m) - e, max(hi2, hi2 - eiv_bias_m) + e
    if turning_ms2 > MAX_TURNING_MS2:
        reasons.append(f"the ride turns (RMS centripetal acceleration {turning_ms2:.1f} m/s^2 > {MAX_TURNING_MS2:g}): "
                       "the planar model lacks the turning terms; see `euc-ros residual`")
    if nb < 4:
        reasons.append(f"too few independent blocks ({nb} of {length * dt:.1f} s)")
    if fit.sharpness < MIN_SHARPNESS:
        reasons.append(f"too little excitation: the RMSE curve rises only {100 * fit.sharpness:.0f} % at h +- 0.1 m "
                       f"(at least {100 * MIN_SHARPNESS:.0f} % needed; ride with speed changes)")
    if not (np.isfinite(lo2) and np.isfinite(hi2)):
        reasons.append("the data do not bound h: bootstrap optima reach the edge of the search range")
    elif hi2 - lo2 > MAX_CI_WIDTH_M:
        reasons.append(f"the 95 % interval is {100 * (hi2 - lo2):.0f} cm wide")
    return Interval(h, (lo2, hi2), boot, length * dt, nb, eiv_bias_m, not reasons, "; ".join(reasons),
                    float(fit.sharpness), {"turning_rms_ms2": _f(turning_ms2)})


# --------------------------------------------------------------------------------------------------------------------
# Budget over the nominal values
# --------------------------------------------------------------------------------------------------------------------

#: Budget keys -> (EucParams field, session path) for the values that enter the model only.
_PARAM_KEYS = {
    "rider.mass": "m", "rider.inertia_pitch": "J", "euc.body_mass": "m0", "euc.body_inertia": "J0",
    "euc.wheel_mass": "mw", "euc.wheel_inertia": "Jw", "euc.wheel_radius": "R", "euc.h0": "h0", "euc.l0": "l0",
}


def parse_tolerances(items: Sequence[str] | None) -> dict:
    """``["rider.mass=2", "euc.body_inertia=20%"]`` over :data:`DEFAULT_TOLERANCES`; ConfigError naming the key."""
    tol = dict(DEFAULT_TOLERANCES)
    for item in items or ():
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in DEFAULT_TOLERANCES:
            raise ConfigError(f"expected KEY=VALUE with KEY one of {', '.join(DEFAULT_TOLERANCES)}, got {item!r}",
                              key="--tolerance")
        v = value.strip()
        try:
            num = float(v[:-1]) if v.endswith("%") else float(v)
        except ValueError:
            raise ConfigError(f"{key}: {v!r} is not a number (give e.g. {key}=0.01 or {key}=5%)",
                              key="--tolerance") from None
        if not num >= 0:
            raise ConfigError(f"{key}: a tolerance must be >= 0, got {v}", key="--tolerance")
        tol[key] = f"{num:g}%" if v.endswith("%") else num
    return tol


def _nominal(session, key: str) -> float:
    if key.startswith("rider.") and key != "rider.segments.com_offset":
        return float(getattr(session.rider, key.split(".", 1)[1]))
    if key.startswith("euc."):
        return float(getattr(session.euc, key.split(".", 1)[1]))
    return float("nan")


def _absolute(tol, nominal: float) -> float:
    return abs(nominal) * float(tol[:-1]) / 100.0 if isinstance(tol, str) else float(tol)


def budget(series_list, states, session, params, h: float, *, window_s: float, polyorder: int,
           phi_definition: str = "hinge", tolerances: dict | None = None, cog_method: str = "segments") -> dict:
    """dh/dp for every nominal value and the h range for the tolerances.

    Model-only values are perturbed in :class:`EucParams` on the reconstructed states; the segment CoM
    offsets enter the geometry, so the recordings are reconstructed again with every offset moved
    along its body's z axis.

    Returns
    -------
    dict
        ``{"sensitivity": {key: {"dh_dp": [m per unit], "unit", "tolerance", "dh_m"}}, "h_range_m": [lo, hi]}``
    """
    from euc_ros.core.euc.identify import identify_h
    from euc_ros.core.euc.kinematics import reconstruct_states

    tolerances = tolerances or dict(DEFAULT_TOLERANCES)

    def h_of(st, p):
        return identify_h(st, p, models=("3dof",)).pooled["3dof"].h_m

    out = {}
    total = 0.0
    for key, fld in _PARAM_KEYS.items():
        nominal = float(getattr(params, fld))
        step = max(abs(nominal) * 0.02, 1e-4)
        hp = h_of(states, dataclasses.replace(params, **{fld: nominal + step}))
        hm = h_of(states, dataclasses.replace(params, **{fld: nominal - step}))
        d = (hp - hm) / (2 * step)
        tol = _absolute(tolerances[key], nominal)
        unit = {"m": "kg", "m0": "kg", "mw": "kg", "J": "kg m^2", "J0": "kg m^2", "Jw": "kg m^2"}.get(fld, "m")
        out[key] = {"dh_dp": _f(d), "unit": f"m per {unit}", "nominal": nominal, "tolerance": tol,
                    "dh_m": _f(abs(d) * tol)}
        total += abs(d) * tol if np.isfinite(d) else 0.0
    step = 0.01
    segs = session.rider.segments

    def shifted(dz):
        new = {name: dataclasses.replace(seg, com_offset=tuple(np.add(seg.com_offset, (0.0, 0.0, dz))))
               for name, seg in segs.items()}
        return dataclasses.replace(session, rider=dataclasses.replace(session.rider, segments=new))

    hs = []
    for dz in (step, -step):
        s2 = shifted(dz)
        st2 = [reconstruct_states(s, s2, phi_definition=phi_definition, window_s=window_s, polyorder=polyorder,
                                  cog_method=cog_method) for s in series_list]
        hs.append(h_of(st2, params))
        del st2                       # before the other shift's states are made
    d = (hs[0] - hs[1]) / (2 * step)
    tol = _absolute(tolerances["rider.segments.com_offset"], 0.0)
    out["rider.segments.com_offset"] = {"dh_dp": _f(d), "unit": "m per m (all offsets along the body z axis)",
                                        "nominal": None, "tolerance": tol, "dh_m": _f(abs(d) * tol)}
    total += abs(d) * tol if np.isfinite(d) else 0.0
    return {"sensitivity": out, "h_range_m": [_f(h - total), _f(h + total)], "tolerances": {
        k: v for k, v in tolerances.items()}}
