"""The short Python API: ``euc_ros.identify`` and ``euc_ros.residual``, what the commands compute.

Each returns a result whose :attr:`~Result.data` is the command's JSON document, key for key and number
for number (the commands call the same functions), with the main numbers as attributes: the headline
``h`` (the one to give ``torque_estimator``), its ``interval``, and whether the data determine it
(``identifiable``, with the ``reason`` when not). A result that is not identifiable, or an extended
model that fits worse than the base model, is also a Python warning, so it is not missed in a script.

Examples
--------
>>> import tempfile, euc_ros
>>> from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
>>> from euc_ros.core.ridesim.writers import write_ride
>>> folder = tempfile.mkdtemp()
>>> _ = write_ride(simulate_ride(RideConfig(runs=1, seed=1, duration_s=6.0)), folder)
>>> import warnings
>>> with warnings.catch_warnings(record=True) as caught:
...     warnings.simplefilter("always")
...     fit = euc_ros.identify(f"{folder}/session.yaml", f"{folder}/deceleration_01.csv")
>>> fit.identifiable, fit.reason.startswith("too few independent blocks")
(False, True)
>>> [w.category.__name__ for w in caught]
['NotIdentifiableWarning']
>>> fit.data["h_m"] == fit.h and fit.data["h_ci95_m"] == [None if v != v else v for v in fit.interval]
True
>>> fit.to_json().startswith('{')
True
"""
from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence


class NotIdentifiableWarning(UserWarning):
    """The data do not determine h: the result's ``h`` is a best fit, not a value to use."""


class ModelFitWarning(UserWarning):
    """An extended model fits the data worse than the model it extends (its effects came from other data)."""


@dataclass(frozen=True)
class Result:
    """What an analysis command reports.

    Attributes
    ----------
    h : float
        The headline rider CoG height [m]: the one to give ``torque_estimator`` (``h_m`` of identify's
        JSON; the final model's ``h_after_m`` for ``residual``).
    interval : tuple of float
        The 95 % interval of ``h`` [m] (NaN for an end the data do not bound or that was not computed).
    identifiable : bool
        Whether the data determine ``h``; when False, ``h`` is only the best fit: do not use it.
    reason : str
        Why ``h`` is not identifiable, in the ride's numbers ("" when it is).
    data : dict
        The command's JSON document.
    """

    h: float
    interval: tuple[float, float]
    identifiable: bool
    reason: str
    data: dict = field(repr=False)

    def to_json(self) -> str:
        """The JSON text the command writes with ``--json``.

        Returns
        -------
        str
            Indented JSON with a final newline.
        """
        return json.dumps(self.data, indent=2) + "\n"


@dataclass(frozen=True)
class ResidualResult(Result):
    """What ``residual`` reports.

    Besides :class:`Result` (whose ``h`` is the final model's):

    Attributes
    ----------
    effect : str
        The selected effect(s), ``"none"``, or with ``+discovered`` / ``+unexplained``.
    h_base : float
        The base 3-DoF model's h [m] (``h_m`` of the JSON), with ``interval_base`` its interval.
    interval_base : tuple of float
    rmse_before, rmse_after : float
        Held-out RMSE of M_d1 - M_d2 before and after [N m].
    """

    effect: str = "none"
    h_base: float = float("nan")
    interval_base: tuple[float, float] = (float("nan"), float("nan"))
    rmse_before: float = float("nan")
    rmse_after: float = float("nan")

    @property
    def h_after(self) -> float:
        """The final model's h [m] (the same as :attr:`h`)."""
        return self.h


def _pair(ci) -> tuple[float, float]:
    ci = ci or [None, None]
    return tuple(float("nan") if v is None else float(v) for v in ci)


def _paths(recordings: str | os.PathLike | Sequence[str | os.PathLike]) -> list[str]:
    """One path or a sequence of paths, as strings (a single string is one path, not its characters)."""
    if isinstance(recordings, (str, os.PathLike)):
        return [os.fspath(recordings)]
    out = [os.fspath(r) for r in recordings]
    if not out:
        from euc_ros.core.errors import ConfigError

        raise ConfigError("no recording given", key="recordings")
    return out


