"""The identification of h from files: session and recordings in, a result that knows its JSON out.

:func:`identify_recordings` is what ``euc-ros identify``, :func:`euc_ros.identify` and the campaigns run:
read and check the recordings (:func:`~euc_ros.core.states.load.load_states`), choose the filter from
the data, identify h with its interval (:func:`~euc_ros.core.identify.cog_height.identify_h`) and
assemble the analysis JSON of the recording format (with its ``inputs``, so the result is never applied
to other data).

Examples
--------
>>> grid = HGrid(0.3, 0.9, 0.1)
>>> grid.values().round(3).tolist()
[0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9]
>>> HGrid(0.9, 0.3)
Traceback (most recent call last):
    ...
euc_ros.core.errors.ConfigError: key '--h-min': need 0 < h-min < h-max, got 0.9 and 0.3
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.budget import parse_tolerances
from euc_ros.core.identify.cog_height import HIdentification, identify_h
from euc_ros.core.identify.options import IntervalOptions
from euc_ros.core.identify.sliding_prior import SlidingPrior
from euc_ros.core.io.provenance import inputs_record
from euc_ros.core.model.extended import Model
from euc_ros.core.model.terms import EucParams
from euc_ros.core.session import load_session
from euc_ros.core.states.load import cog_faults, collect_warnings, load_states, usage_table
from euc_ros.core.states.settings import ReconstructionSettings


@dataclass(frozen=True)
class HGrid:
    """The grid of h the RMSE curves are evaluated on.

    Parameters
    ----------
    min_m, max_m : float
        Smallest and largest h [m] (also the ends the interval's bootstrap may reach).
    step_m : float
        Step [m].

    Raises
    ------
    ConfigError
        Not finite, not ``0 < min_m < max_m``, or a step that is not positive or longer than half the range,
        naming the command-line option.
    """

    min_m: float = 0.1
    max_m: float = 1.2
    step_m: float = 0.005

    def __post_init__(self) -> None:
        for name, v in (("--h-min", self.min_m), ("--h-max", self.max_m), ("--h-step", self.step_m)):
            if not np.isfinite(v):
                raise ConfigError(f"must be a finite number, got {v}", key=name)
        if not 0 < self.min_m < self.max_m:
            raise ConfigError(f"need 0 < h-min < h-max, got {self.min_m} and {self.max_m}", key="--h-min")
        if not 0 < self.step_m <= (self.max_m - self.min_m) / 2:
            raise ConfigError(f"must be > 0 and at most half the range, got {self.step_m}", key="--h-step")

    def values(self) -> np.ndarray:
        """The grid's h values [m], from ``min_m`` up to ``max_m`` (inclusive when a whole number of steps).

        Returns
        -------
        numpy.ndarray
        """
        n = int(np.floor((self.max_m - self.min_m) / self.step_m + 1e-9)) + 1
        return self.min_m + self.step_m * np.arange(n)


def sliding_prior(mm: float | None) -> SlidingPrior:
    """The :class:`~euc_ros.core.identify.sliding_prior.SlidingPrior` of ``--sliding-prior-mm``.

    Parameters
    ----------
    mm : float or None
        RMS of the sliding all rider bodies share [mm]; None: as large as the links show.

    Returns
    -------
    SlidingPrior
    """
    return SlidingPrior(rms_m=None if mm is None else float(mm) * 1e-3)


def worse_fit_warnings(fits) -> list[str]:
    """A warning when an extended model fits the recordings worse than the 3-DoF model it extends.

    Both are fitted on the same states, each at its own best h; an effect that belongs to the data
    lowers the RMSE, so a higher one says the effect (or its parameters) came from other data.

    Parameters
    ----------
    fits : IdentifyResult
        The fits of :func:`~euc_ros.core.identify.cog_height.identify_h`.

    Returns
    -------
    list of str
        One warning, or none.
    """
    name = fits.settings.get("extended_model")
    ext, base = fits.pooled.get(name), fits.pooled.get("3dof")
    if name is None or ext is None or base is None or not ext.rmse_nm > base.rmse_nm:
        return []
    return [f"the extended model {name} fits these recordings worse than the 3-DoF model without its effects "
            f"(RMSE of M_d1 - M_d2 {ext.rmse_nm:.3f} against {base.rmse_nm:.3f} N m, each at its best h): the "
            "effect's parameters do not describe these recordings; do not use its h"]


@dataclass(frozen=True)
class AnalysisRun:
    """What one analysis of files made: its JSON document, the states and the parameters.

    Parameters
    ----------
    data : dict
        The analysis JSON (the command's ``--json``).
    states : list of RiderStates
        The recordings' reconstructed states.
    params : EucParams
        The session's nominal parameters.
    """

    data: dict
    states: list
    params: EucParams

    def to_json(self) -> str:
        """The JSON text, indented, with a final newline.

        Returns
        -------
        str
        """
        return json.dumps(self.data, indent=2) + "\n"


@dataclass(frozen=True)
class IdentifyRun(AnalysisRun):
    """An identification's :class:`AnalysisRun` with its result.

    Parameters
    ----------
    data : dict
        The identification JSON (the command's ``--json``).
    states : list of RiderStates
        The recordings' reconstructed states.
    params : EucParams
        The session's nominal parameters.
    identification : HIdentification or None
        The headline h with its interval and fits.
    """

    identification: HIdentification | None = None


def identify_recordings(session_path, recordings: Sequence, settings: ReconstructionSettings | None = None, *,
                        grid: HGrid | None = None, effects: dict | None = None, model: str | None = None,
                        uncertainty: bool = True, sliding: bool = True, tolerances: dict | None = None,
                        sliding_prior_mm: float | None = None,
                        progress: Callable[[Sequence], Iterable] | None = None) -> IdentifyRun:
    """Identify h from a session file and recordings, as ``euc-ros identify`` does.

    Parameters
    ----------
    session_path : str or Path
        The session file.
    recordings : sequence of str or Path
        Motive CSV exports, bag directories or ``.mcap`` files.
    settings : ReconstructionSettings, optional
        The filter (default ``"auto"``: chosen from the recordings; the document's ``filter`` key and the
        interval's floor for the filter's distortion), the pitch definition and the CoG method.
    grid : HGrid, optional
        The h grid (default 0.1-1.2 m in 5 mm steps).
    effects : dict, optional
        ``{effect: {parameter: value}}`` extending the 3-DoF model (the JSON is then headed by it).
    model : str, optional
        The model heading the JSON (default: the extended model with ``effects``, else ``3dof``).
    uncertainty : bool
        Compute the interval, identifiability, biases and budget.
    sliding : bool
        Include the soft-tissue sliding's bias in the interval.
    tolerances : dict, optional
        Tolerances of the nominal values for the budget (default: the budget's).
    sliding_prior_mm : float, optional
        RMS of the sliding all rider bodies share [mm] (:func:`sliding_prior`).
    progress : callable, optional
        A progress display over the recordings (:func:`~euc_ros.core.states.load.load_states`).

    Returns
    -------
    IdentifyRun

    Raises
    ------
    EucError
        A session or recording that cannot be read or used, an unknown effect or a missing parameter
        (before any long read), a bad grid.
    """
    settings = ReconstructionSettings() if settings is None else settings
    grid = HGrid() if grid is None else grid
    h_values = grid.values()
    effects = dict(effects or {})
    session = load_session(session_path)
    params = EucParams.from_session(session)
    if effects:
        Model.from_report(params, effects)  # unknown effects and missing parameters fail before any long read
    states = load_states(session, recordings, settings, progress=progress, keep_series=uncertainty)
    choice = states[0].meta.get("filter")
    if choice is not None:
        settings = settings.with_filter(choice.window_s, choice.polyorder)
    record = {"session": str(session_path), "recordings": [str(p) for p in recordings],
              "phi_definition": settings.phi_definition, "cog_method": settings.cog_method,
              "window_s": settings.window_s, "window_samples": states[0].window, "polyorder": settings.polyorder,
              "h_grid": {"min_m": float(h_values[0]), "max_m": float(h_values[-1]), "step_m": grid.step_m},
              "gravity_m_per_s2": float(params.g)}
    options = IntervalOptions(h_bounds=(grid.min_m, grid.max_m), sliding=sliding,
                              sliding_prior=sliding_prior(sliding_prior_mm),
                              tolerances=tolerances if tolerances is not None else parse_tolerances([]))
    ident = identify_h(states, session, params, reconstruction=settings, filter_choice=choice, h_grid=h_values,
                       effects=effects, model=model, settings=record, uncertainty=options if uncertainty else None)
    data = ident.to_dict()
    if choice is not None:
        data["filter"] = choice.to_json()
    usage = {u["recording"]: u for u in usage_table(states)}
    for rec in data.get("per_recording", []):
        rec.update({k: v for k, v in usage.get(rec["recording"], {}).items() if k != "recording"})
    data["cog"] = cog_faults(states)
    data["warnings"] = collect_warnings(states) + worse_fit_warnings(ident.fits)
    data["inputs"] = inputs_record(session_path, recordings)
    return IdentifyRun(data=data, states=states, params=params, identification=ident)
