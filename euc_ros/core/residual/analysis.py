"""Close the loop: fit candidate effects to the residual M_d1 - M_d2, select by held-out error.

:func:`analyze` runs the steps in order, each a function of this module or of an object it is given (the
selection of named effects, a :class:`~.selector.Selector`; the discovery, a :class:`~.discovery.Discovery`):

1. :func:`prepare_setup`: identify h with the paper's 3-DoF model, prepare the recordings, cut the
   held-out folds and the blocks of the paired test;
2. :func:`screen_candidates`: each candidate's detectability (is its generalized force in
   span(b_d, b_h)?);
3. :func:`floor_geometry_step`: a floor tilted or uneven in the mocap frame goes into the model as
   geometry, before any dynamic candidate;
4. :meth:`Selector.select <.selector.Selector.select>` (default :class:`~.selector.ForwardSelector`): fit
   each detectable candidate's parameters jointly with h on training data and evaluate on held-out data
   (other runs, or other segments of a single run); select by held-out error with a one-sided paired test
   over blocks (family-wise over the candidates: max-T) and a minimum relative gain; repeat greedily until
   nothing significant remains. A fit outside its parameter's plausible range is refused as a name;
   candidates the data cannot tell from the selected one (held out, or confounded in shape) are its ties;
5. :func:`radius_step`: a rolling radius measured on a flat floor is a wheel_radius_error by geometry;
6. :func:`discovery_alternative` and :func:`discovery_step`: the discovery (default
   :class:`~.discovery.GroupSparseDiscovery`: group-sparse forces from function families) for what the named
   effects leave, against and after them;
7. :func:`conclude`: the noise floor, the h range of the tied models and the result.

What passes between the steps are the frozen records of :mod:`.records` (:class:`~.records.Setup`,
:class:`~.records.Stage`, :class:`~.records.Trial`...); a :class:`~.records.Journal` collects what the steps
report as they go.

The residual of a model is ``M_d1 - M_d2 = R m11 (w . (M q_ddot + h - Q_g - dQ)) / D``
(:mod:`euc_ros.core.model.torque`), so an extra force with ``w . dQ = 0`` cannot change it.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable, Sequence

import numpy as np

from euc_ros.core.identify.held import geometric_h
from euc_ros.core.model.candidate import Candidate
from euc_ros.core.model.effects import FloorGeometry, MocapTimeOffset, make_candidates, with_plausible
from euc_ros.core.model.extended import HELD_H
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.discovery import Discovery, GroupSparseDiscovery
from euc_ros.core.residual.folds import (
    MIN_BLOCK_WINDOWS,
    MIN_FOLDS,
    TREND_WINDOWS,
    folds_of,
    residual_block_length,
    with_blocks,
)
from euc_ros.core.residual.interval import final_interval, sandwich_covariance
from euc_ros.core.residual.names_beside import names_beside_discovery
from euc_ros.core.residual.records import (
    Alternative,
    DiscoveryOutcome,
    Journal,
    LastStep,
    Screening,
    Setup,
    Stage,
    Trial,
)
from euc_ros.core.residual.result import CandidateResult, ResidualResult
from euc_ros.core.residual.selection import (
    DETECTABILITY_TOL,
    HeldOut,
    Model,
    admissibility,
    common_samples,
    detectability,
    fit_base_h,
    fit_model,
    h_freed,
    held_out,
)
from euc_ros.core.residual.selector import ForwardSelector, Selector, holds_without_any_recording
from euc_ros.core.residual.session_reference import session_reference
from euc_ros.core.residual.significance import AMBIGUITY_ALPHA, paired_block_test
from euc_ros.core.states.contexts import ANALYSIS_RATE_HZ, DEFAULT_BLOCK_S, forget_shift_caches, prepare
from euc_ros.core.states.floor import RADIUS_TOL_M, floor_from_states, rolling_radius_from_floor
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, RiderStates

#: Savitzky-Golay settings of the residual analysis: the project defaults (measured: with a 0.9 s
#: quartic the attenuation of the accelerations inflated inertia-type parameters, rider mass by
#: +25-30 %; 1.2 s / order 6 keeps the noise floor with less bias, rider mass within 15 %).
RESIDUAL_WINDOW_S = DEFAULT_WINDOW_S
RESIDUAL_POLYORDER = DEFAULT_SG_POLYORDER
#: The residual is above its noise floor when its held-out RMSE exceeds this many noise floors. The floor
#: is one realisation of the white pose noise propagated (within 3 % of the true noise contribution on a
#: simulated ride, test_noise.py); on no-effect rides the held-out RMSE is 0.9x it at 120 Hz and 1.1x at
#: 360 Hz (filter bias, 3-D reconstruction): 1.5x leaves ~4 standard errors of that ratio on 3 runs of 7 s
#: (~30 blocks). A factor of 3 would report swinging arms at 1.8 floors as `none` ("at the noise floor");
#: coloured noise the floor does not see is then `unexplained`, which is what it is.
NOISE_FLOOR_FACTOR = 1.5



# ------------------------------------------------------------------------------------------------ the driver
def analyze(states: Sequence[RiderStates], params: EucParams, *, candidates: Sequence[Candidate] | None = None,
            selector: Selector | None = None, discovery: Discovery | bool | None = True,
            n_folds: int | None = None, use_geometry: bool = True,
            noise_floor_of: Callable[[Model, np.ndarray], float] | None = None,
            analysis_rate_hz: float | None = ANALYSIS_RATE_HZ, plausible: dict | None = None,
            progress: Callable[[str], None] | None = None, h_held: float | None = None) -> ResidualResult:
    """Trace the residual M_d1 - M_d2 of ``states`` to the candidate effects.

    By default, greedy forward selection then group-sparse discovery.

    Parameters
    ----------
    states : sequence of RiderStates
        Reconstructed recordings (phi about the hinge for the time-offset candidate).
    params : EucParams
        Nominal parameters (``h`` is identified).
    candidates : sequence of Candidate, optional
        The library (default: all of :data:`~euc_ros.core.model.effects.LIBRARY`).
    selector : Selector, optional
        The selection of named effects; its ``alpha`` and ``min_gain`` are also the discovery's test
        (default: :class:`~.selector.ForwardSelector` with its defaults: a family-wise level of
        :data:`~.selector.DEFAULT_ALPHA` per step, a minimum relative gain of
        :data:`~.selector.DEFAULT_MIN_GAIN`, at most 3 effects).
    discovery : Discovery, bool or None
        What looks for structure the named effects leave, after them: a :class:`~.discovery.Discovery`;
        True (default): :class:`~.discovery.GroupSparseDiscovery` with its defaults; None or False: no
        discovery.
    n_folds : int, optional
        Segments per run of the held-out folds (default: enough for :data:`~.folds.MIN_FOLDS` folds).
    use_geometry : bool
        Measure the floor from the wheel's contact path: a floor tilted or uneven in the mocap frame goes
        into the model as geometry; a flat one may measure the rolling radius.
    noise_floor_of : callable, optional
        ``(model, x) -> RMS [N m]``: the residual's noise floor for a fitted model (the recordings' pose
        noise propagated, :func:`euc_ros.core.residual.noise.noise_floor`); without it the significance
        of the residual rests on the held-out test of the discovery step alone.
    analysis_rate_hz : float or None
        Work on a sub-sample at about this rate (:func:`~.data.decimation_step`); None: every sample.
    plausible : dict, optional
        Plausible ranges that replace the library's, ``"effect.parameter" -> (low, high)``
        (:func:`~euc_ros.core.model.effects.with_plausible`). A named effect whose fit leaves its plausible
        range is refused as a name (reported in ``refused``): the discovered terms, or ``unexplained``.
    progress : callable, optional
        Called with a line of text at each step.
    h_held : float, optional
        h held fixed [m] in every fit (:data:`~euc_ros.core.model.extended.HELD_H`), for recordings whose data
        do not bound h (:func:`~euc_ros.core.identify.held.held_h`); the selection and the discovery then
        start from :func:`free_h_reference`. None: h is fitted jointly.

    Returns
    -------
    ResidualResult
    """
    say = progress or (lambda _m: None)
    rules = selector if selector is not None else ForwardSelector()
    finder = GroupSparseDiscovery() if discovery is True else discovery or None
    candidates = with_plausible(list(candidates) if candidates is not None else make_candidates(), plausible or {})
    setup = prepare_setup(states, params, n_folds=n_folds, use_geometry=use_geometry,
                          analysis_rate_hz=analysis_rate_hz, say=say, h_held=h_held)
    screening = screen_candidates(candidates, setup, say)
    journal = Journal()
    base = base_stage(setup)
    stage = floor_geometry_step(setup, base, journal, say)
    reference = free_h_reference(setup, base, say) if h_held is not None and stage is base else None
    # the references stand in for the stage they judge: a final model that is one is that stage
    stand_in = {id(reference): base} if reference is not None else {}
    stage = reference or stage
    # the session reference stands in for the stage it judged as the final model, but its residual is the one
    # the noise floor judges: what the session's tolerances explain is not missing physics
    judged, stage = stage, session_start(setup, stage, rules, journal, say)
    session_stand_in = {id(stage): stand_in.get(id(judged), judged)} if stage is not judged else {}
    remaining = [c for c in screening.detectable if c.name not in {e.name for e in stage.model.effects}]
    selection = rules.select(setup, stage, remaining, screening, journal, say)
    for c in candidates:
        if c not in screening.detectable:
            journal.rows[c.name] = CandidateResult(c.name, False, screening.visible[c.name], base.heldout.rmse, 1.0,
                                                   {}, setup.base_fit.h)
    geometry, stage = radius_step(setup, candidates, selection.stage, use_geometry, journal, say)
    if not any(c.name == MocapTimeOffset.name for c in stage.model.effects):
        forget_shift_caches(setup.recs)     # no time offset fitted from here on: its hook's geometry let go
    alternative = Alternative(stage, {})
    if finder is not None and any(not getattr(c, "geometric", False) for c in stage.model.effects):
        # named and discovered alternatives compared on their own held-out residuals (neither with the session's
        # tolerances free)
        plain = selection.stand_in.get(id(stage), stage)
        alternative = discovery_alternative(setup, plain, finder, rules, journal)
        if alternative.stage is plain:
            alternative = dataclasses.replace(alternative, stage=stage)
    found = DiscoveryOutcome(alternative.stage, alternative.stage, {"run": False}, [], 1.0)
    if finder is not None:
        say("discovery: function families on what the named effects leave")
        found = discovery_step(setup, alternative, selection.last, finder, rules, journal, say)
        found = names_beside_discovery(setup, found, {c.name for c in candidates}, rules, journal, say)
    # nothing beat a reference: the final model is the stage it judged (with h held where it is)
    final = {**stand_in, **session_stand_in, **selection.stand_in}
    found = dataclasses.replace(found, stage=final.get(id(found.stage), found.stage),
                                named=stand_in.get(id(found.named), found.named))
    return conclude(setup, base, found, geometry, noise_floor_of, rules, journal)


# ------------------------------------------------------------------------------------------------- the steps
def prepare_setup(states: Sequence[RiderStates], params: EucParams, *, n_folds: int | None, use_geometry: bool,
                  analysis_rate_hz: float | None, say: Callable[[str], None], h_held: float | None = None) -> Setup:
    """Step 1: the floor, the prepared recordings, the base model's fit, the blocks and the folds.

    With ``h_held`` every recording carries it (:data:`~euc_ros.core.model.extended.HELD_H`) and it is the start
    of every fit; the discovery is then not linearised at the geometric h (h does not move).

    Parameters
    ----------
    states : sequence of RiderStates
        Reconstructed recordings.
    params : EucParams
        Nominal parameters.
    n_folds : int or None
        Segments per run of the folds (None: enough for :data:`~.folds.MIN_FOLDS` folds).
    use_geometry : bool
        Measure the floor from the wheel's contact path.
    analysis_rate_hz : float or None
        Sub-sampling rate of the prepared recordings [Hz]; None: every sample.
    say : callable
        Progress lines.
    h_held : float, optional
        h held fixed in every fit [m]; None: fitted.

    Returns
    -------
    Setup
    """
    # geometry first: the contact path measures the floor (plane, smooth deviation, scatter)
    floor = floor_from_states(states, params.R) if use_geometry else None
    recs = prepare(states, params, floor=floor, analysis_rate_hz=analysis_rate_hz)
    h_geo = geometric_h(states, params)
    if h_held is not None:
        for rec in recs:
            rec.ctx.extras[HELD_H] = float(h_held)
        h_geo = float("nan")
        say(f"h held at {h_held:.3f} m in every fit (the data do not bound it)")
    h0 = fit_base_h(recs) if h_held is None else float(h_held)
    base_fit = fit_model(Model(), recs, h0)
    # blocks of the paired test and guard bands of the folds from the residual's measured autocorrelation
    st0 = states[0]
    window_s = st0.window * st0.dt if st0.window and np.isfinite(st0.dt) else DEFAULT_BLOCK_S
    block_s = residual_block_length(recs, [Model().residual(r, base_fit.x)[0] for r in recs],
                                    min_s=MIN_BLOCK_WINDOWS * window_s, trend_s=TREND_WINDOWS * window_s)
    recs = with_blocks(recs, block_s)
    n_segments = n_folds if n_folds else max(2, math.ceil(MIN_FOLDS / len(recs)))
    folds = folds_of(recs, n_segments, guard_s=max(window_s, 0.5 * block_s))
    say(f"held-out: {len(folds)} folds ({n_segments} segments per run), blocks of {block_s:.2f} s")
    say(f"base model: h = {base_fit.h:.3f} m, RMSE {base_fit.rmse:.3f} N m (training)")
    return Setup(params, floor, recs, folds, n_segments, block_s, h_geo, h0, base_fit)


def session_start(setup: Setup, stage: Stage, rules: Selector, journal: Journal, say: Callable[[str], None]
                  ) -> Stage:
    """Where the selection starts when the rules carry the session's tolerances: what they can mimic.

    Parameters
    ----------
    setup : Setup
        The prepared recordings and folds.
    stage : Stage
        The stage judged (the base model, h freed, or the floor's geometry).
    rules : Selector
        The selection's rules; their ``session`` (if any) is the nuisance model
        (:func:`~euc_ros.core.residual.session_reference.session_tolerances`).
    journal : Journal
        Gets a warning when the session's tolerance alone explains the residual by the minimum gain.
    say : callable
        Progress lines.

    Returns
    -------
    Stage
        :func:`~euc_ros.core.residual.session_reference.session_reference`'s stage, or ``stage``.
    """
    nuisance = getattr(rules, "session", None)
    if nuisance is None:
        return stage
    ref = session_reference(setup, stage, nuisance, say)
    if ref is not stage and rules.cuts(ref.heldout, stage.heldout):
        journal.warnings.append(
            f"the session's CoM tolerance alone explains the residual down to {ref.heldout.rmse:.3f} N m "
            f"(from {stage.heldout.rmse:.3f}), and a named effect must explain more: a constant torque of "
            "that size (a slope, a rolling resistance on rides in one direction) cannot be told from a CoM "
            "offset error; ride both ways, or measure the CoM offsets and give their tolerance "
            "(--tolerance rider.segments.com_offset=...)")
    return ref


def free_h_reference(setup: Setup, base: Stage, say: Callable[[str], None]) -> Stage:
    """The stage the selection starts from when h is held: the held base model, judged against h freed.

    With h held (the data do not bound it), the pose noise's errors in variables still pull the fits' h (a flat
    curve's optimum goes where the bias takes it), and a candidate that can stand in for h (a rider mass or
    inertia error, a slow h(t), a wheel radius) would cut the held model's residual by that pull alone. A named
    effect or a discovered term is evidence only when it explains more than freeing h does, so the start's
    held-out residual is the base model's with h fitted freely on the same samples and folds; its model and
    parameters stay the held ones (every fit from it holds h).

    Parameters
    ----------
    setup : Setup
        The prepared recordings (h held) and folds.
    base : Stage
        The base model with h held.
    say : callable
        Progress lines.

    Returns
    -------
    Stage
        ``base``'s model and parameters with the held-out residual of h freed.
    """
    free = h_freed(setup.recs)
    h_free = fit_base_h(free)
    fit = fit_model(Model(), free, h_free)
    ho = held_out(Model(), free, h_free, setup.folds, start=fit.x)
    say(f"reference with h free (h = {fit.h:.3f} m): held-out RMSE {base.heldout.rmse:.3f} -> {ho.rmse:.3f} N m; "
        "an effect must explain more than that")
    return Stage(base.model, ho, base.x)


def screen_candidates(candidates: Sequence[Candidate], setup: Setup, say: Callable[[str], None]) -> Screening:
    """Step 2: which candidates can show in the residual at all (a force in span(b_d, b_h) cannot).

    Parameters
    ----------
    candidates : sequence of Candidate
        The library.
    setup : Setup
        The prepared recordings and the base fit (its h).
    say : callable
        Progress lines.

    Returns
    -------
    Screening
    """
    visible = {c.name: detectability(c, setup.recs, setup.base_fit.h) for c in candidates}
    detectable = [c for c in candidates if visible[c.name] > DETECTABILITY_TOL]
    for c in candidates:
        if c not in detectable:
            say(f"{c.name}: undetectable (its generalized force lies in span(b_d, b_h))")
    return Screening(visible, detectable)


def base_stage(setup: Setup) -> Stage:
    """The paper's model alone, held out: where the selection starts and what every cut is measured against.

    Parameters
    ----------
    setup : Setup
        The prepared recordings, folds and base fit.

    Returns
    -------
    Stage
    """
    model = Model()
    return Stage(model, held_out(model, setup.recs, setup.h0, setup.folds, start=setup.base_fit.x), setup.base_fit.x)


def floor_geometry_step(setup: Setup, stage: Stage, journal: Journal, say: Callable[[str], None]) -> Stage:
    """Step 3: a floor tilted or uneven in the mocap frame (level-calibrated lab) into the model as geometry.

    Known from geometry, it goes in before any dynamic candidate; the dynamic ground_slope (a mocap frame
    tilted against gravity) then has nothing left to explain on this floor.

    Parameters
    ----------
    setup : Setup
        The prepared recordings and the measured floor.
    stage : Stage
        The base stage.
    journal : Journal
        Gets the step and the ``ground_slope`` row when the floor goes in.
    say : callable
        Progress lines.

    Returns
    -------
    Stage
        ``stage`` without a floor or on a flat one; else the model with the floor's geometry.
    """
    floor = setup.floor
    if floor is None or floor.flat:
        return stage
    geo = FloorGeometry(math.degrees(math.atan(floor.plane[1])), math.degrees(math.atan(floor.plane[2])))
    geo_model = Model([geo])
    geo_fit = fit_model(geo_model, setup.recs, setup.h0)
    geo_ho = held_out(geo_model, setup.recs, setup.h0, setup.folds, start=geo_fit.x)
    say(f"geometry: floor slope {math.degrees(floor.slope_along_travel_rad):+.2f} deg along travel, deviation "
        f"{floor.deviation_m * 1e3:.1f} mm: in the model (held-out RMSE {stage.heldout.rmse:.3f} -> "
        f"{geo_ho.rmse:.3f} N m)")
    journal.steps.append({"model": stage.model.name, "rmse_nm": stage.heldout.rmse, "selected": "ground_slope",
                          "evidence": "geometry: floor measured from the wheel's contact path (level lab)",
                          "rmse_after_nm": geo_ho.rmse})
    journal.rows["ground_slope"] = CandidateResult("ground_slope", True, 1.0, geo_ho.rmse, 0.0,
                                                   geo_model.report(geo_fit.x), geo_fit.h)
    return Stage(geo_model, geo_ho, geo_fit.x)


def radius_step(setup: Setup, candidates: Sequence[Candidate], stage: Stage, use_geometry: bool, journal: Journal,
                say: Callable[[str], None]) -> tuple[dict, Stage]:
    """Step 5: the rolling radius from the floor; returns the geometry's JSON record and the stage.

    Only a flat floor measures the rolling radius, which the residual cannot separate from h (quasi-static
    riding): a significant offset of a flat floor is a wheel_radius_error found by geometry; a sloped or
    uneven floor is reported, never read as a radius.

    Parameters
    ----------
    setup : Setup
        The prepared recordings, the measured floor and the nominal wheel radius.
    candidates : sequence of Candidate
        The library (the radius goes in only when it holds ``wheel_radius_error``).
    stage : Stage
        Where the selection ended.
    use_geometry : bool
        Whether the floor was measured (for the record's reason).
    journal : Journal
        Gets the step when the radius goes in.
    say : callable
        Progress lines.

    Returns
    -------
    geometry : dict
        The rolling radius measured and nominal [m], its scatter, the floor and whether it was used.
    stage : Stage
        ``stage``, or with the measured radius error (:class:`MeasuredWheelRadius`).
    """
    floor, R = setup.floor, setup.params.R
    r_meas, r_significant, r_reason = rolling_radius_from_floor(floor, R, RADIUS_TOL_M)
    geometry = {"rolling_radius_measured_m": r_meas, "rolling_radius_std_m": floor.scatter_m if floor else float("nan"),
                "samples": floor.samples if floor else 0, "rolling_radius_nominal_m": float(R),
                "rolling_radius_reason": r_reason if use_geometry else "geometry not used",
                "floor": floor.as_dict() if floor else None, "used": False}
    if floor is not None and not floor.flat:
        say(f"geometry: {r_reason}")
    if not (np.isfinite(r_meas) and r_significant
            and "wheel_radius_error" not in [c.name for c in stage.model.effects]
            and any(c.name == "wheel_radius_error" for c in candidates)):
        return geometry, stage
    geo_model = Model(stage.model.effects + [MeasuredWheelRadius(r_meas - R)])
    geo_fit = fit_model(geo_model, setup.recs, setup.h0, fixed=stage.x)
    geo_ho = held_out(geo_model, setup.recs, setup.h0, setup.folds, start=geo_fit.x)
    say(f"geometry: rolling radius {r_meas:.4f} m measured against {R:.4f} m nominal: "
        f"wheel_radius_error by geometry (held-out RMSE {stage.heldout.rmse:.3f} -> {geo_ho.rmse:.3f} N m)")
    journal.steps.append({"model": stage.model.name, "rmse_nm": stage.heldout.rmse, "selected": "wheel_radius_error",
                          "evidence": "geometry: wheel-centre height over the floor", "rmse_after_nm": geo_ho.rmse})
    geometry["used"] = True
    return geometry, Stage(geo_model, geo_ho, geo_fit.x)


def discovery_alternative(setup: Setup, stage: Stage, finder: Discovery, rules: Selector, journal: Journal
                          ) -> Alternative:
    """Step 6a: the discovered alternative to the named dynamic effects (from the model without them).

    A named effect is dropped for the discovered alternative when that is significantly better (the same
    paired test at alpha) by the minimum gain. Without the gain, a tilted mocap frame's true ground_slope
    (0.342 N m) lost to one discovered term, a force cos(psi) at the rider CoG (0.341 N m, p = 0.002): the
    basis mimics library effects (speed at the contact is viscous friction), so a near-equal fit is a tie,
    not a better explanation. A tie (the named not significantly better either) is reported: the
    alternative is listed with the h it implies.

    Parameters
    ----------
    setup : Setup
        The prepared recordings and folds.
    stage : Stage
        The named effects selected.
    finder : Discovery
        The discovery.
    rules : Selector
        The significance level and minimum gain.
    journal : Journal
        Gets the warning and the step (dropped or tied).

    Returns
    -------
    Alternative
    """
    root = Model([c for c in stage.model.effects if getattr(c, "geometric", False)])
    root_fit = fit_model(root, setup.recs, setup.h0)
    root_ho = held_out(root, setup.recs, setup.h0, setup.folds, start=root_fit.x)
    alt = finder.discover(root, root_fit.x, setup.recs, setup.folds, setup.h0, root_ho, setup.h_geo)
    sel = alt.selection_heldout
    pair = None if sel is None else common_samples(stage.heldout, sel)
    if pair is None or not pair[0].residual.size:
        return Alternative(stage, {})
    # on the samples both models have (a named time offset drops some at the runs' ends)
    named_ho, sel = pair
    p_alt = paired_block_test(named_ho, sel)
    record = {"rmse_after_nm": sel.rmse, "p_value_against_named": p_alt,
              "fitted_rmse_after_nm": alt.heldout.rmse if alt.heldout is not None else None,
              "terms": ([r["formula"] for r in alt.model.effects[-1].describe(
                  alt.x[-alt.model.effects[-1].n_params:])] if alt.model is not None else []),
              "linearised_at_h_m": alt.linearised_at_h_m,
              "linearisations_tried_h_m": alt.linearisations_tried_h_m}
    name, rmse = stage.model.name, named_ho.rmse
    if p_alt < rules.alpha and rules.cuts(sel, named_ho):
        journal.warnings.append(f"named {name} not reported: a discovered combination explains "
                                f"significantly more (held-out {rmse:.3f} -> {sel.rmse:.3f} N m, p = {p_alt:.2g})")
        journal.steps.append({"model": name, "rmse_nm": rmse, "selected": None, "dropped_for_discovery": name,
                              "p_value": p_alt})
        return Alternative(Stage(root, root_ho, root_fit.x), record)
    if alt.model is not None and paired_block_test(sel, named_ho) >= AMBIGUITY_ALPHA:
        # statistically tied: the named effect is kept (the physical hypothesis of the library) and the
        # discovered alternative is listed with the h it implies
        terms = record["terms"]
        label = "discovered: " + "; ".join(terms)
        h_alt = float(alt.x[0])
        last = next((st for st in reversed(journal.steps) if st.get("selected")), None)
        if last is not None:
            last.setdefault("tied", []).append({"effect": label, "h_m": h_alt, "rmse_after_nm": sel.rmse,
                                                "effect_parameters": {}})
            last["ambiguous_with"] = list(last.get("ambiguous_with", [])) + [label]
        record["tied_with_named"] = True
        journal.warnings.append(f"named {name} is statistically tied with discovered terms ({'; '.join(terms)}: "
                                f"held-out {rmse:.3f} against {sel.rmse:.3f} N m, h {h_alt:.3f} m): the "
                                f"residual cannot tell them apart; both are listed")
    return Alternative(stage, record)


def named_equal_to_discovery(setup: Setup, stage: Stage, last: LastStep | None, sel_ho: HeldOut, rules: Selector
                             ) -> tuple[Trial, float, list[Trial]] | None:
    """A named effect of the last selection step that explains the discovered structure as well as the terms.

    The discovery showed structure at alpha (one test: the terms were chosen within the folds); a named
    effect that cuts the residual as much (its own test at alpha now that structure is shown, not
    Bonferroni over the library), that holds with any one recording left out
    (:func:`~.selector.holds_without_any_recording`) and that the discovered terms do not beat significantly is
    the physical explanation of it.

    Parameters
    ----------
    setup : Setup
        The prepared recordings.
    stage : Stage
        The model the discovery started from.
    last : LastStep or None
        The last selection step (considered only when it started from ``stage``'s model).
    sel_ho : HeldOut
        The discovered terms' held-out residual.
    rules : Selector
        The significance level and minimum gain.

    Returns
    -------
    tuple of (Trial, float, list of Trial) or None
        ``(trial, p that the terms explain more, the trials tied with it)``; None when no named effect does.
    """
    if last is None or last.model is not stage.model:
        return None
    equal = []
    for t in last.trials:
        pair = common_samples(t.heldout, sel_ho)
        if (t.usable and t.p_value < rules.alpha and rules.cuts(t.heldout, stage.heldout) and pair is not None
                and holds_without_any_recording(setup, stage.heldout, t.heldout, rules)):
            p_better = paired_block_test(*pair)
            if p_better >= AMBIGUITY_ALPHA:
                equal.append((t, p_better))
    if not equal:
        return None
    best, p_best = min(equal, key=lambda e: e[0].heldout.rmse)
    # the named effects the data cannot tell apart from the best one
    tied = [t for t, _ in equal if t is best or paired_block_test(t.heldout, best.heldout) >= AMBIGUITY_ALPHA]
    return best, p_best, tied


def discovery_step(setup: Setup, alternative: Alternative, last: LastStep | None, finder: Discovery,
                   rules: Selector, journal: Journal, say: Callable[[str], None]) -> DiscoveryOutcome:
    """Step 6b: structure left above what the named effects explain (held out, consistent across runs).

    Parameters
    ----------
    setup : Setup
        The prepared recordings, folds and geometric h.
    alternative : Alternative
        Where the discovered alternative left the named stage.
    last : LastStep or None
        The last selection step.
    finder : Discovery
        The discovery.
    rules : Selector
        The significance level and minimum gain.
    journal : Journal
        Gets the step and warnings.
    say : callable
        Progress lines.

    Returns
    -------
    DiscoveryOutcome
    """
    stage = alternative.stage
    disc = finder.discover(stage.model, stage.x, setup.recs, setup.folds, setup.h0, stage.heldout, setup.h_geo)
    info = disc.to_json()
    info["alternative_to_named"] = alternative.record
    if disc.model is None:
        return DiscoveryOutcome(stage, stage, info, [], 1.0)
    sel = disc.selection_heldout
    p_disc = paired_block_test(stage.heldout, sel if sel is not None else disc.heldout)
    gain_ok = rules.cuts(disc.heldout, stage.heldout)
    why = admissibility(disc.model, disc.x, setup.h_geo)
    info.update({"p_value": p_disc, "rmse_after_nm": disc.heldout.rmse, "threshold_p": rules.alpha,
                 "inadmissible": why})
    d_eff = disc.model.effects[-1]
    # the discovered functions' 95 % bands from the block sandwich of the joint fit
    cov, n_blocks = sandwich_covariance(disc.model, setup.recs, disc.x)
    rows_found = d_eff.describe(disc.x[-d_eff.n_params:], cov[-d_eff.n_params:, -d_eff.n_params:],
                                n_blocks - disc.x.size)
    say(f"discovery: {'; '.join(r['formula'] for r in rows_found)}: held-out RMSE {stage.heldout.rmse:.3f} -> "
        f"{disc.heldout.rmse:.3f} N m (p = {p_disc:.2g})")
    equal = None
    if p_disc < rules.alpha and gain_ok:
        # (the structure test stands even when the discovered model itself is not admissible)
        equal = named_equal_to_discovery(setup, stage, last, sel if sel is not None else disc.heldout, rules)
    if equal is not None:
        t, p_better, tied = equal
        journal.steps.append({
            "model": stage.model.name, "rmse_nm": stage.heldout.rmse, "selected": t.candidate.name,
            "p_value": t.p_value,
            "evidence": f"the discovery found structure (p = {p_disc:.2g}); {t.candidate.name} explains it as well "
                        f"as the discovered terms (p = {p_better:.2g} that they explain more)",
            "rmse_after_nm": t.heldout.rmse, "discovered_alternative": [r["formula"] for r in rows_found],
            "ambiguous_with": [e.candidate.name for e in tied if e.candidate is not t.candidate],
            "tied": [e.tied_record("selected" if e is t else "held-out") for e in tied]})
        say(f"named instead of the discovered terms: {t.candidate.name} (held-out RMSE {t.heldout.rmse:.3f} N m, "
            f"terms {disc.heldout.rmse:.3f} N m)")
        info["named_instead"] = t.candidate.name
        named = Stage(t.model, t.heldout, t.fit.x)
        # the structure is the named effect's: what is left is judged on its own
        return DiscoveryOutcome(named, named, info, [], 1.0)
    if p_disc < rules.alpha and gain_ok and why is None:
        for row in rows_found:
            row["rmse_after_nm"] = disc.heldout.rmse
        journal.steps.append({"model": stage.model.name, "rmse_nm": stage.heldout.rmse, "selected": "discovered",
                              "p_value": p_disc, "rmse_after_nm": disc.heldout.rmse,
                              "terms": [r["formula"] for r in rows_found]})
        return DiscoveryOutcome(Stage(disc.model, disc.heldout, disc.x), stage, info, rows_found, p_disc)
    if why is not None and p_disc < rules.alpha and gain_ok:
        journal.warnings.append(f"discovered terms would cut the held-out RMSE but are not admissible: {why}")
    # structure is what the terms would cut by the minimum gain: a significant cut of a few per cent (a slightly
    # different h, the filter's distortion) is the noise floor's business, not an effect left unexplained
    return DiscoveryOutcome(stage, stage, info, [], p_disc if gain_ok else 1.0)


def conclude(setup: Setup, base: Stage, found: DiscoveryOutcome, geometry: dict,
             noise_floor_of: Callable[[Model, np.ndarray], float] | None, rules: Selector,
             journal: Journal) -> ResidualResult:
    """Step 7: the noise floor, the final fit, the h range of the tied models, and the result.

    Parameters
    ----------
    setup : Setup
        The prepared recordings, folds and base fit.
    base : Stage
        The base model held out.
    found : DiscoveryOutcome
        The discovery step's outcome.
    geometry : dict
        The rolling-radius record (:func:`radius_step`).
    noise_floor_of : callable or None
        ``(model, x) -> RMS [N m]``; its failure is a warning.
    rules : Selector
        The significance level and minimum gain.
    journal : Journal
        What the steps reported.

    Returns
    -------
    ResidualResult
    """
    current, named = found.stage, found.named
    noise = float("nan")
    if noise_floor_of is not None:
        try:
            noise = float(noise_floor_of(named.model, named.x))
        except Exception as exc:  # noqa: BLE001 - a floor we cannot measure is reported, not fatal
            journal.warnings.append(f"noise floor not measured: {exc}")
    above_noise = math.isfinite(noise) and named.heldout.rmse > NOISE_FLOOR_FACTOR * noise
    # a refused name passed the family-wise test in a step that then named nothing: structure is there, unless the
    # residual is below its noise floor (then it is at the floor: what the name cut is within what noise makes)
    below_floor = math.isfinite(noise) and named.heldout.rmse <= noise
    refused_left = any(s_.get("refused") and s_.get("selected") is None for s_ in journal.steps) \
        and not named.model.effects and not below_floor
    residual_significant = bool(found.p_value < rules.alpha or above_noise or refused_left)
    # the model is the judged one (a reference stands in for it): the residual it leaves is the reference's
    left = named.heldout if named.model is current.model else current.heldout
    still_above = math.isfinite(noise) and left.rmse > NOISE_FLOOR_FACTOR * noise
    # explained when the discovered terms were accepted (their formula is the explanation offered); what
    # they leave above the noise floor is reported as residual_after_above_noise
    unexplained = bool(residual_significant and not found.rows)
    final_fit = fit_model(current.model, setup.recs, setup.h0, fixed=current.x) if current.model.effects \
        else setup.base_fit
    # h of every model the data cannot tell apart from the selected one
    tied = [t for s_ in journal.steps for t in s_.get("tied", []) if s_.get("selected")]
    ties = [{"effects": [t["effect"] for t in s_["tied"]], "h_m": [t["h_m"] for t in s_["tied"]],
             "tie": [t.get("tie", "held-out") for t in s_["tied"]], "step_model": s_["model"]}
            for s_ in journal.steps if s_.get("selected") and len(s_.get("tied", [])) > 1]
    hs = [final_fit.h] + [t["h_m"] for t in tied]
    h_range = (float(min(hs)), float(max(hs)))
    if h_range[1] - h_range[0] > 0.01:
        journal.warnings.append(f"tied models imply h from {h_range[0]:.3f} to {h_range[1]:.3f} m: h is not "
                                f"determined better than that by these recordings")
    # the final model's intervals: its own statistics, and the h of every tied explanation
    interval = final_interval(current.model, setup.recs, final_fit.x,
                              tied_h=[t["h_m"] for t in tied if t.get("tie") != "selected"])
    effect = current.model.name
    if found.rows:
        effect = "+".join([c.name for c in current.model.effects if c.name != "discovered"] + ["discovered"])
    if unexplained and not found.rows:
        effect = "+".join([c.name for c in current.model.effects] + ["unexplained"])
    return ResidualResult(
        h_base=setup.base_fit.h, rmse_train_base=setup.base_fit.rmse, rmse_before=base.heldout.rmse,
        rmse_after=current.heldout.rmse, effect=effect, effect_parameters=current.model.report(final_fit.x),
        h_after=final_fit.h, final_x=final_fit.x, selected=[c.name for c in current.model.effects],
        candidates=list(journal.rows.values()), steps=journal.steps, alpha=rules.alpha, min_gain=rules.min_gain,
        folds=len(setup.folds),
        fold_kind=f"segments within runs ({setup.n_segments} per run, across {len(setup.recs)} run(s)), "
                  f"blocks {setup.block_s:.2f} s",
        block_s=setup.block_s, base_heldout=base.heldout, final_heldout=current.heldout, final_model=current.model,
        geometry=geometry, warnings=journal.warnings, h_range=h_range, tied=tied,
        residual_significant=residual_significant, unexplained=unexplained, discovered=found.rows,
        discovery=found.info, noise_floor_nm=noise, floor_fit=setup.floor,
        residual_after_above_noise=bool(still_above) if math.isfinite(noise) else None, refused=journal.refused,
        ties=ties, final_interval=interval)


class MeasuredWheelRadius(Candidate):
    """wheel_radius_error with its parameter measured (wheel-centre height), not fitted.

    Parameters
    ----------
    delta : float
        The rolling radius measured minus the nominal one [m].
    """

    name = "wheel_radius_error"
    params = ()

    def __init__(self, delta: float):
        self.delta = float(delta)

    def modify(self, ctx, theta):
        """Override the rolling radius with the measured error: R -> R + delta.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters the model is evaluated on (changed in place: ``overrides["R"]``).
        theta : numpy.ndarray
            The fitted parameters (none: ``delta`` is measured); unused.
        """
        ctx.overrides["R"] = ctx.params.R + self.delta

    def report(self, theta):
        """The measured radius error as reported in the JSON.

        Parameters
        ----------
        theta : numpy.ndarray
            The fitted parameters (none); unused.

        Returns
        -------
        dict of str to float
            ``{"delta_r_m": delta}`` [m].
        """
        return {"delta_r_m": self.delta}
