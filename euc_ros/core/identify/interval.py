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
holds fewer than :data:`MIN_BLOCKS` independent blocks, turns, has an RMSE curve too flat (too
little excitation), or the interval reaches the edge of the search range or is wider than
:data:`MAX_CI_WIDTH_M`. Every reason says what the ride had and what it needs, in the lab's terms
(:mod:`~euc_ros.core.identify.excitation`): usable seconds and blocks against those needed, with the
seconds to add to one take or the runs like these to add; for the sharpness, the ride's speed
changes, accelerations and rider pitch range, and how many times its speed changes the criterion
needs (derived from the residual's sensitivity to h, not guessed). The same numbers are in the
JSON's ``uncertainty.excitation`` whether h is identifiable or not (:func:`excitation_json`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from euc_ros.core.filters.derivatives import savgol_derivatives
from euc_ros.core.identify.bootstrap import block_bootstrap, block_counts
from euc_ros.core.identify.excitation import (
    Excitation,
    Needs,
    measure_excitation,
    more_data_for_blocks,
    more_data_for_seconds,
)

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
#: Fewest bootstrap blocks for an identifiable h (fewer give no meaningful percentiles).
MIN_BLOCKS = 4
#: RMS longitudinal acceleration beyond any ride [m/s^2]: holding it, the rider leans atan(a / g) = 17 deg
#: forward or back the whole time (EUC rides reach peaks of 1-2 m/s^2). Advice that needs more is not
#: advice about excitation: such a residual is an effect the model lacks.
MAX_RIDE_ACCEL_RMS_MPS2 = 3.0


@dataclass
class Interval:
    """The 95 % interval of h and what it is made of.

    Parameters
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
    extra : dict
        More keys of the JSON's ``uncertainty`` (``turning_rms_ms2``, ``excitation``).
    data_reasons : tuple of str
        The reasons that concern the data alone (duration, turning, blocks, sharpness), which hold for
        every estimate of h from them; ``reason`` adds the one about the interval (unbounded, too wide).
    random_width_m : float
        The width of the interval's random part [m] (the bootstrap's, widened for few blocks).
    usable_s : tuple of float
        Usable seconds per recording (what more recording a too-wide interval needs).
    duration_s : float
        Seconds of valid samples, all recordings together.
    more_for_data : tuple of (float, int)
        Seconds to add to one take and runs to add for the duration and block criteria (0 when they hold).
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
    data_reasons: tuple = ()
    random_width_m: float = float("nan")
    usable_s: tuple = ()
    duration_s: float = float("nan")
    more_for_data: tuple = (0.0, 0)

    def for_estimate(self, h_m: float, ci95_m, bootstrap_ci95_m, random_width_m: float) -> "Interval":
        """The verdict on another estimate of h from the same data, blocks and curve, with its own interval.

        Parameters
        ----------
        h_m : float
            The estimate [m] (e.g. h corrected for the pose noise and the filter's distortion).
        ci95_m : (float, float)
            Its 95 % interval [m] (non-finite ends: not bounded by the data).
        bootstrap_ci95_m : (float, float)
            Its bootstrap percentiles alone [m].
        random_width_m : float
            The width of its interval's random part [m].

        Returns
        -------
        Interval
            This interval's blocks, sharpness and data reasons, with ``h_m`` and the intervals given;
            ``identifiable`` and ``reason`` judge the given interval (bounded, at most
            :data:`MAX_CI_WIDTH_M` wide), and ``extra["excitation"]``'s ``record_more_s`` and
            ``more_runs_needed`` are those it needs.
        """
        lo, hi = (float(v) for v in ci95_m)
        text, width_s, width_runs = _interval_reason(lo, hi, float(random_width_m), self.usable_s, self.n_blocks,
                                                     self.block_s, self.duration_s, self.sharpness)
        reasons = list(self.data_reasons) + ([text] if text else [])
        extra = dict(self.extra)
        if isinstance(extra.get("excitation"), dict):
            extra["excitation"] = dict(extra["excitation"],
                                       record_more_s=json_float(max(self.more_for_data[0], width_s)),
                                       more_runs_needed=int(max(self.more_for_data[1], width_runs)))
        boot = tuple(float(v) for v in bootstrap_ci95_m)
        return replace(self, h_m=float(h_m), ci95_m=(lo, hi), bootstrap_ci95_m=boot, identifiable=not reasons,
                       reason="; ".join(reasons), extra=extra, random_width_m=float(random_width_m))

    def to_json(self) -> dict:
        """Plain-JSON form: ``h_ci95_m``, ``identifiable``, ``identifiability_reason`` and ``uncertainty``.

        Returns
        -------
        dict
            ``uncertainty`` holds the bootstrap interval, the block length, the number of blocks, the
            errors-in-variables bias, the sharpness and the keys of ``extra``; non-finite numbers are None
            (:func:`json_float`).
        """
        f = json_float
        return {"h_ci95_m": [f(v) for v in self.ci95_m], "identifiable": bool(self.identifiable),
                "identifiability_reason": self.reason or None,
                "uncertainty": {"bootstrap_ci95_m": [f(v) for v in self.bootstrap_ci95_m], "block_s": f(self.block_s),
                                "n_blocks": int(self.n_blocks), "eiv_bias_m": f(self.eiv_bias_m),
                                "sharpness": f(self.sharpness), **self.extra}}


def extend_by_prior(lo: float, hi: float, prior_range_m) -> tuple[float, float]:
    """``(lo, hi)`` moved out by a prior's range of the change of h (``[p_lo <= 0 <= p_hi]``); never narrowed.

    The truth may lie at ``h - p_hi`` to ``h - p_lo``.

    Parameters
    ----------
    lo, hi : float
        The interval's ends [m].
    prior_range_m : pair of float or None
        ``(p_lo, p_hi)`` [m]; a None or non-finite end counts 0.

    Returns
    -------
    (float, float)
        ``(lo - max(p_hi, 0), hi + max(-p_lo, 0))`` [m].
    """
    p_lo, p_hi = (float(v) if v is not None and np.isfinite(v) else 0.0 for v in prior_range_m)
    return lo - max(p_hi, 0.0), hi + max(-p_lo, 0.0)


def json_float(v) -> float | None:
    """A number as a JSON number: None for None, NaN and infinities, else a float.

    Parameters
    ----------
    v : float or None
        The number.

    Returns
    -------
    float or None
    """
    return None if v is None or not np.isfinite(v) else float(v)


def percentiles95(replicates: np.ndarray, n_blocks: int) -> tuple[float, float]:
    """The 2.5 and 97.5 % percentiles of bootstrap replicates; infinite with fewer than 2 blocks.

    Unbounded replicates (+-inf or NaN) make them infinite.

    Parameters
    ----------
    replicates : ndarray (n_boot,)
        Bootstrap replicates of h [m].
    n_blocks : int
        Number of blocks they were drawn from.

    Returns
    -------
    (float, float)
        The low and high percentile [m].
    """
    if n_blocks < 2:
        return -np.inf, np.inf
    with np.errstate(invalid="ignore"):      # unbounded replicates (+-inf) make the percentile infinite
        lo, hi = np.percentile(replicates, [2.5, 97.5])
    return float(-np.inf if np.isnan(lo) else lo), float(np.inf if np.isnan(hi) else hi)


def student_factor(n_blocks: int) -> float:
    """Widening of a bootstrap interval over ``n_blocks`` blocks (1 below 2 blocks).

    Few blocks make the percentiles undercover, so they move out as Student's t quantile does against the normal one.

    Parameters
    ----------
    n_blocks : int
        Number of bootstrap blocks.

    Returns
    -------
    float
        ``t_0.975(n_blocks - 1) / z_0.975`` (at least 1).
    """
    from scipy.stats import t as student

    return float(student.ppf(0.975, max(n_blocks - 1, 1)) / 1.959964) if n_blocks >= 2 else 1.0


def turning_rms(states) -> float:
    """RMS centripetal acceleration ``x_dot psi_dot`` over the valid samples [m/s^2].

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states (a recording with fewer valid samples than its filter window is left out);
        ``psi_dot`` is the Savitzky-Golay derivative of the yaw with the states' window.

    Returns
    -------
    float
        The RMS [m/s^2]; 0 without a sample.
    """
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


@dataclass(frozen=True)
class Systematics:
    """The systematic terms the interval holds beside the bootstrap's random part.

    Parameters
    ----------
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

    eiv_bias_m: float = float("nan")
    eiv_bias_err_m: float = 0.0
    filter_floor_m: float = 0.0
    prior_range_m: tuple[float, float] = (0.0, 0.0)


#: No systematic term.
NO_SYSTEMATICS = Systematics()


def interval(coefs: Sequence[np.ndarray], fit, *, window: int, dt: float,
             systematics: Systematics = NO_SYSTEMATICS, h_bounds=(0.1, 1.2), n_boot: int = 1000, seed: int = 0,
             turning_ms2: float = 0.0, states=None) -> Interval:
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
    systematics : Systematics
        The SIMEX bias with its error, the filter's floor and the prior's range.
    h_bounds : tuple of float
        Search range of h [m] (:func:`~euc_ros.core.identify.bootstrap.block_bootstrap`).
    n_boot : int
        Number of bootstrap replicates.
    seed : int
        Seed of the bootstrap's block draws.
    turning_ms2 : float
        RMS centripetal acceleration of the ride [m/s^2] (:func:`turning_rms`; above
        :data:`MAX_TURNING_MS2` h is not identifiable).
    states : sequence of RiderStates, optional
        The recordings' states, in the order of ``coefs``: the reasons then give the ride's speed
        changes, accelerations and rider pitch range against what h needs
        (:mod:`~euc_ros.core.identify.excitation`); without them, the residual's sensitivity to h.

    Returns
    -------
    Interval
        Its ``extra["excitation"]`` (the JSON's ``uncertainty.excitation``) holds what the ride had and
        what it needs, whether or not h is identifiable (:func:`excitation_json`).
    """
    eiv_bias_m, eiv_bias_err_m = systematics.eiv_bias_m, systematics.eiv_bias_err_m
    filter_floor_m, prior_range_m = systematics.filter_floor_m, systematics.prior_range_m
    h = float(fit.h_m)
    n_rec = [int(c.shape[1]) for c in coefs]
    n = sum(n_rec)
    duration = n * dt
    reasons = []
    if not np.isfinite(h):
        return Interval(h, (np.nan, np.nan), (np.nan, np.nan), np.nan, 0, eiv_bias_m, False, "no valid sample",
                        float("nan"), data_reasons=("no valid sample",))
    exc = measure_excitation(coefs, h, float(fit.rmse_nm), states)
    usable = exc.usable_s if exc.usable_s else tuple(k * dt for k in n_rec)
    more_s, more_runs = more_data_for_seconds(usable, MIN_DURATION_S)
    if duration < MIN_DURATION_S:
        reasons.append(f"too short: {duration:.1f} s of usable states (at least {MIN_DURATION_S:g} s needed): "
                       f"record at least {_up(more_s)} s more, or {_runs(more_runs)}")
    hb, length, nb, grid = block_bootstrap(coefs, h, window, dt, n_boot=n_boot, seed=seed, h_bounds=h_bounds)
    lo, hi = percentiles95(hb, nb)
    boot = (float(lo), float(hi))
    k = student_factor(nb)
    lo2, hi2 = h - k * (h - boot[0]), h + k * (boot[1] - h)
    random_width = hi2 - lo2
    if np.isfinite(eiv_bias_m):
        # the interval contains the estimate and the bias-corrected estimate, each with the bias'
        # own random error (two standard errors)
        e = 2.0 * (eiv_bias_err_m if np.isfinite(eiv_bias_err_m) else 0.0)
        lo2, hi2 = min(lo2, lo2 - eiv_bias_m) - e, max(hi2, hi2 - eiv_bias_m) + e
    if np.isfinite(filter_floor_m) and filter_floor_m > 0:
        lo2, hi2 = lo2 - filter_floor_m, hi2 + filter_floor_m
    lo2, hi2 = extend_by_prior(lo2, hi2, prior_range_m)
    if turning_ms2 > MAX_TURNING_MS2:
        v = exc.speed_rms_mps
        radius = (f": at the ride's RMS speed of {v:.1f} m/s, turns of radius at least {v * v / MAX_TURNING_MS2:.0f} m"
                  if np.isfinite(v) and v > 0 else "")
        reasons.append(f"the ride turns (RMS centripetal acceleration {turning_ms2:.1f} m/s^2, at most "
                       f"{MAX_TURNING_MS2:g} for the planar model{radius}): it lacks the turning terms, see "
                       "`euc-ros residual`")
    counts = block_counts(coefs, length)
    block_more_s, block_runs = more_data_for_blocks(counts, n_rec, length, MIN_BLOCKS, dt)
    if nb < MIN_BLOCKS:
        reasons.append(f"too few independent blocks ({nb} of {length * dt:.1f} s in {duration:.1f} s of usable states, "
                       f"at least {MIN_BLOCKS} needed): record at least {_up(block_more_s)} s more in one take, or "
                       f"{_runs(block_runs)}")
    needs = exc.needs(MIN_SHARPNESS, sharpness=float(fit.sharpness))
    if fit.sharpness < MIN_SHARPNESS:
        reasons.append(f"too little excitation: the RMSE curve rises only {100 * fit.sharpness:.0f} % at h +- 0.1 m "
                       f"(at least {100 * MIN_SHARPNESS:.0f} % needed, which riding longer does not change): "
                       + _excitation_text(exc, needs))
    data_reasons = tuple(reasons)
    text, width_more_s, width_runs = _interval_reason(lo2, hi2, random_width, usable, nb, length * dt, duration,
                                                      float(fit.sharpness))
    if text:
        reasons.append(text)
    for_data = (max(more_s if duration < MIN_DURATION_S else 0.0, block_more_s),
                max(more_runs if duration < MIN_DURATION_S else 0, block_runs))
    more = {"record_more_s": max(for_data[0], width_more_s), "more_runs_needed": max(for_data[1], width_runs)}
    ex = excitation_json(exc, needs, usable, nb, length * dt, more)
    return Interval(h, (lo2, hi2), boot, length * dt, nb, eiv_bias_m, not reasons, "; ".join(reasons),
                    float(fit.sharpness), {"turning_rms_ms2": json_float(turning_ms2), "excitation": ex},
                    data_reasons, float(random_width), tuple(usable), float(duration), for_data)


def _interval_reason(lo: float, hi: float, random_width: float, usable, nb: int, block_s: float, duration: float,
                     sharpness: float) -> tuple[str | None, float, int]:
    """Why an interval ``[lo, hi]`` is no identification, with the recording its width needs.

    The reason is None when the interval is bounded and at most :data:`MAX_CI_WIDTH_M` wide; with it, the seconds to add
    to one take and the runs to add that its width needs.
    """
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return ("the data do not bound h: bootstrap optima reach the edge of the search range "
                f"({nb} block{'' if nb == 1 else 's'} of {block_s:.1f} s in {duration:.1f} s of usable "
                f"states, curve sharpness {sharpness:.2f}: more runs like these or more excitation "
                "bound it)", 0.0, 0)
    if hi - lo > MAX_CI_WIDTH_M:
        return _width_text(hi - lo, random_width, usable)
    return None, 0.0, 0


def _runs(k: int) -> str:
    return f"{k} more run{'' if k == 1 else 's'} like these"


def _times(k: float) -> str:
    """A factor as text: two decimals below 2 (a ride just short of the criterion needs 1.05, not 1.0)."""
    return f"{k:.2f}" if k < 2.0 else f"{k:.1f}"


def _up(seconds: float) -> str:
    """``seconds`` rounded up to 0.1 s, as text."""
    return f"{np.ceil(10.0 * seconds - 1e-9) / 10.0:.1f}"


def _span(values, scale: float = 1.0, digits: int = 1) -> str:
    """``"a-b"`` (or one value) of the finite ``values`` times ``scale``."""
    v = [scale * x for x in values if np.isfinite(x)]
    if not v:
        return "-"
    lo, hi = f"{min(v):.{digits}f}", f"{max(v):.{digits}f}"
    return lo if lo == hi else f"{lo}-{hi}"


def _excitation_text(exc: Excitation, needs: Needs) -> str:
    """What the ride had and what h needs, for the sharpness reason."""
    if not exc.has_ride:
        return (f"the residual's RMS sensitivity to h is {exc.sensitivity_nm_per_m:.1f} N m/m, about "
                f"{needs.sensitivity_nm_per_m:.1f} needed: larger longitudinal accelerations")
    had = (f"the recordings changed speed by {_span(exc.speed_change_mps)} m/s (RMS longitudinal acceleration "
           f"{exc.accel_rms_mps2:.2f} m/s^2, {exc.speed_change_accel_rms_mps2:.2f} from the speed changes, peak "
           f"{exc.accel_peak_mps2:.1f} m/s^2, rider pitch range {_span(exc.phi_range_rad, np.degrees(1.0), 0)} deg)")
    k = needs.speed_change_factor
    a_n = needs.speed_change_accel_rms_mps2
    if exc.gain_from_ride and np.isfinite(k):
        need = (f"about {_times(k)} times these speed changes in the same time (about "
                f"{_span(needs.speed_change_mps)} m/s, an RMS acceleration of about {a_n:.2f} m/s^2 from them)")
    else:
        need = f"speed changes giving an RMS acceleration of about {a_n:.2f} m/s^2" + (
            f", about {_times(k)} times these recordings'" if np.isfinite(k) else "")
    text = f"{had}, h needs {need}"
    if np.isfinite(a_n) and a_n > MAX_RIDE_ACCEL_RMS_MPS2:
        lean = np.degrees(np.arctan(a_n / 9.81))
        text += (f"; no ride gives that (a rider would lean about {lean:.0f} deg the whole time): a residual this far "
                 "above what the ride's excitation explains is more likely an effect the 3-DoF model lacks (run "
                 "`euc-ros residual` on these recordings) than too little excitation")
    return text


def _width_text(width: float, random_width: float, usable) -> tuple[str, float, int]:
    """The too-wide reason with the recording it needs.

    The random part of the width shrinks as one over the square root of the usable time, the bias terms do not.
    """
    fixed = width - random_width
    head = f"the 95 % interval is {100 * width:.0f} cm wide (at most {100 * MAX_CI_WIDTH_M:.0f} cm)"
    total = float(sum(usable))
    if not (np.isfinite(random_width) and random_width > 0) or fixed >= MAX_CI_WIDTH_M:
        return (f"{head}: its bias terms alone take {100 * fixed:.0f} cm, which more of the same data does not "
                "narrow (less pose noise or more excitation does)", 0.0, 0)
    factor = (random_width / (MAX_CI_WIDTH_M - fixed)) ** 2
    more_s, runs = more_data_for_seconds(usable, factor * total)
    return (f"{head}: its random part ({100 * random_width:.0f} cm) shrinks as one over the square root of the "
            f"{total:.1f} s of usable states, so record about {_up(more_s)} s more, or {_runs(runs)}", more_s, runs)


def excitation_json(exc: Excitation, needs: Needs, usable, blocks: int, block_s: float, more: dict) -> dict:
    """The JSON's ``uncertainty.excitation``: what the ride had, and what identifying h needs.

    Keys: per recording ``speed_change_mps`` (max - min of ``x_dot``), ``phi_range_deg`` (the rider's
    pitch range) and ``usable_s_per_recording``; ``accel_rms_mps2``, ``accel_peak_mps2`` and
    ``speed_change_accel_rms_mps2`` (its share from the speed changes); ``usable_s`` against
    ``usable_s_needed``; ``blocks`` of ``block_s`` against ``blocks_needed``; ``sensitivity_nm_per_m``
    against ``sensitivity_needed_nm_per_m``; ``speed_change_factor_needed`` (how many times these speed
    changes, in the same time, the sharpness criterion needs: below 1 a margin), with
    ``speed_change_needed_mps`` (per recording, its speed change times that),
    ``speed_change_accel_rms_needed_mps2`` and ``accel_rms_needed_mps2``;
    ``record_more_s`` (usable seconds to add to one take) and ``more_runs_needed`` (runs like these to
    add) for the duration, block and width criteria (0 when they hold). Non-finite numbers are null.

    Parameters
    ----------
    exc : Excitation
        What the ride had (:func:`~euc_ros.core.identify.excitation.measure_excitation`).
    needs : Needs
        What the sharpness criterion needs (:meth:`~euc_ros.core.identify.excitation.Excitation.needs`).
    usable : sequence of float
        Per recording, its usable seconds [s].
    blocks : int
        Number of bootstrap blocks.
    block_s : float
        Block length [s].
    more : dict
        ``record_more_s`` [s] and ``more_runs_needed``.

    Returns
    -------
    dict
    """
    f = json_float
    return {
        "speed_change_mps": [f(v) for v in exc.speed_change_mps],
        "phi_range_deg": [f(np.degrees(v)) for v in exc.phi_range_rad],
        "accel_rms_mps2": f(exc.accel_rms_mps2),
        "accel_peak_mps2": f(exc.accel_peak_mps2),
        "speed_change_accel_rms_mps2": f(exc.speed_change_accel_rms_mps2),
        "usable_s": f(float(sum(usable))),
        "usable_s_per_recording": [f(v) for v in usable],
        "usable_s_needed": MIN_DURATION_S,
        "blocks": int(blocks),
        "blocks_needed": MIN_BLOCKS,
        "block_s": f(block_s),
        "sensitivity_nm_per_m": f(exc.sensitivity_nm_per_m),
        "sensitivity_needed_nm_per_m": f(needs.sensitivity_nm_per_m),
        "speed_change_factor_needed": f(needs.speed_change_factor),
        "speed_change_needed_mps": [f(v) for v in needs.speed_change_mps],
        "speed_change_accel_rms_needed_mps2": f(needs.speed_change_accel_rms_mps2),
        "accel_rms_needed_mps2": f(needs.accel_rms_mps2),
        "record_more_s": f(more["record_more_s"]),
        "more_runs_needed": int(more["more_runs_needed"]),
    }
