"""The short Python API: ``euc_ros.identify`` and ``euc_ros.residual``, what the commands compute.

Each returns a result whose :attr:`~Result.data` is the command's JSON document, key for key and number
for number (the commands call the same functions), with the main numbers as attributes.

Examples
--------
>>> import tempfile, euc_ros
>>> from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
>>> from euc_ros.core.ridesim.writers import write_ride
>>> folder = tempfile.mkdtemp()
>>> _ = write_ride(simulate_ride(RideConfig(runs=1, seed=1, duration_s=6.0)), folder)
>>> fit = euc_ros.identify(f"{folder}/session.yaml", [f"{folder}/deceleration_01.csv"])
>>> 0.5 < fit.h < 0.7 and fit.interval[0] <= fit.h <= fit.interval[1]
True
>>> fit.data["h_m"] == fit.h and fit.data["h_ci95_m"] == list(fit.interval)
True
>>> fit.to_json().startswith('{')
True
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence


@dataclass(frozen=True)
class Result:
    """What an analysis command reports.

    Attributes
    ----------
    h : float
        The rider CoG height of the reported model [m] (``h_m`` of the JSON; for ``residual`` the base
        3-DoF model's, with :attr:`h_after` the selected model's).
    interval : tuple of float
        h's 95 % interval [m] (``h_ci95_m``; NaN ends when it was not computed).
    data : dict
        The command's JSON document.
    """

    h: float
    interval: tuple[float, float]
    data: dict = field(repr=False)

    def to_json(self) -> str:
        """The JSON text the command writes with ``--json``."""
        return json.dumps(self.data, indent=2) + "\n"


@dataclass(frozen=True)
class ResidualResult(Result):
    """What ``residual`` reports; besides :class:`Result`: the selected effect, its h and the held-out RMSEs."""

    effect: str = "none"
    h_after: float = float("nan")
    rmse_before: float = float("nan")
    rmse_after: float = float("nan")


def _interval(data: dict) -> tuple[float, float]:
    ci = data.get("h_ci95_m") or [None, None]
    return tuple(float("nan") if v is None else float(v) for v in ci)


def identify(session: str | Path, recordings: Sequence[str | Path], **options) -> Result:
    """Identify h as ``euc-ros identify`` does.

    Parameters
    ----------
    session : str or Path
        Session file.
    recordings : sequence of str or Path
        Motive CSV exports, bag folders or ``.mcap`` files.
    **options
        The command's options by their Python names: ``window_s``, ``polyorder``, ``phi_definition``,
        ``cog_method``, ``h_min``, ``h_max``, ``h_step``, ``effects`` (``{name: {parameter: value}}``),
        ``model``, ``uncertainty``, ``sliding``, ``tolerances``, ``sliding_prior_mm``.
    """
    from euc_ros.cli.identify import run_identify

    _, data, _, _ = run_identify(str(session), [str(r) for r in recordings], **options)
    return Result(float(data["h_m"]), _interval(data), data)


def residual(session: str | Path, recordings: Sequence[str | Path], **options) -> ResidualResult:
    """Trace the M_d1 - M_d2 residual as ``euc-ros residual`` does.

    Parameters
    ----------
    session, recordings
        As for :func:`identify`.
    **options
        ``candidates``, ``alpha``, ``min_gain``, ``max_effects``, ``use_geometry``, ``discover``,
        ``window_s``, ``polyorder``, ``cog_method``, ``phi_definition``, ``tolerances``, ``sliding_prior_mm``.
    """
    from euc_ros.cli.residual import run_residual

    _, data, _, _ = run_residual(str(session), [str(r) for r in recordings], **options)
    return ResidualResult(float(data["h_m"]), _interval(data), data, effect=data["effect"],
                          h_after=float(data["h_after_m"]), rmse_before=float(data["rmse_before_nm"]),
                          rmse_after=float(data["rmse_after_nm"]))
