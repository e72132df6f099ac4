"""How well the data determine h: a confidence interval that respects correlation, and identifiability.

Three sources of error, three tools (:func:`interval` combines the first two):

* **Random error, correlated.** The Savitzky-Golay filter correlates neighbouring samples over its
  window, so the formal curvature-based ``h_std_m`` (independent samples) is far too small (a
  25-minute ride gave +-0.4 mm). :func:`~euc_ros.core.identify.bootstrap.block_bootstrap` resamples
  whole blocks of consecutive samples (a moving-block bootstrap with non-overlapping blocks); the
  block length comes from the residual's measured autocorrelation (twice its first zero crossing, at
  least one filter window). Each block's SSE(h) is computed once on a fine grid, so a replicate is a
  weighted sum: 1000 replicates cost one matrix product.
* **Errors in variables.** Pose noise reaches the accelerations the regressors are built from, which
  biases h (low: a noisy CoG looks lower), independently of the recording's length. The bias is
  proportional to the noise variance, so simulation-extrapolation (SIMEX) measures it on the data:
  the noise of every body is estimated from the recording itself (third differences of positions
  and of rotation increments), the same amount is added again, and the change of h is the bias of
  the data as recorded (:func:`~euc_ros.core.identify.simex.eiv_bias`). The interval is widened to
  contain the bias-corrected h.
* **Nominal values no residual can check.** Masses, inertias, l0, h0 and the segment CoM offsets
  enter the model as given; h moves with them while the residual stays at its floor.
  :func:`~euc_ros.core.identify.budget.budget` measures dh/dp for each (re-identifying with the value
  perturbed) and the h range that stated tolerances imply.

h is **not identifiable** (``identifiable: false`` with a reason) when the recording is too short,
the RMSE curve too flat (too little excitation), or the interval reaches the edge of the search
range or is wider than :data:`MAX_CI_WIDTH_M`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from euc_ros.core.filters.derivatives import savgol_derivatives
from euc_ros.core.identify.bootstrap import block_bootstrap

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
        f = json_float
        return {"h_ci95_m": [f(v) for v in self.ci95_m], "identifiable": bool(self.identifiable),
                "identifiability_reason": self.reason or None,
                "uncertainty": {"bootstrap_ci95_m": [f(v) for v in self.bootstrap_ci95_m], "block_s": f(self.block_s),
                                "n_blocks": int(self.n_blocks), "eiv_bias_m": f(self.eiv_bias_m),
                                "sharpness": f(self.sharpness), **self.extra}}


def extend_by_prior(lo: float, hi: float, prior_range_m) -> tuple[float, float]:
    """``(lo, hi)`` moved out by a prior's range of the change of h (``[p_lo <= 0 <= p_hi]``): the truth
    may lie at ``h - p_hi`` to ``h - p_lo``; never narrowed."""
    p_lo, p_hi = (float(v) if v is not None and np.isfinite(v) else 0.0 for v in prior_range_m)
    return lo - max(p_hi, 0.0), hi + max(-p_lo, 0.0)


def json_float(v) -> float | None:
    """``v`` as a JSON number: None for None, NaN and infinities, else a float."""
    return None if v is None or not np.isfinite(v) else float(v)


def percentiles95(replicates: np.ndarray, n_blocks: int) -> tuple[float, float]:
    """The 2.5 and 97.5 % percentiles of bootstrap replicates (unbounded ones, +-inf or NaN, make
    them infinite); infinite with fewer than 2 blocks."""
    if n_blocks < 2:
        return -np.inf, np.inf
    with np.errstate(invalid="ignore"):      # unbounded replicates (+-inf) make the percentile infinite
        lo, hi = np.percentile(replicates, [2.5, 97.5])
    return float(-np.inf if np.isnan(lo) else lo), float(np.inf if np.isnan(hi) else hi)


def student_factor(n_blocks: int) -> float:
    """Widening of a bootstrap interval over ``n_blocks`` blocks: few blocks make the percentiles
    undercover, so they move out as Student's t quantile does against the normal one (1 below 2 blocks)."""
    from scipy.stats import t as student

    return float(student.ppf(0.975, max(n_blocks - 1, 1)) / 1.959964) if n_blocks >= 2 else 1.0


def turning_rms(states) -> float:
    """RMS centripetal acceleration ``x_dot psi_dot`` over the valid samples [m/s^2]."""

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
             eiv_bias_err_m: float = 0.0, filter_floor_m: float = 0.0,
             prior_range_m: tuple[float, float] = (0.0, 0.0)) -> Interval:
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
    eiv_bias_err_m : float
        Its standard error.
    filter_floor_m : float
        Bound on the bias the filter's distortion leaves in h, sign unknown (:func:`~euc_ros.core.
        identify.cog_height.filter_floor`): both ends move out by it, as a systematic shift of at
        most that size moves the whole interval.
    prior_range_m : (float, float)
        Change of h a stated prior allows, ``lo <= 0 <= hi`` (the common soft-tissue sliding,
        :func:`~euc_ros.core.identify.sliding_prior.prior_spread`): the truth may lie at ``h - hi`` to
        ``h - lo``, so the ends move out by ``hi`` (below) and ``-lo`` (above).
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
    lo, hi = percentiles95(hb, nb)
    boot = (float(lo), float(hi))
    k = student_factor(nb)
    lo2, hi2 = h - k * (h - boot[0]), h + k * (boot[1] - h)
    if np.isfinite(eiv_bias_m):
        # the interval contains the estimate and the bias-corrected estimate, each with the bias'
        # own random error (two standard errors)
        e = 2.0 * (eiv_bias_err_m if np.isfinite(eiv_bias_err_m) else 0.0)
        lo2, hi2 = min(lo2, lo2 - eiv_bias_m) - e, max(hi2, hi2 - eiv_bias_m) + e
    if np.isfinite(filter_floor_m) and filter_floor_m > 0:
        lo2, hi2 = lo2 - filter_floor_m, hi2 + filter_floor_m
    lo2, hi2 = extend_by_prior(lo2, hi2, prior_range_m)
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
                    float(fit.sharpness), {"turning_rms_ms2": json_float(turning_ms2)})
