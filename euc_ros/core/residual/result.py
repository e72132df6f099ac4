"""What the residual analysis returns.

Per candidate (:class:`CandidateResult`) and as a whole (:class:`ResidualResult`, with its JSON form).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.model.extended import Model
from euc_ros.core.residual.interval import FinalInterval
from euc_ros.core.residual.selection import HeldOut
from euc_ros.core.states.floor import FloorFit


@dataclass
class CandidateResult:
    """One row of the candidate table.

    Parameters
    ----------
    effect : str
        The candidate's name.
    detectable : bool
        Whether its generalized force shows in the residual at all (:func:`~.selection.detectability`).
    visibility : float
        The visible fraction of its generalized force (0 to 1).
    rmse_after_nm : float
        Held-out RMSE with it added to the model of its step [N m] (the base model's when undetectable).
    p_value : float
        One-sided p-value of the paired block test against the model of its step (1 when undetectable, 0 for
        the floor's geometry).
    parameters : dict
        The fitted model's reported parameters (:meth:`Model.report <euc_ros.core.model.extended.Model.report>`).
    h_m : float
        The fitted h [m].
    inadmissible : str or None
        Why the fitted model cannot be selected (:func:`~.selection.admissibility`).
    p_adjusted : float or None
        The p-value adjusted over the step's candidates (max-T, :func:`~.significance.max_t_adjusted`).
    refused : str or None
        The line of its parameters outside their plausible range (:func:`~.selection.refusal`).
    """

    effect: str
    detectable: bool
    visibility: float
    rmse_after_nm: float
    p_value: float
    parameters: dict
    h_m: float
    inadmissible: str | None = None
    p_adjusted: float | None = None
    refused: str | None = None

    def to_dict(self) -> dict:
        """The candidate's JSON row.

        Returns
        -------
        dict
            The fields under their JSON keys (``effect_parameters`` for ``parameters``); ``inadmissible`` and
            ``refused`` only when set.
        """
        d = {"effect": self.effect, "rmse_after_nm": self.rmse_after_nm, "p_value": self.p_value,
             "p_adjusted": self.p_adjusted,
             "detectable": self.detectable, "visibility": self.visibility, "effect_parameters": self.parameters,
             "h_m": self.h_m}
        if self.inadmissible:
            d["inadmissible"] = self.inadmissible
        if self.refused:
            d["refused"] = self.refused
        return d


@dataclass
class ResidualResult:
    """Outcome of :func:`~.analysis.analyze`.

    Parameters
    ----------
    h_base : float
        The base model's h fitted on all samples [m].
    rmse_train_base : float
        Its RMSE on those samples [N m].
    rmse_before : float
        The base model's held-out RMSE [N m].
    rmse_after : float
        The final model's held-out RMSE [N m].
    effect : str
        The final model's effects joined by ``+`` (``none`` without one), with ``discovered`` or
        ``unexplained`` (:mod:`.names`).
    effect_parameters : dict
        The final model's reported parameters.
    h_after : float
        The final model's h [m].
    final_x : ndarray
        The final model's parameters ``[h, theta...]``.
    selected : list of str
        The final model's effects.
    candidates : list of CandidateResult
        The candidate table.
    steps : list of dict
        The selection steps' JSON records.
    alpha : float
        The significance level.
    min_gain : float
        The minimum relative cut of the held-out RMSE.
    folds : int
        Number of held-out folds.
    fold_kind : str
        How the folds and blocks were cut (text).
    base_heldout, final_heldout : HeldOut
        The base and the final model's held-out residuals.
    final_model : Model
        The final model.
    geometry : dict
        The floor and rolling-radius record (:func:`~.analysis.radius_step`).
    warnings : list of str
        The analysis' warnings.
    h_range : tuple of float
        Smallest and largest h of the final model and the models tied with a selected one [m].
    tied : list of dict
        The tied models' records (:meth:`~.records.Trial.tied_record`) of the steps that selected an effect.
    residual_significant : bool
        The residual shows structure: the discovery's test below ``alpha``, the named model's held-out RMSE
        above :data:`~.analysis.NOISE_FLOOR_FACTOR` noise floors, or a refused name left nothing named.
    unexplained : bool
        Significant with no discovered terms accepted.
    discovered : list of dict
        The accepted discovered terms.
    discovery : dict
        The discovery's JSON record.
    noise_floor_nm : float
        The residual's noise floor [N m] (NaN: not measured).
    residual_after_above_noise : bool or None
        The final held-out RMSE above :data:`~.analysis.NOISE_FLOOR_FACTOR` noise floors (None: no floor).
    floor_fit : FloorFit or None
        The floor measured from the contact path.
    block_s : float
        Block length of the paired test [s].
    refused : list of dict
        The refused names (:attr:`~.records.Journal.refused`).
    ties : list of dict
        Per step with more than one tied model: ``effects``, ``h_m``, ``tie`` and ``step_model``.
    final_interval : FinalInterval or None
        The final model's intervals.
    """

    h_base: float
    rmse_train_base: float
    rmse_before: float
    rmse_after: float
    effect: str
    effect_parameters: dict
    h_after: float
    final_x: np.ndarray
    selected: list[str]
    candidates: list[CandidateResult]
    steps: list[dict]
    alpha: float
    min_gain: float
    folds: int
    fold_kind: str
    base_heldout: HeldOut
    final_heldout: HeldOut
    final_model: Model
    geometry: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    h_range: tuple = (float("nan"), float("nan"))
    tied: list = field(default_factory=list)
    residual_significant: bool = False
    unexplained: bool = False
    discovered: list = field(default_factory=list)
    discovery: dict = field(default_factory=dict)
    noise_floor_nm: float = float("nan")
    residual_after_above_noise: bool | None = None
    floor_fit: FloorFit | None = None
    block_s: float = float("nan")
    refused: list = field(default_factory=list)
    ties: list = field(default_factory=list)
    final_interval: FinalInterval | None = None

    def to_json(self) -> dict:
        """The result's JSON document (docs/residual.md, JSON), with the analysis settings and steps.

        Returns
        -------
        dict
        """
        rows = sorted(self.candidates, key=lambda c: (not c.detectable, c.rmse_after_nm))
        table = [c.to_dict() for c in rows]
        if not any(c["effect"] == "none" for c in table):
            table.append({"effect": "none", "rmse_after_nm": self.rmse_before, "p_value": None, "detectable": True,
                          "effect_parameters": {}, "h_m": self.h_base})
            table.sort(key=lambda c: (not c["detectable"], c["rmse_after_nm"]))
        ambiguous = sorted({a for s in self.steps for a in s.get("ambiguous_with", [])})
        return {"h_m": self.h_base, "rmse_before_nm": self.rmse_before, "effect": self.effect,
                "effect_parameters": self.effect_parameters, "rmse_after_nm": self.rmse_after,
                "ambiguous_with": ambiguous,
                "h_after_m": self.h_after, "candidates": table, "selection_steps": self.steps,
                "significance_level": self.alpha, "min_relative_gain": self.min_gain,
                "held_out": {"folds": self.folds, "kind": self.fold_kind, "block_s": self.block_s},
                "geometry": self.geometry,
                "undetectable": [c.effect for c in self.candidates if not c.detectable],
                "h_range_m": [float(self.h_range[0]), float(self.h_range[1])], "tied_models": self.tied,
                "residual_significant": bool(self.residual_significant), "unexplained": bool(self.unexplained),
                "discovered": self.discovered, "discovery": self.discovery,
                "noise_floor_nm": None if not math.isfinite(self.noise_floor_nm) else self.noise_floor_nm,
                "residual_after_above_noise": self.residual_after_above_noise,
                "refused": list(self.refused), "ties": list(self.ties),
                "effect_is_tie": any(set(t["effects"]) & set(self.selected) for t in self.ties),
                "analysis_warnings": list(self.warnings),
                **(self.final_interval.to_json() if self.final_interval is not None else {})}