def _settings(options: dict, default=None):
    """The reconstruction options as :class:`~euc_ros.core.states.settings.ReconstructionSettings`, and the rest."""
    from dataclasses import replace

    from euc_ros.core.states.settings import ReconstructionSettings

    keys = ("window_s", "polyorder", "phi_definition", "cog_method")
    given = {k: options[k] for k in keys if k in options}
    rest = {k: v for k, v in options.items() if k not in keys}
    if default is None:
        return ReconstructionSettings(**given), rest
    if "window_s" in given and "polyorder" not in given:
        given["polyorder"] = None if given["window_s"] == "auto" else default.polyorder
    return replace(default, **given), rest


def _warn(identifiable: bool, reason: str, h: float, what: str, notes: Sequence[str] = ()) -> None:
    if not identifiable:
        warnings.warn(f"{what} is NOT identifiable from these recordings: {reason} (best fit {h:.3f} m: do not "
                      "use it as h)", NotIdentifiableWarning, stacklevel=3)
    for note in notes:
        warnings.warn(note, ModelFitWarning, stacklevel=3)


def identify(session: str | Path, recordings: str | Path | Sequence[str | Path], *,
             from_residual: str | Path | None = None, force: bool = False, **options) -> Result:
    """Identify the rider CoG height h as ``euc-ros identify`` does.

    Parameters
    ----------
    session : str or Path
        Session file.
    recordings : str, Path or sequence of them
        Motive CSV exports, bag folders or ``.mcap`` files (one path, or several).
    from_residual : str or Path, optional
        A ``residual`` JSON whose selected effects extend the 3-DoF model (``--from-residual``). It must
        have been made from this session and these recordings (its ``inputs``), or ``force``.
    force : bool
        Apply ``from_residual`` to data it was not made from (the mismatch becomes a warning).
    **options
        The command's options by their Python names: ``window_s``, ``polyorder``, ``phi_definition``,
        ``cog_method``, ``h_min``, ``h_max``, ``h_step``, ``effects`` (``{name: {parameter: value}}``),
        ``model``, ``uncertainty``, ``sliding``, ``tolerances``, ``sliding_prior_mm``.

    Returns
    -------
    Result
        ``h`` (the JSON's ``h_m``), ``interval``, ``identifiable`` and ``reason``, and ``data``, the JSON.

    Warns
    -----
    NotIdentifiableWarning
        When the data do not determine h.
    ModelFitWarning
        When the extended model fits the recordings worse than the 3-DoF model.

    Raises
    ------
    euc_ros.core.errors.EucError
        Bad input: a file that cannot be read, a session error, a residual JSON made from other data.

    Examples
    --------
    A ride of the simulator (two decelerations, known truth h = 0.61 m):

    >>> import tempfile, euc_ros
    >>> from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    >>> from euc_ros.core.ridesim.writers import write_ride
    >>> folder = tempfile.mkdtemp()
    >>> _ = write_ride(simulate_ride(RideConfig(runs=2, seed=0)), folder)
    >>> fit = euc_ros.identify(f"{folder}/session.yaml", [f"{folder}/deceleration_01.csv",
    ...                                                    f"{folder}/deceleration_02.csv"])
    >>> fit.identifiable, fit.reason
    (True, '')
    >>> lo, hi = fit.interval
    >>> lo <= fit.h <= hi and lo < 0.61 < hi
    True
    """
    from euc_ros.core.identify.pipeline import HGrid, identify_recordings, worse_fit_warnings

    recs = _paths(recordings)
    effects = dict(options.pop("effects", None) or {})
    if from_residual is not None:
        from euc_ros.core.identify.model_file import read_model_file

        applied = read_model_file(from_residual)
        for line in applied.check(session=session, recordings=recs, force=force):
            warnings.warn(line, ModelFitWarning, stacklevel=2)
        effects = {**applied.effects, **effects}
    settings, rest = _settings(options)
    options_of_grid = {"h_min": "min_m", "h_max": "max_m", "h_step": "step_m"}
    grid = HGrid(**{field: rest.pop(option) for option, field in options_of_grid.items() if option in rest})
    run = identify_recordings(os.fspath(session), recs, settings, grid=grid, effects=effects, **rest)
    data = run.data
    ci = _pair(data.get("h_ci95_m"))
    ok = bool(data.get("identifiable", True))
    reason = data.get("identifiability_reason") or ""
    _warn(ok, reason, float(data["h_m"]), "h", worse_fit_warnings(run.identification.fits))
    return Result(float(data["h_m"]), ci, ok, reason, data)


