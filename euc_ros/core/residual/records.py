"""The records that pass between the steps of the residual analysis (:func:`~.analysis.analyze`).

The prepared data (:class:`Setup`), where the selection stands (:class:`Stage`), a candidate tried (:class:`Trial`), the
selection's and the discovery's outcomes, and the :class:`Journal` of what the steps report.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.model.candidate import Candidate
from euc_ros.core.model.extended import Model
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.folds import Fold
from euc_ros.core.residual.result import CandidateResult
from euc_ros.core.residual.selection import Fit, HeldOut
from euc_ros.core.states.contexts import Recording
from euc_ros.core.states.floor import FloorFit


@dataclass(frozen=True)
class Setup:
    """What every step works on: the prepared recordings, their folds and blocks, the base model's fit.

    Parameters
    ----------
    params : EucParams
        Nominal parameters.
    floor : FloorFit or None
        The floor measured from the contact path (None without geometry).
    recs : list of Recording
        The recordings prepared for the analysis, with the blocks of the paired test.
    folds : list of Fold
        The held-out folds (:func:`~.folds.folds_of`).
    n_segments : int
        Segments per run of the folds.
    block_s : float
        Block length of the paired test [s].
    h_geo : float
        The segments' geometric h [m] (:func:`~euc_ros.core.identify.held.geometric_h`).
    h0 : float
        The base model's h on a grid, the start of every fit [m].
    base_fit : Fit
        The base model fitted on all samples.
    """

    params: EucParams
    floor: FloorFit | None
    recs: list[Recording]
    folds: list[Fold]
    n_segments: int
    block_s: float
    h_geo: float
    h0: float
    base_fit: Fit


@dataclass(frozen=True)
class Screening:
    """Each candidate's detectability (its force's projection on w, relative) and the detectable ones.

    Parameters
    ----------
    visible : dict of str to float
        Candidate name -> the visible fraction of its generalized force (:func:`~.selection.detectability`).
    detectable : list of Candidate
        The candidates visible above :data:`~.selection.DETECTABILITY_TOL`.
    """

    visible: dict[str, float]
    detectable: list[Candidate]


@dataclass(frozen=True, eq=False)
class Stage:
    """Where the selection stands: a model, its held-out residual and its fitted parameters.

    Parameters
    ----------
    model : Model
        The model (the base model and its effects).
    heldout : HeldOut
        Its held-out residual over the folds.
    x : ndarray
        Its parameters ``[h, theta...]`` fitted on all samples (h [m]).
    """

    model: Model
    heldout: HeldOut
    x: np.ndarray


@dataclass(frozen=True, eq=False)
class Trial:
    """One candidate added to the current model: fitted, held out, tested against the current model.

    Parameters
    ----------
    candidate : Candidate
        The candidate tried.
    model : Model
        The current model with the candidate added.
    heldout : HeldOut
        That model's held-out residual.
    p_value : float
        One-sided p-value that it cuts the current model's held-out residual
        (:func:`~.significance.paired_block_test`, not adjusted).
    fit : Fit
        That model fitted on all samples.
    inadmissible : str or None
        Why the fitted model cannot be selected (:func:`~.selection.admissibility`); None: admissible.
    refused : tuple of dict
        The fitted parameters outside their plausible range (:func:`~.selection.plausibility`); empty: plausible.
    """

    candidate: Candidate
    model: Model
    heldout: HeldOut
    p_value: float
    fit: Fit
    inadmissible: str | None
    refused: tuple[dict, ...] = ()

    @property
    def usable(self) -> bool:
        """Admissible and plausible: the trial may be named (or tied with the named one)."""
        return self.inadmissible is None and not self.refused

    def tied_record(self, why: str = "selected") -> dict:
        """The JSON record of a tied candidate.

        Parameters
        ----------
        why : str
            Why it is listed: ``selected``, ``held-out`` or ``confounded``.

        Returns
        -------
        dict
            ``effect``, ``h_m`` [m], ``rmse_after_nm`` (held out) [N m], ``effect_parameters`` and ``tie``.
        """
        return {"effect": self.candidate.name, "h_m": self.fit.h, "rmse_after_nm": self.heldout.rmse,
                "effect_parameters": self.model.report(self.fit.x), "tie": why}


@dataclass(frozen=True, eq=False)
class LastStep:
    """The last selection step: the model it started from and its trials (the named alternatives to discovery).

    Parameters
    ----------
    model : Model
        The model the step started from.
    trials : tuple of Trial
        Each remaining candidate added to it.
    """

    model: Model
    trials: tuple[Trial, ...]


@dataclass(frozen=True)
class Selection:
    """Where the greedy selection of named effects ended, and its last step.

    Parameters
    ----------
    stage : Stage
        The stage reached.
    last : LastStep or None
        The last step tried (None when no step was tried).
    stand_in : dict
        ``id`` of a stage judged against the session's tolerances -> the stage it stands in for (the model
        reported, with its own held-out residual).
    """

    stage: Stage
    last: LastStep | None
    stand_in: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Alternative:
    """After the discovered alternative to the named effects: the stage, and the alternative's JSON record.

    Parameters
    ----------
    stage : Stage
        The named stage, or the geometric effects alone when the alternative explains significantly more.
    record : dict
        The alternative's JSON record (empty when there was none to compare).
    """

    stage: Stage
    record: dict


@dataclass(frozen=True)
class DiscoveryOutcome:
    """After the discovery step: the final stage, the named one before discovered terms, what was found.

    Parameters
    ----------
    stage : Stage
        The final model (with the discovered terms when they were accepted).
    named : Stage
        The model of named effects (the noise floor's model).
    info : dict
        The discovery's JSON record.
    rows : list of dict
        The accepted discovered terms (empty when none).
    p_value : float
        The structure test's p-value (1 when not run, when the discovered terms cut the held-out RMSE by less
        than the minimum gain, or when a named effect explains the structure).
    """

    stage: Stage
    named: Stage
    info: dict
    rows: list[dict]
    p_value: float


@dataclass(frozen=True)
class Journal:
    """What the steps report as they go: per-candidate rows, the selection steps (JSON records), warnings.

    Parameters
    ----------
    rows : dict of str to CandidateResult
        Candidate name -> its row of the candidate table.
    steps : list of dict
        The selection steps' JSON records, in order.
    warnings : list of str
        Warnings for the result.
    refused : list of dict
        The refused names: the records of :func:`~.selection.plausibility` with the trial's ``rmse_after_nm``,
        ``h_m``, ``model`` and ``text``.
    """

    rows: dict[str, CandidateResult] = field(default_factory=dict)
    steps: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    refused: list[dict] = field(default_factory=list)
