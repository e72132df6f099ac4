"""h, the rider CoG height above the ankle hinge, with its interval: the library call behind ``euc-ros identify``.

:func:`identify_h` fits h on a grid for the paper's models (:func:`~euc_ros.core.identify.fit.fit_h`),
optionally for the 3-DoF model extended with effects (:mod:`.extended`), and, unless told not to, says how
well the data determine the pooled 3-DoF h (:func:`uncertainty_of_h`): the block-bootstrap interval
widened by the errors-in-variables biases (white pose noise, :mod:`.simex`; soft-tissue sliding,
:mod:`.sliding`), identifiability, and the budget over the session's nominal values (:mod:`.budget`).
The result, :class:`HIdentification`, carries h, its interval and the numbers the command reports, and
gives the command's JSON document (:meth:`HIdentification.to_dict`).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.budget import DEFAULT_TOLERANCES, budget
from euc_ros.core.identify.extended import extended_fits
from euc_ros.core.identify.fit import (
    DEFAULT_H_GRID,
    MODELS,
    IdentifyResult,
    ModelFit,
    coefficients_for,
    fit_h,
    pooled_h_of_states,
)
from euc_ros.core.identify.interval import interval, json_float, turning_rms
from euc_ros.core.identify.simex import SimexShare, eiv_bias
from euc_ros.core.identify.sliding import sliding_bias
from euc_ros.core.model.terms import EucParams
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, RiderStates, reconstruct_states

#: Lowest and highest h the interval may reach [m] (the ends of the default grid).
H_BOUNDS = (0.1, 1.2)


@dataclass(frozen=True)
class HIdentification:
    """h with its interval, and everything ``euc-ros identify`` reports about it.

    Attributes
    ----------
    h : float
        The pooled 3-DoF h [m] (NaN without a valid sample).
    interval : tuple of float
        Its 95 % interval [m]: the block bootstrap's, widened to contain the bias-corrected h (NaN, NaN
        when the uncertainty was not computed; infinite ends when the data do not bound h).
    identifiable : bool or None
        Whether the data determine h (None when the uncertainty was not computed).
    reason : str
        Why not ("" when identifiable or not computed).
    model : str
        The model heading the JSON document (``3dof``, ``2dof`` or the extended model's name).
    fits : IdentifyResult
        Per-recording and pooled fits of every model, with their RMSE curves.
    uncertainty : dict or None
        The interval's details, JSON-ready (:func:`uncertainty_of_h`), or None.
    """

    h: float
    interval: tuple[float, float]
    identifiable: bool | None
    reason: str
    model: str
    fits: IdentifyResult
    uncertainty: dict | None

    def to_dict(self) -> dict:
        """The JSON document: the fits headed by :attr:`model`, then the uncertainty (when computed)."""
        data = self.fits.to_json(self.model)
        if self.uncertainty is not None:
            data["h_std_formal_m"] = data.get("h_std_m")
            data.update(self.uncertainty)
        return data

    def to_json(self) -> str:
        """:meth:`to_dict` as JSON text (indented, with a final newline)."""
        return json.dumps(self.to_dict(), indent=2) + "\n"


def identify_h(states: Sequence[RiderStates], session, params: EucParams | None = None, *,
               h_grid=DEFAULT_H_GRID, h_bounds: tuple[float, float] = H_BOUNDS, models: Sequence[str] = MODELS,
               effects: dict[str, dict[str, float]] | None = None, model: str | None = None,
               settings: dict | None = None, uncertainty: bool = True, with_budget: bool = True,
               sliding: bool = True, tolerances: dict | None = None, window_s: float = DEFAULT_WINDOW_S,
               polyorder: int = DEFAULT_SG_POLYORDER, phi_definition: str = "hinge", cog_method: str = "segments",
               simex_share: SimexShare | None = None, filter_choice=None) -> HIdentification:
    """Identify h from reconstructed recordings, with its interval.

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states, reconstructed with ``window_s``, ``polyorder``, ``phi_definition`` and
        ``cog_method``. The interval needs each recording's poses in ``states[i].meta["series"]``; without
        them the errors-in-variables biases and the budget are left out.
    session : Session
        The recordings' session (the budget perturbs its nominal values).
    params : EucParams, optional
        Nominal parameters (default: the session's).
    h_grid : array_like
        CoG heights of the grid search [m], increasing.
    h_bounds : tuple of float
        Lowest and highest h the bootstrap's grid may reach [m].
    models : sequence of {"3dof", "2dof"}
        The paper's models to fit (the interval needs ``3dof``).
    effects : dict, optional
        Effects of the residual analysis added to the 3-DoF model, ``{effect: {parameter: value}}`` in the
        residual report's units; h is then identified for that model too.
    model : str, optional
        The model heading the JSON document (default: the extended model with ``effects``, else ``3dof``).
    settings : dict, optional
        Stored in the fits (and the JSON).
    uncertainty : bool
        Compute the interval, identifiability and biases (the slow part).
    with_budget : bool
        Also the budget over the nominal values (re-identifies h once per value).
    sliding : bool
        Include the soft-tissue sliding's SIMEX bias in the interval.
    tolerances : dict, optional
        Tolerances of the nominal values for the budget (default :data:`~.budget.DEFAULT_TOLERANCES`).
    window_s, polyorder, phi_definition, cog_method
        How the states were reconstructed (the biases reconstruct the recordings again alike).
    simex_share : SimexShare, optional
        Holds SIMEX's first replicate when the residual's noise floor made it already.
    filter_choice : FilterChoice or WindowChoice, optional
        The filter chosen from the data (:func:`~euc_ros.core.states.filter_choice.choose_filter`)
        that ``window_s`` and ``polyorder`` come from; its ``probe`` gives the interval a floor for the
        distortion the filter leaves (:func:`filter_floor`). Without it (a fixed window) there is no
        such term.

    Returns
    -------
    HIdentification
    """
    params = EucParams.from_session(session) if params is None else params
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
    if not uncertainty or pooled3 is None:
        return HIdentification(h, (float("nan"), float("nan")), None, "", head, fits, None)
    unc = uncertainty_of_h(states, session, params, pooled3, window_s=window_s, polyorder=polyorder,
                           phi_definition=phi_definition, cog_method=cog_method, h_bounds=h_bounds,
                           sliding=sliding, tolerances=tolerances, with_budget=with_budget,
                           simex_share=simex_share, filter_choice=filter_choice)
    lo, hi = (float("nan") if v is None else float(v) for v in unc["h_ci95_m"])
    return HIdentification(h, (lo, hi), bool(unc["identifiable"]), unc["identifiability_reason"] or "", head, fits,
                           unc)


def uncertainty_of_h(states: Sequence[RiderStates], session, params: EucParams, fit: ModelFit, *, window_s: float,
                     polyorder: int, phi_definition: str = "hinge", cog_method: str = "segments",
                     h_bounds: tuple[float, float] = H_BOUNDS, sliding: bool = True, tolerances: dict | None = None,
                     with_budget: bool = True, simex_share: SimexShare | None = None, filter_choice=None) -> dict:
    """Interval, identifiability, errors-in-variables bias and budget of the pooled 3-DoF h (JSON-ready).

    ``fit`` is the pooled 3-DoF fit of ``states``; the other arguments are those of :func:`identify_h`.
    Returns the JSON document's keys ``h_ci95_m``, ``identifiable``, ``identifiability_reason``,
    ``uncertainty``, ``h_std_m`` and, with the budget, ``h_range_m`` and ``uncertainty_budget``.
    """
    tolerances = dict(DEFAULT_TOLERANCES) if tolerances is None else tolerances
    series = [st.meta.get("series") for st in states]
    out = {}
    bias = err = float("nan")
    if np.isfinite(fit.h_m) and all(s is not None for s in series):
        bias, err = eiv_bias(series, session, params, fit.h_m, window_s=window_s, polyorder=polyorder,
                             phi_definition=phi_definition, with_error=True, cog_method=cog_method,
                             share=simex_share)
    # soft-tissue sliding the chain's links show (docs/cog_artefacts.md): its SIMEX bias joins the
    # white-noise bias in the interval (0 when no sliding above MIN_SLIDING_M is seen)
    slide = None
    if np.isfinite(fit.h_m) and all(s is not None for s in series) and sliding:
        try:
            slide = sliding_bias(series, session, params, fit.h_m, window_s=window_s, polyorder=polyorder,
                                 phi_definition=phi_definition, cog_method=cog_method)
        except ConfigError:      # no chain link between the recorded bodies: no sliding measurable
            slide = None
    total, total_err = bias, err
    if slide is not None and np.isfinite(slide["sliding_bias_m"]) and slide["sliding_bias_m"] != 0.0:
        total = (bias if np.isfinite(bias) else 0.0) + slide["sliding_bias_m"]
        total_err = float(np.hypot(err if np.isfinite(err) else 0.0, slide["sliding_bias_err_m"]))
    floor = None
    if filter_choice is not None and np.isfinite(fit.h_m) and all(s is not None for s in series):
        floor = filter_floor(series, session, params, fit.h_m, filter_choice, phi_definition=phi_definition,
                             cog_method=cog_method)
    coefs = coefficients_for(states, params, "3dof", None)
    iv = interval(coefs, fit, window=states[0].window, dt=states[0].dt, eiv_bias_m=total, eiv_bias_err_m=total_err,
                  h_bounds=h_bounds, turning_ms2=turning_rms(states),
                  filter_floor_m=floor["filter_floor_m"] if floor else 0.0)
    del coefs                         # per-sample coefficients: not kept through the budget
    out.update(iv.to_json())
    if slide is not None:
        out["uncertainty"]["eiv_bias_m"] = json_float(bias)
        out["uncertainty"].update({k: json_float(v) for k, v in slide.items()})
    if floor is not None:
        out["uncertainty"].update({k: json_float(v) for k, v in floor.items()})
    lo, hi = iv.bootstrap_ci95_m
    out["h_std_m"] = float((hi - lo) / 3.92) if np.isfinite(lo) and np.isfinite(hi) else None
    if with_budget and np.isfinite(fit.h_m) and all(s is not None for s in series):
        b = budget(series, states, session, params, fit.h_m, window_s=window_s, polyorder=polyorder,
                   phi_definition=phi_definition, tolerances=tolerances, cog_method=cog_method)
        out["h_range_m"] = b["h_range_m"]
        out["uncertainty_budget"] = b
    return out


def filter_floor(series_list, session, params: EucParams, h: float, choice, *, phi_definition: str = "hinge",
                 cog_method: str = "segments") -> dict:
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
    w, p = choice.probe
    states = [reconstruct_states(s, session, phi_definition=phi_definition, window_s=float(w), polyorder=int(p),
                                 cog_method=cog_method) for s in series_list]
    h_probe = pooled_h_of_states(states, params)
    r = getattr(choice, "probe_ratio", float("nan"))
    r = float(r) if r is not None and np.isfinite(r) and r > 1.0 else 2.0
    d = h_probe - h
    return {"h_probe_m": h_probe, "filter_distortion_m": d,
            "filter_floor_m": abs(d) / (r - 1.0) if np.isfinite(d) else float("nan")}