def residual(session: str | Path, recordings: str | Path | Sequence[str | Path], **options) -> ResidualResult:
    """Trace the M_d1 - M_d2 residual as ``euc-ros residual`` does.

    Parameters
    ----------
    session : str or Path
        Session file.
    recordings : str, Path or sequence of them
        As for :func:`identify`.
    **options
        ``candidates``, ``alpha``, ``min_gain``, ``max_effects``, ``use_geometry``, ``discover``,
        ``window_s``, ``polyorder``, ``cog_method``, ``phi_definition``, ``tolerances``, ``sliding_prior_mm``.

    Returns
    -------
    ResidualResult
        ``h`` is the final model's h (``h_after_m``) with its ``interval`` and ``identifiable``; the
        base model's are ``h_base`` and ``interval_base``; ``effect``, ``rmse_before``, ``rmse_after``;
        ``data``, the JSON (whose ``inputs`` let ``identify(from_residual=...)`` and the live pipeline's
        ``model:=`` check the data they are applied to).

    Warns
    -----
    NotIdentifiableWarning
        When the data do not determine the final model's h.

    Examples
    --------
    A ride of the simulator with a rolling resistance nobody declared. Its runs all go one way, where a rolling
    resistance is a constant torque, as a CoM offset error is: the session's CoM offsets measured to 2 mm
    (their default tolerance, 1 cm, would explain this residual, and nothing would be named):

    >>> import tempfile, warnings, euc_ros
    >>> from euc_ros.core.ridesim.effects import EffectSet
    >>> from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    >>> from euc_ros.core.ridesim.writers import write_ride
    >>> folder = tempfile.mkdtemp()
    >>> rolling = EffectSet({"rolling_resistance": {"c_rr": 0.02}})
    >>> ride = simulate_ride(RideConfig(runs=2, seed=3, effects=rolling))
    >>> _ = write_ride(ride, folder)
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     res = euc_ros.residual(f"{folder}/session.yaml", [f"{folder}/deceleration_01.csv",
    ...                                                       f"{folder}/deceleration_02.csv"],
    ...                            tolerances={"rider.segments.com_offset": 0.002})
    >>> res.effect, res.rmse_after < 0.5 * res.rmse_before
    ('rolling_resistance', True)
    >>> res.h == res.data["h_after_m"], isinstance(res.identifiable, bool)
    (True, True)
    """
    from euc_ros.core.residual.pipeline import RESIDUAL_SETTINGS, ResidualOptions, trace_residual

    settings, rest = _settings(options, RESIDUAL_SETTINGS)
    analysis = ResidualOptions(**{k: rest.pop(k) for k in ("candidates", "alpha", "min_gain", "max_effects",
                                                            "use_geometry", "discover", "plausible") if k in rest})
    data = trace_residual(os.fspath(session), _paths(recordings), settings, options=analysis, **rest).data
    h = float(data.get("h_after_m", data["h_m"]))
    ci = _pair(data.get("h_after_ci95_m") if data.get("h_after_ci95_m") is not None else data.get("h_ci95_m"))
    ok = bool(data.get("h_after_identifiable", data.get("identifiable", True)))
    reason = data.get("h_after_identifiability_reason", data.get("identifiability_reason")) or ""
    _warn(ok, reason, h, "the final model's h")
    return ResidualResult(h, ci, ok, reason, data, effect=data["effect"], h_base=float(data["h_m"]),
                          interval_base=_pair(data.get("h_ci95_m")), rmse_before=float(data["rmse_before_nm"]),
                          rmse_after=float(data["rmse_after_nm"]))


__all__ = ["ModelFitWarning", "NotIdentifiableWarning", "Result", "ResidualResult", "identify", "residual"]
