"""The model an analysis found, read from its JSON, to be applied to other data or to a live run.

``euc-ros residual --json`` and ``euc-ros identify --json`` write the h to use and, for an extended
model, its effects with their parameters. :func:`read_model_file` reads either into an
:class:`AppliedModel`: the one artefact between the offline analysis and the live
``torque_estimator`` (``model:=residual.json``) or ``identify --from-residual``. The file's ``inputs``
(:mod:`euc_ros.core.io.provenance`) say what data it belongs to; :meth:`AppliedModel.check` refuses
another session or other recordings.

A residual JSON gives the final model's h (``h_after_m``) and its named effects. What the offline
model has that cannot be evaluated from one state at a time is listed in
:attr:`AppliedModel.left_out`: the discovery's terms (functions fitted on those recordings) and a
measured floor that is not flat.

Examples
--------
>>> model = model_from_json({"effect": "ground_slope", "effect_parameters": {"alpha_deg": 2.5},
...                          "h_m": 0.29, "h_after_m": 0.6}, "residual.json")
>>> model.name, model.h_m, model.assignments()
('3dof+ground_slope', 0.6, ['ground_slope.alpha_deg=2.5'])
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.io.provenance import check_inputs
from euc_ros.core.model.effects import LIBRARY

#: Outcome words of the residual's ``effect`` that name no library effect.
_OUTCOMES = ("none", "discovered", "unexplained")


@dataclass(frozen=True)
class AppliedModel:
    """h and the effects of an analysis result, with where they came from.

    Parameters
    ----------
    h_m : float
        The rider CoG height of this model [m] (a residual's final model's ``h_after_m``, an identify
        result's ``h_m``).
    effects : dict
        ``{effect: {parameter: value}}`` in the residual report's names and units (empty: the 3-DoF model).
    path : str
        The JSON file read.
    kind : {"residual", "identify"}
        Which command wrote it.
    inputs : dict or None
        Its ``inputs`` block (session and recordings with their hashes), None when it has none.
    base_h_m : float or None
        The base 3-DoF model's h of a residual result [m] (what the effects are compared against).
    left_out : tuple of str
        What the offline model holds that a model of named effects cannot (discovered terms, a measured
        floor), one line each.
    identifiable : bool or None
        The result's verdict on its h (None: not stated).
    """

    h_m: float
    effects: dict = field(default_factory=dict)
    path: str = ""
    kind: str = "residual"
    inputs: dict | None = None
    base_h_m: float | None = None
    left_out: tuple[str, ...] = ()
    identifiable: bool | None = None

    @property
    def name(self) -> str:
        """``"3dof"`` or ``"3dof+<effect>+..."``, as the extended model names itself."""
        return "+".join(["3dof", *self.effects])

    def assignments(self) -> list[str]:
        """The effects' parameters as ``torque_estimator``'s ``effect_parameters`` (``effect.param=value``).

        Returns
        -------
        list of str
            One ``effect.param=value`` item per parameter (empty for the 3-DoF model).
        """
        return [f"{e}.{k}={v!r}" for e, values in self.effects.items() for k, v in values.items()]

    def check(self, *, session: str | Path | None = None, recordings: Sequence[str | Path] | None = None,
              force: bool = False, force_option: str = "--force") -> list[str]:
        """Refuse a session or recordings the result was not made from (:func:`.provenance.check_inputs`).

        Parameters
        ----------
        session : str or Path, optional
            Session file it is applied with.
        recordings : sequence of str or Path, optional
            Recordings it is applied to (a live run has none).
        force : bool
            Return the mismatches as warnings instead of raising.
        force_option : str
            How the user says ``force``, named in the messages.

        Returns
        -------
        list of str
            Warnings (mismatches under ``force``).

        Raises
        ------
        InputMismatch
            The first mismatch, naming this file.
        """
        return check_inputs(self.inputs, session=session, recordings=recordings, source=self.path, force=force,
                            force_option=force_option)


def effects_of(effect: str, parameters: dict, *, path: str = "", key: str = "effect_parameters") -> dict:
    """Split a result's flat ``effect_parameters`` among the library effects its ``effect`` names.

    Parameters
    ----------
    effect : str
        The result's ``effect`` (names joined by ``+``; ``none``, ``discovered``, ``unexplained`` name none).
    parameters : dict
        ``{parameter: value}`` of all of them, as the JSON holds them.
    path, key : str
        Named in errors.

    Returns
    -------
    dict
        ``{effect: {parameter: value}}``, each effect with the parameters its library entry reports.

    Raises
    ------
    InputError
        An effect the library does not know, or one whose parameter is missing.
    """
    out: dict[str, dict[str, float]] = {}
    for name in (n.strip() for n in str(effect).split("+")):
        if not name or name in _OUTCOMES:
            continue
        if name not in LIBRARY:
            raise InputError(f"unknown effect {name!r} (the library: {', '.join(LIBRARY)})", path=path, key="effect")
        cand = LIBRARY[name]()
        reported = cand.report(np.array([q.start for q in cand.params], float))
        values = {}
        for k in reported:
            if k not in parameters:
                raise InputError(f"effect {name} needs its parameter {k!r}", path=path, key=f"{key}.{k}")
            values[k] = float(parameters[k])
        out[name] = values
    return out


def _number(data: dict, key: str, path: str) -> float:
    v = data.get(key)
    if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
        raise InputError(f"expected a finite number, got {v!r}", path=path, key=key)
    return float(v)


def model_from_json(data: dict, path: str | Path = "") -> AppliedModel:
    """The :class:`AppliedModel` of a parsed ``residual`` or ``identify`` JSON document.

    Parameters
    ----------
    data : dict
        The document.
    path : str or Path
        Its file, named in errors.

    Returns
    -------
    AppliedModel

    Raises
    ------
    InputError
        Neither a residual nor an identify result, or a key it needs is missing or not a number.
    """
    path = str(path)
    if not isinstance(data, dict):
        raise InputError("expected a JSON object written by 'euc-ros residual' or 'euc-ros identify'", path=path)
    inputs = data.get("inputs") if isinstance(data.get("inputs"), dict) else None
    identifiable = data.get("identifiable") if isinstance(data.get("identifiable"), bool) else None
    if "effect" in data:      # residual
        flat = data.get("effect_parameters", {})
        if not isinstance(data.get("effect"), str) or not isinstance(flat, dict):
            raise InputError("expected a string 'effect' and a mapping 'effect_parameters'", path=path, key="effect")
        effects = effects_of(data["effect"], flat, path=path)
        left = [f"{d.get('name', 'discovered')}: {d.get('formula', '')}".strip() for d in data.get("discovered") or []
                if isinstance(d, dict)]
        if not left and "discovered" in (n.strip() for n in data["effect"].split("+")):
            left.append("the discovered terms")
        floor = (data.get("geometry") or {}).get("floor") if isinstance(data.get("geometry"), dict) else None
        if isinstance(floor, dict) and floor.get("flat") is False:
            left.append("the floor measured from the wheel's contact path (not flat)")
        h_key = "h_after_m" if "h_after_m" in data else "h_m"
        return AppliedModel(_number(data, h_key, path), effects, path, "residual", inputs,
                            _number(data, "h_m", path), tuple(left), identifiable)
    if "model" in data and "h_m" in data:   # identify
        settings = data.get("settings") if isinstance(data.get("settings"), dict) else {}
        effects = settings.get("effects") or {}
        if not isinstance(effects, dict):
            raise InputError("expected a mapping of effects to their parameters", path=path, key="settings.effects")
        return AppliedModel(_number(data, "h_m", path), {str(e): {str(k): float(v) for k, v in p.items()}
                                                        for e, p in effects.items()},
                            path, "identify", inputs, None, (), identifiable)
    raise InputError("expected the JSON of 'euc-ros residual' (effect, h_m, h_after_m) or of "
                     "'euc-ros identify' (model, h_m)", path=path)


def read_model_file(path: str | Path) -> AppliedModel:
    """Read a ``residual`` or ``identify`` JSON file into an :class:`AppliedModel`.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    AppliedModel

    Raises
    ------
    InputError
        The file cannot be read, is not JSON (line and column named) or not an analysis result.
    """
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read the model file: {exc.strerror}", path=path) from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", path=path, line=exc.lineno, column=exc.colno) from None
    return model_from_json(data, path)
