"""Reading recordings into states for the offline analyses (identify, residual): one path for both.

:func:`load_states` reads every recording, checks it against the session, chooses the filter from the
data when asked, reconstructs the states and says what it left out; :func:`usage_table`,
:func:`cog_faults` and :func:`collect_warnings` are what the analyses' JSON reports of it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable, Iterable, Sequence

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.filters.derivatives import DEFAULT_MAX_GAP
from euc_ros.core.io.recordings import load_recording, recording_kind
from euc_ros.core.mocap.checks import check_recording
from euc_ros.core.mocap.duplicates import TakeIndex
from euc_ros.core.states.settings import ReconstructionSettings


def load_states(session, paths: Sequence, settings: ReconstructionSettings | None = None, *,
                progress: Callable[[Sequence], Iterable] | None = None, keep_series: bool = False) -> list:
    """Read recordings, check them against the session and reconstruct their states.

    With ``settings.window_s == "auto"`` the filter is chosen from the recordings' own spectra
    (:func:`euc_ros.core.states.filter_choice.choose_filter`) after all are read and before any is
    reconstructed; the :class:`~euc_ros.core.states.filter_choice.FilterChoice` is kept in every state's
    ``meta["filter"]``.

    Every recording is first checked by :func:`euc_ros.core.mocap.checks.check_recording`; its warnings are
    kept in ``states.meta["warnings"]`` (see :func:`collect_warnings`). A recording without a single usable
    state is left out, said in the first state's ``meta["skipped"]``; with none usable the read is refused
    (an :class:`~euc_ros.core.errors.InputError` naming the first); so is a recording holding the same take as
    an earlier one (:class:`~euc_ros.core.mocap.duplicates.TakeIndex`). Names are made unique. With
    ``cog_method="skeleton"`` the chain's link vectors are estimated once from all recordings (one
    session) before any state is reconstructed.

    Parameters
    ----------
    session : Session
        The recordings' session.
    paths : sequence of str or Path
        Motive CSV exports, bag directories or ``.mcap`` files.
    settings : ReconstructionSettings, optional
        The filter (or ``"auto"``), the pitch definition and the CoG method (default: all defaults).
    progress : callable, optional
        Wraps the sequence of paths in a progress display (a ``tqdm``, say) and returns an iterable of it.
    keep_series : bool
        Keep each recording's poses in ``meta["series"]`` (the interval and the noise floor need them).

    Returns
    -------
    list of RiderStates
        One per usable recording, in the order given.

    Raises
    ------
    InputError
        A path that is not a recording, a recording that does not fit the session, or no usable state
        in any recording.
    """
    from euc_ros.core.memory import release_free_memory
    from euc_ros.core.states.kinematics import reconstruct_states

    settings = ReconstructionSettings() if settings is None else settings
    window_s, polyorder = settings.window_s, settings.polyorder
    phi_definition, cog_method = settings.phi_definition, settings.cog_method

    if not paths:
        raise InputError("no recording given: pass at least one Motive CSV export, bag folder or .mcap file",
                         key="recordings")
    for path in paths:
        recording_kind(path)  # fail early, before any long read
    skeleton = None
    if cog_method == "skeleton":
        from euc_ros.core.states.skeleton import SkeletonModel

        skeleton = SkeletonModel.estimate([load_recording(p, session.world_up) for p in paths], session)
    auto = settings.is_auto
    states = []
    bar = paths if progress is None else progress(paths)
    choice = None
    twins: list[tuple] = []         # (path, why): takes given twice, left out
    unusable: list[tuple] = []      # (path, why): takes without a usable state, left out
    takes = TakeIndex()

    def twice(path, series) -> bool:
        # one take given twice (a CSV and the bag converted from it) would count double: the second is left out
        other = takes.same_as(series, Path(path).stem)
        if other is not None:
            twins.append((path, f"the same take as {other} (equal frames and poses)"))
        return other is not None

    if auto:
        bar, choice = _read_and_choose_filter(session, bar, twice, settings, skeleton)
        window_s, polyorder = choice.window_s, choice.polyorder
    for item in bar:
        path, series = item if auto else (item, load_recording(item, session.world_up))
        if not auto and twice(path, series):
            continue
        warnings = check_recording(series, session, path)
        st = reconstruct_states(series, session, phi_definition=phi_definition, window_s=window_s,
                                polyorder=polyorder, cog_method=cog_method, skeleton=skeleton)
        if not st.valid.any():
            # one recording with nothing usable (a short run the filter's window does not fit between its gaps)
            # is left out and said; with nothing usable in any, the run is refused
            unusable.append((path, unusable_why(st, series)))
            continue
        _annotate_state(st, path, series, warnings, choice, keep_series)
        states.append(st)
    if not states:
        raise InputError(unusable[0][1], path=unusable[0][0])
    states[0].meta["skipped"] = [(Path(path).stem, why) for path, why in twins + unusable]
    _make_names_unique(states)
    release_free_memory()           # the readers' and the reconstruction's temporaries
    return states


def _read_and_choose_filter(session, paths, twice: Callable, settings: ReconstructionSettings, skeleton):
    """Read every recording (the takes given twice left out), then choose the filter from all of them.

    Returns ``(pairs, choice)``: the ``(path, series)`` kept and the
    :class:`~euc_ros.core.states.filter_choice.FilterChoice`.
    """
    from euc_ros.core.states.filter_choice import choose_filter
    from euc_ros.core.states.kinematics import reconstruct_states

    phi_definition, cog_method = settings.phi_definition, settings.cog_method
    pairs = [(path, load_recording(path, session.world_up)) for path in paths]
    pairs = [(path, series) for path, series in pairs if not twice(path, series)]
    try:
        choice = choose_filter([s for _, s in pairs], session, phi_definition=phi_definition)
    except InputError:
        # a recording's own fault (a missing body, nothing tracked) is named by its reconstruction
        for path, series in pairs:
            check_recording(series, session, path)
            reconstruct_states(series, session, phi_definition=phi_definition, cog_method=cog_method,
                               skeleton=skeleton)
        raise
    return pairs, choice


def _annotate_state(st, path, series, warnings: list, choice, keep_series: bool) -> None:
    """Name a usable recording's states; keep in its ``meta`` the filter, the poses, the samples used, the warnings."""
    st.name = st.name or Path(path).stem
    if choice is not None:
        st.meta["filter"] = choice
    if keep_series:
        # kept for the interval and the noise floor, which use the poses only: the marker errors
        # (an eighth of the recording's bytes at 14 bodies) are dropped for the rest of the run
        series.mean_marker_error = np.broadcast_to(np.float64(np.nan), series.tracked.shape)
        st.meta["series"] = series
    used = samples_used(st)
    st.meta["samples"] = used
    if used["samples_used_fraction"] < LOW_USE_FRACTION:
        warnings.append(f"only {used['samples_used']} of {used['frames']} frames "
                        f"({100 * used['samples_used_fraction']:.0f} %) give usable states (bodies lost for "
                        f"more than max_gap frames, or stretches shorter than the filter window)")
    st.meta.setdefault("warnings", []).extend(warnings)


