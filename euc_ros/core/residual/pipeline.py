"""The residual analysis from files: session and recordings in, a result that knows its JSON out.

:func:`trace_residual` is what ``euc-ros residual``, :func:`euc_ros.residual` and the campaigns run:
read the recordings (:func:`~euc_ros.core.states.load.load_states`), measure what the rigid links show
(the rider-to-EUC time offset, the soft-tissue sliding) and the noise floor, give the base model's h its
interval (identify's), trace M_d1 - M_d2 to the candidate effects
(:func:`~euc_ros.core.residual.analysis.analyze`; with h held at the segments' geometric h where the data do
not bound it, :mod:`~euc_ros.core.identify.held`), widen and refit the final model's interval, and assemble
the analysis JSON of the recording format (with its ``inputs``, so the result is never applied to other data).

Examples
--------
>>> ResidualOptions().alpha, ResidualOptions().min_gain
(0.01, 0.1)
>>> ResidualOptions(alpha=1.5)
Traceback (most recent call last):
    ...
euc_ros.core.errors.ConfigError: key '--alpha': must be in (0, 1), got 1.5
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable, Sequence

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.cog_height import identify_h
from euc_ros.core.identify.held import HeldH
from euc_ros.core.identify.interval import MAX_CI_WIDTH_M, json_float
from euc_ros.core.identify.options import H_BOUNDS, IntervalOptions, Measured
from euc_ros.core.identify.pipeline import AnalysisRun, sliding_prior
from euc_ros.core.identify.session_prior import Combined, admissible_bounds, recombine
from euc_ros.core.identify.simex import SimexShare
from euc_ros.core.io.provenance import inputs_record
from euc_ros.core.model.effects import make_candidates
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.analysis import RESIDUAL_POLYORDER, RESIDUAL_WINDOW_S, analyze
from euc_ros.core.residual.discovery import GroupSparseDiscovery
from euc_ros.core.residual.interval import FinalInterval, base_widening, filter_refit
from euc_ros.core.residual.noise import make_noise_floor
from euc_ros.core.residual.result import ResidualResult
from euc_ros.core.residual.selector import DEFAULT_ALPHA, DEFAULT_MIN_GAIN, ForwardSelector
from euc_ros.core.residual.session_reference import session_tolerances
from euc_ros.core.session import load_session
from euc_ros.core.states.contexts import analysis_rate
from euc_ros.core.states.filter_choice import data_filters
from euc_ros.core.states.link_sliding import sliding_or_none, usable_poses
from euc_ros.core.states.load import cog_faults, collect_warnings, load_states, usage_table
from euc_ros.core.states.settings import ReconstructionSettings
from euc_ros.core.states.time_offset import measure_time_offset

#: The residual's reconstruction: a fixed window with less bias of the accelerations than identify's default.
RESIDUAL_SETTINGS = ReconstructionSettings(window_s=RESIDUAL_WINDOW_S, polyorder=RESIDUAL_POLYORDER)


@dataclass(frozen=True)
class ResidualOptions:
    """How the residual is traced: the library, the selection's thresholds, geometry and discovery.

    Parameters
    ----------
    candidates : sequence of str, optional
        Library effects to try (default: all).
    alpha : float
        Significance level of each selection step, in (0, 1).
    min_gain : float
        Minimum relative cut of the held-out RMSE to select an effect, in [0, 1).
    max_effects : int
        Most effects to select.
    use_geometry : bool
        Compare the wheel-centre height with the session's wheel radius (rolling radius, floor).
    discover : bool
        Run the discovery step for what no named effect explains.
    families : sequence of Family, optional
        The discovery's function families (default :data:`~euc_ros.core.residual.families.FAMILIES`).
    plausible : dict
        Plausible ranges of library parameters by ``"effect.parameter"`` instead of the library's.

    Raises
    ------
    ConfigError
        A threshold outside its range, naming the option.
    """

    candidates: Sequence[str] | None = None
    alpha: float = DEFAULT_ALPHA
    min_gain: float = DEFAULT_MIN_GAIN
    max_effects: int = 3
    use_geometry: bool = True
    discover: bool = True
    plausible: dict = field(default_factory=dict)
    families: Sequence | None = None

    def discovery(self):
        """The ``discovery`` argument of :func:`~euc_ros.core.residual.analysis.analyze` these options ask for.

        Returns
        -------
        GroupSparseDiscovery or bool
            A discovery over :attr:`families` when they are given, else :attr:`discover`.
        """
        if self.discover and self.families:
            return GroupSparseDiscovery(families=tuple(self.families))
        return self.discover

    def __post_init__(self) -> None:
        if not 0 < self.alpha < 1:
            raise ConfigError(f"must be in (0, 1), got {self.alpha}", key="--alpha")
        if not 0 <= self.min_gain < 1:
            raise ConfigError(f"must be in [0, 1), got {self.min_gain}", key="--min-gain")


@dataclass(frozen=True)
class ResidualRun(AnalysisRun):
    """A residual analysis' :class:`~euc_ros.core.identify.pipeline.AnalysisRun` with its result.

    Parameters
    ----------
    data : dict
        The residual JSON (the command's ``--json``).
    states : list of RiderStates
        The recordings' reconstructed states.
    params : EucParams
        The session's nominal parameters.
    result : ResidualResult or None
        The analysis' result.
    """

    result: ResidualResult | None = None


def final_identifiability(data: dict) -> dict:
    """Whether the data determine the final model's h (``h_after_m``).

    The final model's h is identifiable when its 95 % interval is bounded on both ends and no wider than
    identify's :data:`~euc_ros.core.identify.interval.MAX_CI_WIDTH_M`; without a final interval (nothing
    selected or discovered) the final model is the base model and its verdict is the base model's. A held h
    (``h_held``) is not identified by the data, whatever its interval.

    Parameters
    ----------
    data : dict
        The residual JSON so far (``h_after_ci95_m``, ``identifiable``, ...).

    Returns
    -------
    dict
        The JSON keys ``h_after_identifiable`` and ``h_after_identifiability_reason``.
    """
    ci = data.get("h_after_ci95_m")
    if data.get("h_held"):
        return {"h_after_identifiable": False,
                "h_after_identifiability_reason": f"h is held: {data['h_held']['reason']}"}
    if ci is None:
        return {"h_after_identifiable": bool(data.get("identifiable")),
                "h_after_identifiability_reason": data.get("identifiability_reason")}
    if None in ci:
        held = (data.get("h_after_uncertainty") or {}).get("widened_by") or []
        reason = "its 95 % interval is not bounded" + (f" (it holds {' and '.join(held)})" if held else "")
    elif ci[1] - ci[0] > MAX_CI_WIDTH_M:
        reason = (f"its 95 % interval is {100 * (ci[1] - ci[0]):.0f} cm wide (at most "
                  f"{100 * MAX_CI_WIDTH_M:.0f} cm for an identified h)")
    else:
        reason = None
    return {"h_after_identifiable": reason is None, "h_after_identifiability_reason": reason}


def held_keys(held: HeldH, final: FinalInterval | None) -> dict:
    """The JSON keys of a residual whose fits held h (:class:`~euc_ros.core.identify.held.HeldH`).

    ``h_m`` and ``h_after_m`` are the held h (no fit moved it); ``h_ci95_m`` and ``h_after_ci95_m`` are its Type B
    interval; ``effect_parameters_ci95`` are the final model's with h held; ``h_held`` says that h is held and
    why.

    Parameters
    ----------
    held : HeldH
    final : FinalInterval or None
        The final model's intervals (with h held, its own h has no statistical interval).

    Returns
    -------
    dict
    """
    ci = [float(v) for v in held.ci95_m]
    out = {"h_ci95_m": ci, "h_held": held.to_json()}
    if final is not None:
        out.update(final.to_json())
        out["h_after_ci95_m"] = ci
        out["h_after_uncertainty"].update(method="held at the segments' geometric h (Type B)",
                                          h_se_m=float(held.std_m), widened_by=[])
    return out


def with_geometric_after(data: dict, geometric: Combined | None, *, admissible=None) -> dict:
    """The final model's h and interval combined with the segments' geometric h, as identify's headline is.

    The final model's h from the data (``h_after_m``, ``h_after_ci95_m``) goes under
    ``diagnostics.h_after_combined`` (:meth:`~euc_ros.core.identify.session_prior.Combined.to_json`); the keys
    become the posterior median and interval (:func:`~euc_ros.core.identify.session_prior.recombine`), with the
    geometric h and its Type B uncertainty identify's combination used. A held h is left as it is (it is the
    geometric h).

    Parameters
    ----------
    data : dict
        The residual JSON so far.
    geometric : Combined or None
        identify's combination (None: nothing is combined).
    admissible : pair of float, optional
        The admissible range of h (identify's ``uncertainty.h_admissible_m``).

    Returns
    -------
    dict
        ``h_after_m``, ``h_after_ci95_m``, ``diagnostics`` and, when the two disagree, ``warnings``; empty when
        nothing is combined.
    """
    ci, h = data.get("h_after_ci95_m"), data.get("h_after_m")
    if geometric is None or data.get("h_held") or ci is None or h is None:
        return {}
    c = recombine(geometric, float(h), ci, bounds=admissible_bounds(H_BOUNDS, admissible))
    if c is None:
        return {}
    out = {"h_after_m": json_float(c.h_m), "h_after_ci95_m": [json_float(v) for v in c.ci95_m],
           "diagnostics": {**(data.get("diagnostics") or {}), "h_after_combined": c.to_json()}}
    if not c.consistent:
        out["warnings"] = list(data.get("warnings") or []) + [f"final model: {c.warning()}"]
    return out


def residual_filter(states: Sequence, settings: ReconstructionSettings) -> tuple:
    """The settings with the residual's filter fixed, and the choice behind it (None for a window in seconds).

    With the window ``auto`` the filter is the one :func:`~euc_ros.core.states.load.load_states` chose from the
    recordings' spectra (:func:`~euc_ros.core.states.filter_choice.choose_filter`, as identify chooses it;
    ``settings.filter_chosen`` in the JSON); the analysis, the noise floor included, then runs at that filter and
    at a sub-sample rate scaled with its passband (:func:`~euc_ros.core.states.contexts.analysis_rate`).

    Parameters
    ----------
    states : sequence of RiderStates
        The loaded recordings (their ``meta["filter"]``).
    settings : ReconstructionSettings

    Returns
    -------
    tuple
        ``(settings, FilterChoice or None)``.

    Raises
    ------
    ConfigError
        ``auto`` without a choice in the states.
    """
    chosen = states[0].meta.get("filter") if settings.is_auto and states else None
    if chosen is not None:
        settings = settings.with_filter(chosen.window_s, chosen.polyorder)
    if settings.is_auto:
        raise ConfigError("no filter could be chosen from the recordings; give a window in seconds", key="--window-s")
    return settings, chosen


def options_candidates(options: ResidualOptions, offset: dict | None) -> list:
    """The library candidates of ``options``, the time offset's plausible range bounded by its measurement.

    Parameters
    ----------
    options : ResidualOptions
        The library and the plausible ranges the user set.
    offset : dict or None
        The rider-to-EUC time offset measured from the ankles on the pedals (``plausible_ms``), or None.

    Returns
    -------
    list of Candidate
        :func:`~euc_ros.core.model.effects.make_candidates` with those ranges (a range the user set wins).
    """
    ranges = dict(options.plausible or {})
    if offset is not None and "mocap_time_offset.dt_ms" not in ranges:
        ranges["mocap_time_offset.dt_ms"] = tuple(offset["plausible_ms"])
    return make_candidates(options.candidates, ranges)


def trace_residual(session_path, recordings: Sequence, settings: ReconstructionSettings | None = None, *,
                   options: ResidualOptions | None = None, tolerances: dict | None = None,
                   sliding_prior_mm: float | None = None, progress: Callable[[Sequence], Iterable] | None = None,
                   say: Callable[[str], None] | None = None) -> ResidualRun:
    """Trace the M_d1 - M_d2 residual of recordings to a missing effect, as ``euc-ros residual`` does.

    Parameters
    ----------
    session_path : str or Path
        The session file.
    recordings : sequence of str or Path
        Motive CSV exports, bag directories or ``.mcap`` files.
    settings : ReconstructionSettings, optional
        The reconstruction (default :data:`RESIDUAL_SETTINGS`); the window may be ``auto``
        (:func:`residual_filter`).
    options : ResidualOptions, optional
        The library and the selection's thresholds (default: the command's).
    tolerances : dict, optional
        Tolerances of nominal session values: adds their h budget to the base model's uncertainty.
    sliding_prior_mm : float, optional
        RMS of the soft-tissue sliding all rider bodies share [mm].
    progress : callable, optional
        A progress display over the recordings.
    say : callable, optional
        Receives one line per analysis step.

    Returns
    -------
    ResidualRun

    Raises
    ------
    EucError
        A session or recording that cannot be read or used, a bad option.
    """
    settings = RESIDUAL_SETTINGS if settings is None else settings
    options = ResidualOptions() if options is None else options
    session = load_session(session_path)
    states = load_states(session, recordings, settings, progress=progress, keep_series=True)
    settings, chosen_filter = residual_filter(states, settings)
    rate_hz = analysis_rate(settings.window_s, settings.polyorder)
    params = EucParams.from_session(session)
    series = [st.meta.get("series") for st in states]
    # the poses the links can use; the time offset measured from the ankles on the pedals bounds the name
    # mocap_time_offset (unless the user set its range)
    usable = [usable_poses(s) for s in series] if all(s is not None for s in series) else None
    offset = measure_time_offset(series, session, usable) if usable is not None else None
    cands = options_candidates(options, offset)
    # what the rigid links show, measured once (the interval's sliding terms, the filter choice)
    links = sliding_or_none(series, session, usable) if usable is not None else None
    del usable
    # the recordings' pose-noise estimate is made once for the interval's SIMEX and the noise floor
    simex = SimexShare()
    noise_of = make_noise_floor(series, states, session, params, share=simex, analysis_rate_hz=rate_hz,
                                sliding=links) if all(s is not None for s in series) else None
    # how well the data determine the base model's h (identify's); unbounded: h held in every fit (.held)
    iv = IntervalOptions(sliding_prior=sliding_prior(sliding_prior_mm), with_budget=bool(tolerances),
                         tolerances=tolerances or None)
    ident = identify_h(states, session, params, reconstruction=settings, models=("3dof",), uncertainty=iv,
                       measured=Measured(simex_share=simex, link_sliding=links))
    base, held = ident.uncertainty, ident.held
    session_free = session_tolerances(held.h_m if held is not None else ident.h, tolerances)
    result = analyze(states, params, candidates=cands,
                     selector=ForwardSelector(options.alpha, options.min_gain, options.max_effects, session_free),
                     discovery=options.discovery(), use_geometry=options.use_geometry, noise_floor_of=noise_of,
                     analysis_rate_hz=rate_hz, progress=say, h_held=None if held is None else held.h_m)
    data = result.to_json()
    for k in ("h_ci95_m", "identifiable", "identifiability_reason"):
        data.setdefault(k, base[k])
    if held is not None:
        data.update(held_keys(held, result.final_interval))
    elif result.final_interval is not None:
        final = result.final_interval.widened(*base_widening(base))
        if settings.cog_method == "segments" and all(s is not None for s in series):
            chosen, probe, ratio = data_filters(series, session, settings.phi_definition, sliding=links)
            final = filter_refit(final, result.final_model, result.final_x, chosen, params, probe_states=probe,
                                 probe_ratio=ratio, floor=result.floor_fit, block_s=result.block_s)
        data.update(final.to_json())
    data["uncertainty"] = base["uncertainty"]
    data["noise_floor_parts_nm"] = dict(noise_of.parts) if noise_of is not None and noise_of.parts else None
    if tolerances:   # what the stated tolerances of nominal values do to the base model's h
        data["uncertainty_budget"] = base.get("uncertainty_budget")
        data["h_range_for_tolerances_m"] = base.get("h_range_m")
    data["recordings"] = [st.name for st in states]
    data["per_recording"] = usage_table(states)
    data["warnings"] = collect_warnings(states)
    data["settings"] = {"session": str(session_path), "window_s": settings.window_s, "polyorder": settings.polyorder,
                        "candidates": [c.name for c in cands], "cog_method": settings.cog_method,
                        **({"filter_chosen": chosen_filter.to_json()} if chosen_filter is not None else {})}
    if settings.phi_definition != "hinge":
        data["settings"]["phi_definition"] = settings.phi_definition
    if options.plausible:
        data["settings"]["plausible"] = {k: list(v) for k, v in options.plausible.items()}
    data["time_offset_measured"] = offset
    data["cog"] = cog_faults(states)
    data.update(final_identifiability(data))        # the data's verdict, before the geometric h joins
    data.update(with_geometric_after(data, ident.combined, admissible=(base.get("uncertainty") or {}).get(
        "h_admissible_m")))
    data["inputs"] = inputs_record(session_path, recordings)
    return ResidualRun(data=data, states=states, params=params, result=result)
