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
    """One row of the candidate table."""

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
        """JSON row."""
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
    """Outcome of :func:`analyze`."""

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
        """JSON per docs/residual.md, JSON (plus the analysis settings and steps)."""
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