def _make_names_unique(states: list) -> None:
    """Number repeated names (``name#2``, ...) for the report."""
    seen: dict[str, int] = {}
    for st in states:
        k = seen.get(st.name, 0)
        seen[st.name] = k + 1
        if k:
            st.name = f"{st.name}#{k + 1}"


def unusable_why(st, series) -> str:
    """Why a recording gives no usable state, and what would help.

    Parameters
    ----------
    st : RiderStates
        Its states (none valid).
    series : MocapSeries
        Its poses.

    Returns
    -------
    str
        One sentence naming the cause and the options that would help.
    """
    dt = st.dt if np.isfinite(st.dt) and st.dt > 0 else 1.0 / float(series.rate_hz)
    window_s = st.window * dt if st.window else float("nan")
    span_s = float(series.t[-1] - series.t[0]) if np.size(series.t) > 1 else 0.0
    where = (f"the take lasts {span_s:.2f} s, less than the filter's {window_s:.2f} s window" if span_s < window_s else
             f"bodies lost for more than {DEFAULT_MAX_GAP} frames leave no stretch as long as the filter's "
             f"{window_s:.2f} s window")
    return (f"no frame with the EUC and every rider segment tracked long enough to differentiate ({where}; a shorter "
            f"--window-s, or a longer take)")


