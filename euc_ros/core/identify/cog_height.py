"""h, the rider CoG height above the ankle hinge, with its interval: the library call behind ``euc-ros identify``.

:func:`identify_h` fits h on a grid for the paper's models (:func:`~euc_ros.core.identify.fit.fit_h`),
optionally for the 3-DoF model extended with effects (:mod:`.extended`), and, unless told not to, says how
well the data determine the pooled 3-DoF h (:func:`uncertainty_of_h`): the block-bootstrap interval
widened by the errors-in-variables biases (white pose noise, :mod:`.simex`; soft-tissue sliding,
:mod:`.sliding`), identifiability, and the budget over the session's nominal values (:mod:`.budget`).
With a filter chosen from the data, the headline h is the pooled 3-DoF h corrected for the pose noise's
bias and the filter's distortion (:func:`distortion_corrected`), with its own interval; the h at the
chosen filter is a diagnostic. The result, :class:`HIdentification`, carries the headline h, its
interval and the numbers the command reports, and gives the command's JSON document
(:meth:`HIdentification.to_dict`).
"""
from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.bootstrap import block_bootstrap, block_counts
from euc_ros.core.identify.budget import DEFAULT_TOLERANCES, budget, with_session
from euc_ros.core.identify.extended import extended_fits, extended_interval
from euc_ros.core.identify.fit import (
    DEFAULT_H_GRID,
    MODELS,
    IdentifyResult,
    ModelFit,
    coefficients_for,
    fit_h,
    pooled_fit,
)
from euc_ros.core.identify.held import HeldH, geometric_mass_sensitivity, held_h
from euc_ros.core.identify.interval import (
    MIN_BLOCKS,
    Systematics,
    extend_by_prior,
    interval,
    json_float,
    percentiles95,
    student_factor,
    turning_rms,
)
from euc_ros.core.identify.options import FULL_INTERVAL, H_BOUNDS, IntervalOptions, Measured
from euc_ros.core.identify.session_prior import Combined, with_geometric
from euc_ros.core.identify.simex import eiv_bias, eiv_biases
from euc_ros.core.identify.sliding import sliding_bias
from euc_ros.core.identify.sliding_prior import SlidingPrior, prior_spread, rms_from_sliding
from euc_ros.core.memory import release_free_memory
from euc_ros.core.model.terms import EucParams
from euc_ros.core.states.admissible import admissible_h
from euc_ros.core.states.kinematics import RiderStates
from euc_ros.core.states.link_sliding import MIN_SLIDING_M, estimate_sliding
from euc_ros.core.states.settings import FIXED_DEFAULT, ReconstructionSettings

#: The reconstruction whose filter is the chosen one (or the default without a choice).
AUTO = ReconstructionSettings()

__all__ = ["H_BOUNDS", "HIdentification", "FilterPair", "identify_h", "uncertainty_of_h", "extended_uncertainty",
           "probe_coefficients", "filter_floor", "distortion_corrected"]