#: Below this fraction of a recording's frames used, the analysis warns.
LOW_USE_FRACTION = 0.5


def samples_used(st) -> dict:
    """How much of a recording the analysis uses.

    ``frames`` (its frame span, dropped frames included), ``samples_used`` (valid states),
    ``samples_used_fraction``, ``bridged_frames`` (frames with a body bridged across a short gap).

    Parameters
    ----------
    st : RiderStates
        The recording's states.

    Returns
    -------
    dict
        The four counts.
    """
    frames = int(st.frame[-1] - st.frame[0] + 1) if st.n else 0
    used = int(st.valid.sum())
    return {"frames": frames, "samples_used": used,
            "samples_used_fraction": used / frames if frames else 0.0,
            "bridged_frames": int(st.meta.get("bridged_frames", 0))}


def usage_table(states) -> list[dict]:
    """Per recording: name plus :func:`samples_used`.

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states (``meta["samples"]`` when :func:`load_states` kept it).

    Returns
    -------
    list of dict
        One row per recording: ``recording`` and the counts of :func:`samples_used`.
    """
    return [{"recording": st.name, **st.meta.get("samples", samples_used(st))} for st in states]


def cog_faults(states) -> dict:
    """The CoG method and the rider body-frames it excluded from G (swaps, flips), JSON-ready.

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states.

    Returns
    -------
    dict
        ``cog_method``, ``excluded_body_frames`` (total), ``per_recording`` and ``per_body`` counts.
    """
    per_body: dict[str, int] = {}
    for st in states:
        for nm, c in st.meta.get("cog_fault_bodies", {}).items():
            per_body[nm] = per_body.get(nm, 0) + int(c)
    return {"cog_method": states[0].cog_method if states else "segments",
            "excluded_body_frames": int(sum(st.meta.get("cog_faults", 0) for st in states)),
            "per_recording": {st.name: int(st.meta.get("cog_faults", 0)) for st in states},
            "per_body": per_body}


#: A rider body excluded from G in more than this share of a recording's frames is worth a warning.
EXCLUDED_WARN_SHARE = 0.05


def collect_warnings(states) -> list[str]:
    """Return every recording's warnings, each prefixed with the recording's name.

    Besides the warnings of the reading, every exclusion that changes G is said with its count: a rider
    body the fitted skeleton excluded in more than :data:`EXCLUDED_WARN_SHARE` of the frames, and bodies
    the skeleton's chain does not know (their poses are used as measured, without swap or flip checks).

    Parameters
    ----------
    states : sequence of RiderStates
        The recordings' states.

    Returns
    -------
    list of str
        The warnings, the recordings left out (``skipped``) first.
    """
    out = [f"{name}: skipped: {why}" for st in states for name, why in st.meta.get("skipped", [])]
    out += [f"{st.name}: {w}" for st in states for w in st.meta.get("warnings", [])]
    for st in states:
        n = max(int(np.size(st.t)), 1)
        for body, count in sorted(st.meta.get("cog_fault_bodies", {}).items()):
            if count > EXCLUDED_WARN_SHARE * n:
                out.append(f"{st.name}: rider body {body} excluded from the CoG in {count} of {n} frames "
                           f"({100 * count / n:.0f} %): its pivot or orientation disagrees with the fitted skeleton "
                           "(a swapped or flipped body, or a session offset that does not fit it)")
        unlinked = st.meta.get("cog_unlinked_bodies")
        if unlinked:
            out.append(f"{st.name}: the skeleton's chain has no link for {', '.join(unlinked)}: used as measured, "
                       "without swap or flip checks (the chain knows the contract's body names H, CHR, CHL, UAR, "
                       "UAL, LAR, LAL, HR, HL, TR, TL, LR, LL)")
    return out