@dataclass(frozen=True)
class HIdentification:
    """The headline h with its interval, and everything ``euc-ros identify`` reports about it.

    Parameters
    ----------
    h : float
        The headline h [m], the JSON's ``h_m``, the one to give ``torque_estimator``: with the uncertainty
        computed and a 3-DoF head, the data's h combined with the geometric h (:attr:`combined`) or held at it
        (:attr:`held`). The data's h: the pooled 3-DoF h, corrected (:func:`distortion_corrected`) with a filter
        chosen from the data; else the pooled fit of :attr:`model` (NaN without a valid sample).
    interval : tuple of float
        The 95 % interval of :attr:`h` [m] (the JSON's ``h_ci95_m``; NaN, NaN when the uncertainty was
        not computed; infinite ends when the data do not bound h).
    identifiable : bool or None
        Whether the data determine :attr:`h` (None when the uncertainty was not computed).
    reason : str
        Why not ("" when identifiable or not computed).
    model : str
        The model heading the JSON document (``3dof``, ``2dof`` or the extended model's name).
    fits : IdentifyResult
        Per-recording and pooled fits of every model, with their RMSE curves.
    uncertainty : dict or None
        The JSON's uncertainty keys (:func:`uncertainty_of_h`), or None.
    corrected : bool
        Whether :attr:`h` is the corrected h (then :attr:`h_at_filter` and :attr:`interval_at_filter`
        are the JSON's ``diagnostics``).
    h_at_filter : float
        The pooled fit of :attr:`model` [m] at the filter the states were reconstructed with,
        uncorrected (:attr:`h` itself when not :attr:`corrected`).
    interval_at_filter : tuple of float
        Its 95 % interval [m]: the block bootstrap's, widened to contain the noise-corrected h and by the
        filter's distortion floor (:attr:`interval` itself when not :attr:`corrected`).
    held : HeldH or None
        Set when the data do not bound the 3-DoF h (:mod:`.held`): :attr:`h` and :attr:`interval` are then the
        segments' geometric h and its Type B interval (the JSON's ``h_held`` says so and why).
    combined : Combined or None
        Set when the data's 3-DoF h is combined with the segments' geometric h (:mod:`.session_prior`), whose
        :attr:`h` and :attr:`interval` these are (both measurements in the JSON's ``diagnostics.h_combined``).
    """

    h: float
    interval: tuple[float, float]
    identifiable: bool | None
    reason: str
    model: str
    fits: IdentifyResult
    uncertainty: dict | None
    corrected: bool = False
    h_at_filter: float = float("nan")
    interval_at_filter: tuple[float, float] = (float("nan"), float("nan"))
    held: HeldH | None = None
    combined: Combined | None = None

    def to_dict(self) -> dict:
        """The JSON document: the fits headed by :attr:`model`, then the uncertainty (when computed).

        The top level holds one h, the headline ``h_m`` (:attr:`h`), with its ``h_ci95_m``,
        ``identifiable`` and ``h_std_m``; with a corrected headline the fit at the chosen filter is under
        ``diagnostics`` (``h_at_chosen_filter_m``, ``h_at_chosen_filter_ci95_m``, ...). ``per_recording``
        and ``models`` hold the fits of every model (each at its optimum, uncorrected).

        Returns
        -------
        dict
        """
        data = self.fits.to_json(self.model)
        if self.uncertainty is not None:
            if not self.corrected:        # the formal std of the fit that h_m is (else under diagnostics)
                data["h_std_formal_m"] = data.get("h_std_m")
            data.update(self.uncertainty)
        if self.held is not None:   # h_m is the held h; h_ci95_m and h_std_m are its own
            data.update(h_m=json_float(self.h), h_ci95_m=[json_float(v) for v in self.interval],
                        h_std_m=json_float(self.held.std_m), h_held=self.held.to_json())
        if self.combined is not None:   # h_m combines the data's h and the geometric h: both are diagnostics
            data.update(h_m=json_float(self.h), h_ci95_m=[json_float(v) for v in self.interval],
                        h_std_m=json_float(self.combined.std_m))
            data["diagnostics"] = {**data.get("diagnostics", {}), "h_combined": self.combined.to_json()}
        return data

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text (indented, with a final newline).

        Returns
        -------
        str
        """
        return json.dumps(self.to_dict(), indent=2) + "\n"


def identify_h(states: Sequence[RiderStates], session, params: EucParams | None = None, *,
               reconstruction: ReconstructionSettings = AUTO, filter_choice=None,
               h_grid=DEFAULT_H_GRID, models: Sequence[str] = MODELS,
               effects: dict[str, dict[str, float]] | None = None, model: str | None = None,
               settings: dict | None = None, uncertainty: IntervalOptions | None = FULL_INTERVAL,
               measured: Measured | None = None) -> HIdentification:
    """Identify h from reconstructed recordings, with its interval.

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states, reconstructed with ``reconstruction``. The interval needs each recording's
        poses in ``states[i].meta["series"]``; without them the errors-in-variables biases and the budget
        are left out.
    session : Session
        The recordings' session (the budget perturbs its nominal values).
    params : EucParams, optional
        Nominal parameters (default: the session's).
    reconstruction : ReconstructionSettings
        How the states were reconstructed (the biases reconstruct the recordings again alike); with
        ``"auto"`` (default) the filter is ``filter_choice``'s, or without one the fixed default
        (:data:`~euc_ros.core.states.settings.FIXED_DEFAULT`).
    filter_choice : FilterChoice or WindowChoice, optional
        The filter chosen from the data (:func:`~euc_ros.core.states.filter_choice.choose_filter`)
        the states were reconstructed with; its ``probe`` gives the interval a floor for the
        distortion the filter leaves (:func:`filter_floor`), and h corrected for the pose noise and that
        distortion (:func:`distortion_corrected`), which becomes the headline h of a 3-DoF head (the
        JSON's ``h_m`` with ``h_ci95_m``; the fit at the chosen filter goes under ``diagnostics``).
        Without it (a fixed window) there are neither: the headline is the fit.
    h_grid : array_like
        CoG heights of the grid search [m], increasing.
    models : sequence of {"3dof", "2dof"}
        The paper's models to fit (the interval needs ``3dof``).
    effects : dict, optional
        Effects of the residual analysis added to the 3-DoF model, ``{effect: {parameter: value}}`` in the
        residual report's units; h is then identified for that model too.
    model : str, optional
        The model heading the JSON document (default: the extended model with ``effects``, else ``3dof``).
    settings : dict, optional
        Stored in the fits (and the JSON).
    uncertainty : IntervalOptions or None
        What the interval, identifiability and biases include (the slow part); None: the fits alone.
    measured : Measured, optional
        What the caller measured on these recordings already (SIMEX's first replicate, the links' sliding;
        default: the links' sliding of ``filter_choice``, else measured here).

    Returns
    -------
    HIdentification

    Raises
    ------
    ConfigError
        A fixed filter in ``reconstruction`` other than ``filter_choice``'s.
    """
    params = EucParams.from_session(session) if params is None else params
    reconstruction = _fixed_filter(reconstruction, filter_choice)
    fits = fit_h(states, params, h_grid, models=models, settings=settings)
    head = model or "3dof"
    if effects:
        name, per, pooled = extended_fits(states, params, effects, np.asarray(h_grid, dtype=float))
        for rec, fit in zip(fits.per_recording, per):
            rec.fits[name] = fit
        fits.pooled[name] = pooled
        fits.settings["effects"] = {k: dict(v) for k, v in effects.items()}
        fits.settings["extended_model"] = name
        head = model or name
    pooled3 = fits.pooled.get("3dof")
    h = float(pooled3.h_m) if pooled3 is not None else float("nan")
    if head != "3dof" and head in fits.pooled:
        h = float(fits.pooled[head].h_m)
    if not uncertainty or pooled3 is None:
        return HIdentification(h, (float("nan"), float("nan")), None, "", head, fits, None, h_at_filter=h)
    unc = uncertainty_of_h(states, session, params, pooled3, reconstruction=reconstruction,
                           filter_choice=filter_choice, options=uncertainty, measured=measured)
    if head != "3dof" and effects and head in fits.pooled:
        unc = extended_uncertainty(unc, states, params, effects, h, base_h=float(pooled3.h_m))
    elif head != "3dof":                     # a 2-DoF head keeps its own h_m (the fit's)
        unc = {k: v for k, v in unc.items() if k != "h_m"}
    ci = _pair(unc["h_ci95_m"])
    corrected = "h_m" in unc and head == "3dof"
    h_fit, ci_fit = h, ci
    if corrected:                            # the headline is the corrected h; the fit is a diagnostic
        h, ci_fit = float(unc["h_m"]), _pair(unc["diagnostics"]["h_at_chosen_filter_ci95_m"])
    u = unc.get("uncertainty") or {}
    need = u.get("excitation", {}).get("speed_change_accel_rms_needed_mps2")
    s_mass = geometric_mass_sensitivity([st.meta.get("series") for st in states], session)
    held = held_h(states, params, h, ci, tolerances=uncertainty.tolerances, sharpness=float(pooled3.sharpness),
                  accel_needed_mps2=need, mass_sensitivity=s_mass) if head == "3dof" else None
    if held is not None:                     # the data do not bound the 3-DoF h: the geometric h (.held)
        h, ci = held.h_m, held.ci95_m
    combined = with_geometric(states, params, h, ci, tolerances=uncertainty.tolerances, mass_sensitivity=s_mass,
                              bounds=uncertainty.h_bounds, admissible=u.get("h_admissible_m")) \
        if held is None and head == "3dof" else None
    if combined is not None:                 # the data's h with the segments' geometric h (.session_prior)
        h, ci = combined.h_m, combined.ci95_m
    return HIdentification(h, ci, bool(unc["identifiable"]), unc["identifiability_reason"] or "", head, fits,
                           unc, corrected, h_fit, ci_fit, held, combined)


def _fixed_filter(reconstruction: ReconstructionSettings, choice) -> ReconstructionSettings:
    """``reconstruction`` with its filter fixed: ``choice``'s when it is ``"auto"``, else the default filter.

    Raises
    ------
    ConfigError
        A fixed filter other than ``choice``'s.
    """
    if reconstruction.is_auto:
        if choice is None:
            return reconstruction.with_filter(FIXED_DEFAULT.window_s, FIXED_DEFAULT.polyorder)
        return reconstruction.with_filter(choice.window_s, choice.polyorder)
    if choice is not None and (abs(float(reconstruction.window_s) - float(choice.window_s)) > 1e-9
                               or int(reconstruction.polyorder) != int(choice.polyorder)):
        raise ConfigError(f"the states' filter ({reconstruction.window_s} s, order {reconstruction.polyorder}) is not "
                          f"the chosen one ({choice.window_s} s, order {choice.polyorder})", key="--window-s")
    return reconstruction


def _pair(ci) -> tuple[float, float]:
    """A JSON interval as floats (NaN for a null end)."""
    lo, hi = ci if ci is not None else (None, None)
    return tuple(float("nan") if v is None else float(v) for v in (lo, hi))


#: Keys of the base model's uncertainty that belong to the base model only (moved under ``base_model``
#: when the JSON is headed by an extended model).
BASE_ONLY_KEYS = ("h_m", "h_ci95_m", "identifiable", "identifiability_reason", "uncertainty", "h_std_m",
                  "diagnostics", "h_range_m", "uncertainty_budget")
#: Block length of the extended model's interval when the base model's bootstrap gives none [s].
DEFAULT_BLOCK_S = 2.0


def extended_uncertainty(base: dict, states, params: EucParams, effects: dict, h: float, *,
                         base_h: float = float("nan")) -> dict:
    """The uncertainty keys of a JSON headed by the extended model of ``effects`` (fitted h ``h``).

    The head's ``h_ci95_m`` is the extended model's own: its block-robust statistical interval
    (:func:`~.extended.extended_interval`, blocks as long as the base model's bootstrap blocks), widened
    as identify widens the base model's: it contains ``h - bias`` (the base model's noise and sliding
    biases, the same states filtered alike), reaches ``filter_floor_m`` beyond on both sides and holds
    the sliding prior's range. The
    errors of those bias estimates are not added. Everything computed for the 3-DoF model goes under
    ``base_model`` with that model's name and its headline h (``base``'s ``h_m`` when it has one, the
    corrected h, with its ``diagnostics``; else the fit ``base_h``), so no interval stands beside another
    model's h. ``uncertainty.excitation`` is the base model's (the ride's speed changes and
    sensitivities) with the extended model's blocks and the recording they need.

    Parameters
    ----------
    base : dict
        The 3-DoF model's uncertainty keys (:func:`uncertainty_of_h`).
    states, params
        The recordings' states and the session's parameters, as for :func:`identify_h`.
    effects : dict
        ``{effect: {parameter: value}}`` of the extended model.
    h : float
        The extended model's fitted h [m].
    base_h : float
        The pooled 3-DoF fit's h [m] (the base model's ``h_m`` when ``base`` has none).

    Returns
    -------
    dict
        ``base``'s keys with the extended model's ``h_ci95_m``, ``identifiable``, ``identifiability_reason``,
        ``h_std_m`` and ``uncertainty``, and the base model's under ``base_model``.
    """
    u = base.get("uncertainty") or {}
    block_s = u.get("block_s") or DEFAULT_BLOCK_S
    lo, hi, se, nb = extended_interval(states, params, effects, h, float(block_s))
    bias = sum(v for v in (u.get("eiv_bias_m"), u.get("sliding_bias_m")) if v is not None)
    floor = u.get("filter_floor_m") or 0.0
    if np.isfinite(lo) and np.isfinite(hi):
        lo, hi = min(lo, lo - bias) - floor, max(hi, hi - bias) + floor
        lo, hi = extend_by_prior(lo, hi, u.get("sliding_prior_range_m") or (0.0, 0.0))
    reasons = []
    ex = dict(u.get("excitation") or {})
    usable = [v for v in ex.get("usable_s_per_recording") or [] if v is not None]
    more_s = float(block_s) * max(MIN_BLOCKS - nb, 0)   # each block_s seconds more in one take add a block
    runs = int(np.ceil(max(MIN_BLOCKS - nb, 0) * len(usable) / nb)) if nb > 0 and usable else 0
    if nb < MIN_BLOCKS:
        reasons.append(f"too few independent blocks ({nb} of {float(block_s):.1f} s"
                       + (f" in {sum(usable):.1f} s of usable states" if usable else "")
                       + f", at least {MIN_BLOCKS} needed): record at least {more_s:.1f} s more in one take"
                       + (f", or {runs} more run{'' if runs == 1 else 's'} like these" if runs else ""))
    if not (np.isfinite(lo) and np.isfinite(hi)):
        reasons.append(f"the extended model's residual does not bound h ({nb} blocks of {float(block_s):.1f} s: "
                       "more runs like these bound it)")
    if ex:
        ex.update(blocks=nb, block_s=float(block_s), record_more_s=more_s, more_runs_needed=runs)
    out = {k: v for k, v in base.items() if k not in BASE_ONLY_KEYS}
    out["base_model"] = {"model": "3dof", "h_m": json_float(base_h),
                         **{k: base[k] for k in BASE_ONLY_KEYS if k in base}}
    out.update({"h_ci95_m": [json_float(lo), json_float(hi)], "identifiable": not reasons,
                "identifiability_reason": "; ".join(reasons) or None, "h_std_m": json_float(se),
                "uncertainty": {"method": "block sandwich (effects fixed)", "n_blocks": nb, "block_s": float(block_s),
                                "eiv_bias_m": json_float(bias), "filter_floor_m": json_float(floor),
                                "sharpness": None, **({"excitation": ex} if ex else {})}})
    return out


def uncertainty_of_h(states: Sequence[RiderStates], session, params: EucParams, fit: ModelFit, *,
                     reconstruction: ReconstructionSettings = AUTO, filter_choice=None,
                     options: IntervalOptions = FULL_INTERVAL, measured: Measured | None = None) -> dict:
    """Interval, identifiability, errors-in-variables bias and budget of the pooled 3-DoF h (JSON-ready).

    Parameters
    ----------
    states, session, params
        As for :func:`identify_h`.
    fit : ModelFit
        The pooled 3-DoF fit of ``states``.
    reconstruction, filter_choice, measured
        As for :func:`identify_h`.
    options : IntervalOptions
        What the interval includes.

    Returns
    -------
    dict
        The JSON document's keys ``h_ci95_m``, ``identifiable``, ``identifiability_reason``,
        ``uncertainty``, ``h_std_m``, and with the budget ``h_range_m`` and ``uncertainty_budget``.
        They describe the headline h. With ``filter_choice`` and a corrected h
        (:func:`distortion_corrected`) the headline is that h: the keys add ``h_m`` (the corrected h,
        replacing the fit's) and ``diagnostics``, the fit at the chosen filter (``h_at_chosen_filter_m``
        with its interval ``h_at_chosen_filter_ci95_m``, ``h_at_chosen_filter_bootstrap_ci95_m``,
        ``h_at_chosen_filter_std_m`` and ``h_at_chosen_filter_std_formal_m``); ``h_ci95_m`` is the
        corrected h's own interval, ``identifiable`` judges it, ``h_std_m`` and
        ``uncertainty.bootstrap_ci95_m`` are its paired bootstrap's (``uncertainty.method``), and
        ``h_range_m`` is centred on it. Without them the headline is ``fit.h_m`` (no ``h_m`` key).
    """
    rec = _fixed_filter(reconstruction, filter_choice)
    measured = measured or Measured()
    series = [st.meta.get("series") for st in states]
    have_series = np.isfinite(fit.h_m) and all(s is not None for s in series)
    (bias, err), probe, h_probe, probe_eiv = _noise_terms(series, session, params, fit, rec, filter_choice,
                                                          measured, have_series)
    slide, spread = _sliding_terms(states, series, session, params, fit, rec, filter_choice, options, measured,
                                   have_series)
    prior_range = tuple(spread["sliding_prior_range_m"]) if spread else (0.0, 0.0)
    total, total_err = bias, err
    sliding_seen = slide is not None and np.isfinite(slide["sliding_bias_m"]) and slide["sliding_bias_m"] != 0.0
    if sliding_seen:
        total = (bias if np.isfinite(bias) else 0.0) + slide["sliding_bias_m"]
        total_err = float(np.hypot(err if np.isfinite(err) else 0.0, slide["sliding_bias_err_m"]))
    floor = None
    if probe is not None:
        floor = filter_floor(series, session, params, fit.h_m, filter_choice, reconstruction=rec, h_probe=h_probe)
    coefs = coefficients_for(states, params, "3dof", None)
    terms = Systematics(total, total_err, floor["filter_floor_m"] if floor else 0.0, prior_range)
    iv = interval(coefs, fit, window=states[0].window, dt=states[0].dt, systematics=terms, h_bounds=options.h_bounds,
                  turning_ms2=turning_rms(states), states=states)
    corrected = None
    release_free_memory()             # the replicates' and the probe's temporaries, before the bootstraps
    if probe is not None:
        slide_m, slide_err = (slide["sliding_bias_m"], slide["sliding_bias_err_m"]) if sliding_seen else (0.0, 0.0)
        pair = FilterPair(filter_choice, coefs, probe, fit.h_m, h_probe, states[0].window, states[0].dt)
        corrected = distortion_corrected(series, session, params, pair, eiv=(bias, err), sliding=(slide_m, slide_err),
                                         h_bounds=options.h_bounds, reconstruction=rec, probe_eiv=probe_eiv)
        del pair
    del coefs, probe                  # per-sample coefficients: not kept through the budget
    out, head = _headline(iv, fit, corrected, prior_range, filter_choice)
    kept = out.pop("_kept")
    if slide is not None:
        out["uncertainty"]["eiv_bias_m"] = json_float(bias)
        out["uncertainty"].update({k: json_float(v) for k, v in slide.items()})
    if floor is not None:
        out["uncertainty"].update({k: json_float(v) for k, v in floor.items()})
    if spread is not None:
        out["uncertainty"].update({k: ([json_float(x) for x in v] if isinstance(v, list) else json_float(v))
                                   for k, v in spread.items()})
    if corrected is not None:
        out["uncertainty"].update({k: json_float(v) for k, v in corrected.items()})
        out["uncertainty"].update(kept)
    out["h_std_m"] = _std_of(*head.bootstrap_ci95_m)
    if options.with_budget and have_series:
        release_free_memory()         # the bootstraps' temporaries, before the budget's reconstructions
        tolerances = dict(DEFAULT_TOLERANCES) if options.tolerances is None else options.tolerances
        b = budget(series, states, session, params, fit.h_m, reconstruction=rec, tolerances=tolerances)
        if head is not iv:            # the sensitivities are the fit's; the range is centred on the headline h
            shift = head.h_m - fit.h_m
            b["h_range_m"] = [None if v is None else float(v + shift) for v in b["h_range_m"]]
        out["h_range_m"] = b["h_range_m"]
        with_session(out, b, head.h_m, options.h_bounds)      # the session's Type B terms inside the interval
        out["uncertainty_budget"] = b
    if have_series:
        _within_admissible(out, admissible_h(series, session), head.h_m)
    return out


def _within_admissible(out: dict, adm, h: float) -> None:
    """The interval cut at the range of h the rider's recorded body allows, in place (``uncertainty.h_admissible_m``).

    An h outside that range is not the rider's: it is not identifiable, and the interval holds only the admissible
    part (both ends None when nothing admissible is in it).
    """
    if adm is None:
        return
    out["uncertainty"]["h_admissible_m"] = adm.to_json()
    lo, hi = out["h_ci95_m"]
    lo = None if lo is None else max(lo, adm.low_m)
    hi = None if hi is None else min(hi, adm.high_m)
    if lo is not None and hi is not None and lo > hi:
        lo = hi = None
    out["h_ci95_m"] = [lo, hi]
    if np.isfinite(h) and not adm.low_m <= h <= adm.high_m:
        reason = (f"h = {h:.3f} m lies outside [{adm.low_m:.3f}, {adm.high_m:.3f}] m, the range the rider's "
                  "recorded joints and the session's mass fractions allow")
        out["identifiable"] = False
        out["identifiability_reason"] = "; ".join(r for r in (out.get("identifiability_reason"), reason) if r)


def _noise_terms(series, session, params: EucParams, fit: ModelFit, rec: ReconstructionSettings, filter_choice,
                 measured: Measured, have_series: bool):
    """SIMEX's bias of h at the chosen filter (and at the probe), and the probe's coefficients and h.

    Returns
    -------
    tuple
        ``((bias, error), probe coefficients or None, h at the probe or None, (probe bias, error) or None)``.
    """
    bias = err = float("nan")
    probe = h_probe = probe_eiv = None
    with_probe = filter_choice is not None and have_series
    biases = []
    if have_series:
        # SIMEX at the chosen filter, and at the probe from the same re-noised recordings; the probe's own h is
        # fitted after (its replicates' h do not depend on it: the bias is their mean minus it), so its
        # coefficients are not held through the replicates
        filters = [(rec.window_s, rec.polyorder, fit.h_m)]
        if with_probe and float(filter_choice.probe[0]) > float(filter_choice.window_s):
            filters.append((float(filter_choice.probe[0]), int(filter_choice.probe[1]), 0.0))
        biases = eiv_biases(series, session, params, filters, reconstruction=rec, share=measured.simex_share)
        bias, err = biases[0]
    if with_probe:
        probe = probe_coefficients(series, session, params, filter_choice, reconstruction=rec)
        h_probe = pooled_fit(probe, DEFAULT_H_GRID).h_m
    if len(biases) > 1:
        probe_eiv = (biases[1][0] - h_probe, biases[1][1])
    return (bias, err), probe, h_probe, probe_eiv


def _sliding_terms(states, series, session, params: EucParams, fit: ModelFit, rec: ReconstructionSettings,
                   filter_choice, options: IntervalOptions, measured: Measured, have_series: bool):
    """The sliding the links show (its SIMEX bias) and the spread of h under the shared sliding's prior.

    Returns
    -------
    tuple
        ``(sliding bias dict or None, prior spread dict or None)``.
    """
    # soft-tissue sliding the chain's links show (docs/cog_artefacts.md): its SIMEX bias joins the
    # white-noise bias in the interval (0 when no sliding above MIN_SLIDING_M is seen)
    slide = links = None
    if have_series and options.sliding:
        try:
            links = measured.link_sliding or getattr(filter_choice, "sliding", None) \
                or estimate_sliding(series, session)
        except ConfigError:      # no chain link between the recorded bodies: no sliding measurable
            links = None
    if have_series and options.sliding and links is not None:
        try:
            slide = sliding_bias(series, session, params, fit.h_m, reconstruction=rec, sliding=links)
        except ConfigError:      # the chain cannot be estimated from these recordings
            slide = None
    # the sliding all bodies share, which no link shows: a stated prior, propagated by re-simulation
    # (its default size is the measured sliding: none when the sliding is left out)
    prior = options.sliding_prior or SlidingPrior()
    if prior.rms_m is None:
        prior = dataclasses.replace(prior, rms_m=rms_from_sliding(links, session, MIN_SLIDING_M))
    spread = prior_spread(states, params, fit.h_m, prior) if np.isfinite(fit.h_m) else None
    return slide, spread


def _headline(iv, fit: ModelFit, corrected: dict | None, prior_range, filter_choice):
    """The JSON keys of the headline h (the corrected h's, or the fit's with the corrected h kept beside it).

    Returns
    -------
    tuple
        ``(out, head)``: the keys (``_kept``: what goes into ``uncertainty`` after the corrected terms) and the
        headline's :class:`~euc_ros.core.identify.interval.Interval`.
    """
    head = iv
    kept = {}
    if corrected is not None:
        hc = corrected.pop("h_corrected_m")
        ci = extend_by_prior(*corrected.pop("h_corrected_ci95_m"), prior_range)
        boot = corrected.pop("h_corrected_bootstrap_ci95_m")
        random_width = corrected.pop("h_corrected_random_width_m")
        if np.isfinite(hc) and not coloured_noise(filter_choice):
            head = iv.for_estimate(hc, ci, boot, random_width)      # the headline: h corrected, on its own interval
        elif np.isfinite(hc):         # a diagnostic: the probe's change is not the distortion's alone
            kept = {"h_corrected_m": json_float(hc), "h_corrected_ci95_m": [json_float(v) for v in ci],
                    "h_corrected_not_headline": NOT_HEADLINE}
    out = dict(head.to_json())
    if head is not iv:
        lo, hi = iv.bootstrap_ci95_m
        out["h_m"] = json_float(head.h_m)
        out["diagnostics"] = {
            "h_at_chosen_filter_m": json_float(fit.h_m),
            "h_at_chosen_filter_ci95_m": [json_float(v) for v in iv.ci95_m],
            "h_at_chosen_filter_bootstrap_ci95_m": [json_float(v) for v in iv.bootstrap_ci95_m],
            "h_at_chosen_filter_std_m": _std_of(lo, hi),
            "h_at_chosen_filter_std_formal_m": json_float(fit.h_std_m)}
        out["uncertainty"]["method"] = "paired block bootstrap (chosen and probe filter)"
    out["_kept"] = kept
    return out, head


#: Why a distortion-corrected h is not the headline when the noise is coloured (:func:`coloured_noise`).
NOT_HEADLINE = ("the noise is coloured (soft-tissue sliding the links show, or a tracker's smoothing): h moves "
                "between the chosen and the probe filter by the distortion and by the noise's own filter-"
                "dependent bias, which the extrapolation cannot tell apart; the headline is the fit at the "
                "chosen filter, its interval holding the distortion's floor")


def coloured_noise(choice) -> bool:
    """Whether the filter choice took the recordings' noise as coloured (``noise_model``; False without a choice).

    Parameters
    ----------
    choice : FilterChoice or WindowChoice or None
        The filter chosen from the data.

    Returns
    -------
    bool

    Notes
    -----
    The distortion correction (:func:`distortion_corrected`) reads the filter's bias from the change of h
    between the chosen filter and its probe. White pose noise's bias is removed at both filters (SIMEX);
    coloured noise (soft tissue sliding in the band of the motion) also biases h by an amount that depends
    on the filter, and no replicate of it is known well enough to remove (the links show only the bodies'
    relative sliding). Measured on 18 rides of the independent generator with 2-4 mm of sliding (tuning
    seeds 100-117, ``studies/real_ride_identify.py``): the corrected h erred by +48 +- 119 mm (up to 414 mm,
    where the choice took order 2 and its probe 2.5 s), the fit at the chosen filter by +0.4 +- 17 mm.
    """
    return getattr(choice, "noise_model", "white") == "coloured" if choice is not None else False


def _std_of(lo: float, hi: float) -> float | None:
    """The standard deviation of a 95 % bootstrap interval ``[lo, hi]`` taken as normal [m] (None when unbounded)."""
    return float((hi - lo) / 3.92) if np.isfinite(lo) and np.isfinite(hi) else None


def probe_coefficients(series_list, session, params: EucParams, choice, *,
                       reconstruction: ReconstructionSettings = FIXED_DEFAULT) -> list[np.ndarray]:
    """The recordings' 3-DoF residual coefficients with the probe filter ``choice.probe``.

    Made by :func:`~euc_ros.core.identify.fit.coefficients_for`, each recording's states dropped once reduced.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings' poses.
    session : Session
        Their session.
    params : EucParams
        The model's parameters.
    choice : FilterChoice or WindowChoice
        The chosen filter with its ``probe`` = ``(window_s, polyorder)``.
    reconstruction : ReconstructionSettings
        The reconstruction but its filter.

    Returns
    -------
    list of ndarray (6, n_i)
    """
    probe = reconstruction.with_filter(*choice.probe)
    return [coefficients_for([probe.reconstruct(s, session, lean=True)], params, "3dof", None)[0]
            for s in series_list]


def filter_floor(series_list, session, params: EucParams, h: float, choice, *,
                 reconstruction: ReconstructionSettings = FIXED_DEFAULT, h_probe: float | None = None) -> dict:
    """Bound on the bias of h the chosen filter's distortion leaves, from h with the probe filter [m].

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings' poses.
    session, params
        As for :func:`identify_h`.
    h : float
        The pooled 3-DoF h with the chosen filter [m].
    choice : FilterChoice or WindowChoice
        The chosen filter; ``probe`` = ``(window_s, polyorder)`` of the companion filter whose RMS
        distortion of the accelerations is ``probe_ratio`` (about 2) times the chosen one's.
    reconstruction : ReconstructionSettings
        The reconstruction but its filter.
    h_probe : float, optional
        h with the probe filter [m], when already fitted (else fitted here).

    Returns
    -------
    dict
        ``h_probe_m`` (h with the probe filter), ``filter_distortion_m`` (``h_probe - h``) and
        ``filter_floor_m`` (the bound, >= 0).

    Notes
    -----
    The filter distorts the accelerations by a relative amount of RMS ``B``; h, a smooth function of
    the regressors, moves by ``b(B) = a B + c B^2 + ...`` (``b(0) = 0``: an undistorting filter
    leaves no bias). The probe's distortion is ``r B`` (``r`` = ``probe_ratio``), so
    ``d = h_probe - h = a (r - 1) B + c (r^2 - 1) B^2``. When the linear and the quadratic term have
    one sign (attenuated accelerations lower h in both: the measured rides), ``|b(B)| <= |d| / (r - 1)``,
    with equality for a linear ``b``; this is the floor. Its sign is left open (the interval moves
    out by it at both ends) because with noisy poses ``d`` also holds the change of the noise's
    errors-in-variables bias between the two windows. The data cannot settle the distortion any
    better than this: a noise-free interval (a few micrometres of bootstrap) gets this width.
    """
    if h_probe is None:
        coefs = probe_coefficients(series_list, session, params, choice, reconstruction=reconstruction)
        h_probe = pooled_fit(coefs, DEFAULT_H_GRID).h_m
    r = _probe_ratio(choice)
    r = r if np.isfinite(r) else 2.0
    d = h_probe - h
    return {"h_probe_m": h_probe, "filter_distortion_m": d,
            "filter_floor_m": abs(d) / (r - 1.0) if np.isfinite(d) else float("nan")}


def _probe_ratio(choice) -> float:
    """``choice.probe_ratio`` when it is a number above 1, else NaN."""
    r = getattr(choice, "probe_ratio", None)
    return float(r) if r is not None and np.isfinite(r) and r > 1.0 else float("nan")


@dataclass(frozen=True)
class FilterPair:
    """The pooled 3-DoF fits of the same recordings at the chosen filter and at its probe.

    Parameters
    ----------
    choice : FilterChoice or WindowChoice
        The chosen filter with its ``probe`` and ``probe_ratio``.
    coefs, probe_coefs : sequence of ndarray (6, n_i)
        The recordings' residual coefficients with the chosen filter and with the probe filter
        (:func:`probe_coefficients`).
    h, h_probe : float
        The pooled 3-DoF h with the chosen filter and with the probe filter [m].
    window : int
        The chosen filter's window [samples] (the bootstrap's shortest block).
    dt : float
        Sample period [s].
    """

    choice: object
    coefs: Sequence
    probe_coefs: Sequence
    h: float
    h_probe: float
    window: int
    dt: float


def distortion_corrected(series_list, session, params: EucParams, pair: FilterPair, *, eiv: tuple[float, float],
                         sliding: tuple[float, float] = (0.0, 0.0), h_bounds: tuple[float, float] = H_BOUNDS,
                         reconstruction: ReconstructionSettings = FIXED_DEFAULT, n_boot: int = 1000, seed: int = 0,
                         probe_eiv: tuple[float, float] | None = None) -> dict:
    """The h corrected for the pose noise and for the filter's distortion, with its own 95 % interval.

    Parameters
    ----------
    series_list, session, params
        As for :func:`filter_floor`.
    pair : FilterPair
        The fits at the chosen filter and at its probe.
    eiv : (float, float)
        SIMEX's bias of ``pair.h`` and its standard error [m] (:func:`~euc_ros.core.identify.simex.eiv_bias`;
        NaN: no noise measurable, taken as 0).
    sliding : (float, float)
        The soft-tissue sliding's bias of h and its standard error [m] (:mod:`.sliding`; 0 when none
        is seen): not subtracted (a rigid rider's pose noise can pass for sliding), but the interval
        contains the estimate corrected for it too, as ``h_ci95_m`` does.
    reconstruction : ReconstructionSettings
        The reconstruction but its filter (SIMEX at the probe when ``probe_eiv`` is not given).
    h_bounds, n_boot, seed
        As for :func:`~euc_ros.core.identify.interval.interval` (the same seed pairs the replicates
        with those of ``h_ci95_m``).
    probe_eiv : (float, float), optional
        SIMEX's bias and standard error at the probe filter, when already measured
        (:func:`~euc_ros.core.identify.simex.eiv_biases`); else measured here.

    Returns
    -------
    dict
        ``h_corrected_m``, ``h_corrected_ci95_m`` (NaN, and NaN ends, without a probe longer than the
        chosen filter), ``h_corrected_bootstrap_ci95_m`` (the paired bootstrap's percentiles alone) and
        ``h_corrected_random_width_m`` (their width widened for few blocks: the part more data narrows),
        ``probe_eiv_bias_m`` and ``probe_eiv_bias_err_m`` (SIMEX at the probe),
        ``distortion_correction_m`` (the extrapolation's step, ``h_corrected - (h - eiv_bias)``).

    Notes
    -----
    SIMEX removes the noise's bias at each filter: ``h_c = h - b_c`` with the chosen filter,
    ``h_p = h_probe - b_p`` with the probe, whose RMS distortion of the accelerations is ``r`` times
    the chosen one's. The distortion moves h by ``a B`` to first order in the distortion ``B``, so
    Richardson's extrapolation to ``B = 0`` is ``h_0 = h_c - (h_p - h_c) / (r - 1)
    = (r h_c - h_p) / (r - 1)`` (what remains is of second order: ``-c r B^2`` for a bias
    ``a B + c B^2``). Its random error comes from the same data at both filters, so the interval is
    a paired block bootstrap: every replicate draws the same blocks of samples for both filters
    (:func:`~euc_ros.core.identify.bootstrap.block_bootstrap` with the same block counts and seed)
    and combines its two optima alike; the percentiles are widened as for ``h_ci95_m`` (Student's t
    for few blocks) and by twice the standard error of the combined SIMEX corrections (the two
    taken independent, which their common draws only make smaller).
    """
    choice, coefs, probe_coefs, h, h_probe = pair.choice, pair.coefs, pair.probe_coefs, pair.h, pair.h_probe
    (eiv_bias_m, eiv_bias_err_m), (sliding_m, sliding_err_m) = eiv, sliding
    w_p, p_p = choice.probe
    r = _probe_ratio(choice)
    b_c = float(eiv_bias_m) if np.isfinite(eiv_bias_m) else 0.0
    e_c = float(eiv_bias_err_m) if np.isfinite(eiv_bias_err_m) else 0.0
    b_p, e_p = probe_eiv if probe_eiv is not None else eiv_bias(
        series_list, session, params, h_probe, reconstruction=reconstruction.with_filter(w_p, p_p), with_error=True)
    nan = float("nan")
    out = {"probe_eiv_bias_m": b_p, "probe_eiv_bias_err_m": e_p, "h_corrected_m": nan,
           "h_corrected_ci95_m": (nan, nan), "h_corrected_bootstrap_ci95_m": (nan, nan),
           "h_corrected_random_width_m": nan, "distortion_correction_m": nan}
    b_p = float(b_p) if np.isfinite(b_p) else 0.0
    e_p = float(e_p) if np.isfinite(e_p) else 0.0
    if not (np.isfinite(r) and np.isfinite(h) and np.isfinite(h_probe)) or float(w_p) <= float(choice.window_s):
        return out

    def combine(hc, hp):
        return (r * (hc - b_c) - (hp - b_p)) / (r - 1.0)

    h0 = combine(h, h_probe)
    hb_c, length, nb, _ = block_bootstrap(coefs, h, pair.window, pair.dt, n_boot=n_boot, seed=seed, h_bounds=h_bounds)
    hb_p, _, nb_p, _ = block_bootstrap(probe_coefs, h_probe, pair.window, pair.dt, n_boot=n_boot, seed=seed,
                                       h_bounds=h_bounds, counts=block_counts(coefs, length))
    with np.errstate(invalid="ignore"):     # unbounded replicates (+-inf at both filters) give NaN: unbounded
        reps = combine(hb_c, hb_p)
    boot = percentiles95(reps, nb if nb == nb_p else 0)
    k = student_factor(nb)
    e = 2.0 * float(np.sqrt((r * e_c) ** 2 + e_p ** 2) / (r - 1.0))
    lo, hi = h0 - k * (h0 - boot[0]), h0 + k * (boot[1] - h0)
    random_width = hi - lo
    if np.isfinite(sliding_m) and sliding_m != 0.0:
        e = float(np.hypot(e, 2.0 * sliding_err_m))
        lo, hi = min(lo, lo - sliding_m), max(hi, hi - sliding_m)
    out.update(h_corrected_m=h0, h_corrected_ci95_m=(lo - e, hi + e), h_corrected_bootstrap_ci95_m=boot,
               h_corrected_random_width_m=random_width, distortion_correction_m=h0 - (h - b_c))
    return out
