"""Close the loop: fit candidate effects to the residual M_d1 - M_d2, select by held-out error.

:func:`analyze` runs the steps in order, each a function of this module:

1. :func:`prepare_setup`: identify h with the paper's 3-DoF model, prepare the recordings, cut the
   held-out folds and the blocks of the paired test;
2. :func:`screen_candidates`: each candidate's detectability (is its generalized force in
   span(b_d, b_h)?);
3. :func:`floor_geometry_step`: a floor tilted or uneven in the mocap frame goes into the model as
   geometry, before any dynamic candidate;
4. :func:`select_named`: fit each detectable candidate's parameters jointly with h on training data
   and evaluate on held-out data (other runs, or other segments of a single run); select by held-out
   error with a one-sided paired test over blocks (family-wise over the candidates: max-T) and a
   minimum relative gain; repeat greedily until nothing significant remains. A fit outside its parameter's
   plausible range is refused as a name; candidates the data cannot tell from the selected one (held out,
   or confounded in shape) are its ties;
5. :func:`radius_step`: a rolling radius measured on a flat floor is a wheel_radius_error by geometry;
6. :func:`discovery_alternative` and :func:`discovery_step`: group-sparse forces from function families for
   what the named effects leave, against and after them;
7. :func:`conclude`: the noise floor, the h range of the tied models and the result.

What passes between the steps are the frozen records below (:class:`Setup`, :class:`Stage`,
:class:`Trial`...); :class:`Journal` collects what the steps report as they go.

The residual of a model is ``M_d1 - M_d2 = R m11 (w . (M q_ddot + h - Q_g - dQ)) / D``
(:mod:`euc_ros.core.model.torque`), so an extra force with ``w . dQ = 0`` cannot change it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from euc_ros.core.model.effects import Candidate, FloorGeometry, MocapTimeOffset, make_candidates, with_plausible
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.discovery import discover_terms
from euc_ros.core.residual.folds import (
    MIN_BLOCK_WINDOWS,
    MIN_FOLDS,
    TREND_WINDOWS,
    Fold,
    folds_of,
    residual_block_length,
    with_blocks,
)
from euc_ros.core.residual.interval import final_interval, sandwich_covariance
from euc_ros.core.residual.result import CandidateResult, ResidualResult
from euc_ros.core.residual.selection import (
    DETECTABILITY_TOL,
    Fit,
    HeldOut,
    Model,
    admissibility,
    common_samples,
    confounding,
    detectability,
    fit_base_h,
    fit_model,
    geometric_h,
    held_out,
    implausibility,
    plausibility,
    refusal,
)
from euc_ros.core.residual.significance import AMBIGUITY_ALPHA, max_t_adjusted, paired_block_test
from euc_ros.core.states.contexts import ANALYSIS_RATE_HZ, DEFAULT_BLOCK_S, Recording, forget_shift_caches, prepare
from euc_ros.core.states.floor import RADIUS_TOL_M, FloorFit, floor_from_states, rolling_radius_from_floor
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, RiderStates

#: Savitzky-Golay settings of the residual analysis: the project defaults (measured: with a 0.9 s
#: quartic the attenuation of the accelerations inflated inertia-type parameters, rider mass by
#: +25-30 %; 1.2 s / order 6 keeps the noise floor with less bias, rider mass within 15 %).
RESIDUAL_WINDOW_S = DEFAULT_WINDOW_S
RESIDUAL_POLYORDER = DEFAULT_SG_POLYORDER
#: Significance level of the selection test (family-wise over the candidates of one step).
DEFAULT_ALPHA = 0.01
#: A selected effect must cut the held-out RMSE by at least this fraction.
DEFAULT_MIN_GAIN = 0.10
#: The residual is above its noise floor when its held-out RMSE exceeds this many noise floors. The floor
#: is one realisation of the white pose noise propagated (within 3 % of the true noise contribution on a
#: simulated ride, test_noise.py); on no-effect rides the held-out RMSE is 0.9x it at 120 Hz and 1.1x at
#: 360 Hz (filter bias, 3-D reconstruction): 1.5x leaves ~4 standard errors of that ratio on 3 runs of 7 s
#: (~30 blocks). A factor of 3 would report swinging arms at 1.8 floors as `none` ("at the noise floor");
#: coloured noise the floor does not see is then `unexplained`, which is what it is.
NOISE_FLOOR_FACTOR = 1.5
#: Which of the candidates the held-out data cannot tell apart is named (all of them are reported as tied with
#: the h each implies): "heldout", the lowest held-out RMSE; "prior", the one needing the most typical parameter
#: values (each in units of ParamInfo.scale). Measured on the power rides (README, statistical power; seeds
#: 100-109 per family): the truth named in 74/80 trials with "heldout", 60/80 with "prior" (which named
#: viscous_friction for aero_drag in 8/10 and rider_inertia_error for rider_mass_error in 6/10; it helped only
#: viscous_friction against its twin mocap_time_offset, 9/10 against 6/10); both pass every undeclared-effect case.
TIE_BREAK = "heldout"


# ------------------------------------------------------------------------------ what passes between the steps
@dataclass(frozen=True)
class Rules:
    """The selection's settings: family-wise level, minimum relative cut of the held-out RMSE, most effects."""

    alpha: float
    min_gain: float
    max_effects: int

    def cuts(self, heldout: HeldOut, reference: HeldOut) -> bool:
        """Whether ``heldout`` cuts the held-out RMSE of ``reference`` by at least :attr:`min_gain`."""
        return heldout.rmse <= (1 - self.min_gain) * reference.rmse


@dataclass(frozen=True)
class Setup:
    """What every step works on: the prepared recordings, their folds and blocks, the base model's fit.

    Attributes
    ----------
    params : EucParams
        Nominal parameters.
    floor : FloorFit or None
        The floor measured from the contact path (None without geometry).
    recs : list of Recording
        The recordings prepared for the analysis, with the blocks of the paired test.
    folds : list of Fold
    n_segments : int
        Segments per run of the folds.
    block_s : float
        Block length of the paired test [s].
    h_geo : float
        The segments' geometric h [m] (:func:`~euc_ros.core.residual.selection.geometric_h`).
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
    """Each candidate's detectability (its force's projection on w, relative) and the detectable ones."""

    visible: dict[str, float]
    detectable: list[Candidate]


@dataclass(frozen=True, eq=False)
class Stage:
    """Where the selection stands: a model, its held-out residual and its fitted parameters."""

    model: Model
    heldout: HeldOut
    x: np.ndarray


@dataclass(frozen=True, eq=False)
class Trial:
    """One candidate added to the current model: fitted, held out, tested against the current model."""

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
        """The JSON record of a tied candidate (``why``: ``selected``, ``held-out`` or ``confounded``)."""
        return {"effect": self.candidate.name, "h_m": self.fit.h, "rmse_after_nm": self.heldout.rmse,
                "effect_parameters": self.model.report(self.fit.x), "tie": why}


@dataclass(frozen=True, eq=False)
class LastStep:
    """The last selection step: the model it started from and its trials (the named alternatives to discovery)."""

    model: Model
    trials: tuple[Trial, ...]


@dataclass(frozen=True)
class Selection:
    """Where the greedy selection of named effects ended, and its last step."""

    stage: Stage
    last: LastStep | None


@dataclass(frozen=True)
class Alternative:
    """After the discovered alternative to the named effects: the stage, and the alternative's JSON record."""

    stage: Stage
    record: dict


@dataclass(frozen=True)
class Discovery:
    """After the discovery step: the final stage, the named one before discovered terms, what was found.

    Attributes
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
    """What the steps report as they go: per-candidate rows, the selection steps (JSON records), warnings."""

    rows: dict[str, CandidateResult] = field(default_factory=dict)
    steps: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    refused: list[dict] = field(default_factory=list)


# ------------------------------------------------------------------------------------------------ the driver
def analyze(states: Sequence[RiderStates], params: EucParams, *, candidates: Sequence[Candidate] | None = None,
            alpha: float = DEFAULT_ALPHA, min_gain: float = DEFAULT_MIN_GAIN, max_effects: int = 3,
            n_folds: int | None = None, use_geometry: bool = True, discover: bool = True,
            noise_floor_of: Callable[[Model, np.ndarray], float] | None = None,
            analysis_rate_hz: float | None = ANALYSIS_RATE_HZ, plausible: dict | None = None,
            progress: Callable[[str], None] | None = None) -> ResidualResult:
    """Trace the residual M_d1 - M_d2 of ``states`` to the candidate effects (greedy forward selection).

    Parameters
    ----------
    states : sequence of RiderStates
        Reconstructed recordings (phi about the hinge for the time-offset candidate).
    params : EucParams
        Nominal parameters (``h`` is identified).
    candidates : sequence of Candidate, optional
        The library (default: all of :data:`~euc_ros.core.model.effects.LIBRARY`).
    alpha : float
        Family-wise significance level of each selection step (max-T over the candidates,
        :func:`~euc_ros.core.residual.significance.max_t_adjusted`).
    min_gain : float
        Minimum relative cut of the held-out RMSE for a selection.
    max_effects : int
        Most named effects to select.
    n_folds : int, optional
        Segments per run of the held-out folds (default: enough for :data:`~.folds.MIN_FOLDS` folds).
    use_geometry : bool
        Measure the floor from the wheel's contact path: a floor tilted or uneven in the mocap frame goes
        into the model as geometry; a flat one may measure the rolling radius.
    discover : bool
        After the named effects, look for structure left in the residual (:mod:`.discovery`).
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

    Returns
    -------
    ResidualResult
    """
    say = progress or (lambda _m: None)
    rules = Rules(alpha, min_gain, max_effects)
    candidates = with_plausible(list(candidates) if candidates is not None else make_candidates(), plausible or {})
    setup = prepare_setup(states, params, n_folds=n_folds, use_geometry=use_geometry,
                          analysis_rate_hz=analysis_rate_hz, say=say)
    screening = screen_candidates(candidates, setup, say)
    journal = Journal()
    base = base_stage(setup)
    stage = floor_geometry_step(setup, base, journal, say)
    remaining = [c for c in screening.detectable if c.name not in {e.name for e in stage.model.effects}]
    selection = select_named(setup, stage, remaining, screening, rules, journal, say)
    for c in candidates:
        if c not in screening.detectable:
            journal.rows[c.name] = CandidateResult(c.name, False, screening.visible[c.name], base.heldout.rmse, 1.0,
                                                   {}, setup.base_fit.h)
    geometry, stage = radius_step(setup, candidates, selection.stage, use_geometry, journal, say)
    if not any(c.name == MocapTimeOffset.name for c in stage.model.effects):
        forget_shift_caches(setup.recs)     # no time offset fitted from here on: its hook's geometry let go
    alternative = Alternative(stage, {})
    if discover and any(not getattr(c, "geometric", False) for c in stage.model.effects):
        alternative = discovery_alternative(setup, stage, rules, journal)
    found = Discovery(alternative.stage, alternative.stage, {"run": False}, [], 1.0)
    if discover:
        say("discovery: function families on what the named effects leave")
        found = discovery_step(setup, alternative, selection.last, rules, journal, say)
    return conclude(setup, base, found, geometry, noise_floor_of, rules, journal)


# ------------------------------------------------------------------------------------------------- the steps
def prepare_setup(states: Sequence[RiderStates], params: EucParams, *, n_folds: int | None, use_geometry: bool,
                  analysis_rate_hz: float | None, say: Callable[[str], None]) -> Setup:
    """Step 1: the floor, the prepared recordings, the base model's fit, the blocks and the folds."""
    # geometry first: the contact path measures the floor (plane, smooth deviation, scatter)
    floor = floor_from_states(states, params.R) if use_geometry else None
    recs = prepare(states, params, floor=floor, analysis_rate_hz=analysis_rate_hz)
    h_geo = geometric_h(states, params)
    h0 = fit_base_h(recs)
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


def screen_candidates(candidates: Sequence[Candidate], setup: Setup, say: Callable[[str], None]) -> Screening:
    """Step 2: which candidates can show in the residual at all (a force in span(b_d, b_h) cannot)."""
    visible = {c.name: detectability(c, setup.recs, setup.base_fit.h) for c in candidates}
    detectable = [c for c in candidates if visible[c.name] > DETECTABILITY_TOL]
    for c in candidates:
        if c not in detectable:
            say(f"{c.name}: undetectable (its generalized force lies in span(b_d, b_h))")
    return Screening(visible, detectable)


def base_stage(setup: Setup) -> Stage:
    """The paper's model alone, held out: where the selection starts and what every cut is measured against."""
    model = Model()
    return Stage(model, held_out(model, setup.recs, setup.h0, setup.folds, start=setup.base_fit.x), setup.base_fit.x)


def floor_geometry_step(setup: Setup, stage: Stage, journal: Journal, say: Callable[[str], None]) -> Stage:
    """Step 3: a floor tilted or uneven in the mocap frame (level-calibrated lab) into the model as geometry.

    Known from geometry, it goes in before any dynamic candidate; the dynamic ground_slope (a mocap frame
    tilted against gravity) then has nothing left to explain on this floor.
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


def try_candidate(candidate: Candidate, stage: Stage, setup: Setup) -> Trial:
    """``candidate`` added to the model of ``stage``: fitted (the current parameters fixed as the start),
    held out, tested against the current model, and checked for admissibility."""
    model = Model(stage.model.effects + [candidate])
    full = fit_model(model, setup.recs, setup.h0, fixed=stage.x)
    ho = held_out(model, setup.recs, setup.h0, setup.folds, start=full.x)
    return Trial(candidate, model, ho, paired_block_test(stage.heldout, ho), full,
                 admissibility(model, full.x, setup.h_geo), tuple(plausibility(model, full.x)))


def select_named(setup: Setup, stage: Stage, remaining: list[Candidate], screening: Screening, rules: Rules,
                 journal: Journal, say: Callable[[str], None]) -> Selection:
    """Step 4: greedy forward selection of named effects by held-out error (see the module docstring)."""
    last = None
    while remaining and len(stage.model.effects) < rules.max_effects:
        trials = [try_candidate(c, stage, setup) for c in remaining]
        last = LastStep(stage.model, tuple(trials))
        best = selection_step(setup, stage, trials, screening, rules, journal, say)
        if best is None:
            break
        stage = Stage(best.model, best.heldout, best.fit.x)
        remaining = [c for c in remaining if c is not best.candidate]
    return Selection(stage, last)


def selection_step(setup: Setup, stage: Stage, trials: list[Trial], screening: Screening, rules: Rules,
                   journal: Journal, say: Callable[[str], None]) -> Trial | None:
    """One step of :func:`select_named`: the trial selected (None: nothing passes), reported in ``journal``.

    A trial that passes the test but is not admissible, or whose fit leaves a plausible range (refused),
    is not selected; a refused trial is reported as such (``refused``: it explains the residual only with
    parameters no rider has, so it is no explanation, and what it would cut is left to the discovery).
    The selected trial is reported as tied (``tied``, ``ambiguous_with``) with every usable trial the
    data cannot tell from it (:func:`tied_trials`).
    """
    # family-wise over this step's candidates: max-T over sign flips of whole blocks (the candidates' test
    # statistics are strongly correlated, so this asks less of each than Bonferroni's alpha / candidates)
    p_adj = dict(zip((t.candidate.name for t in trials), max_t_adjusted(stage.heldout, [t.heldout for t in trials])))
    for t in trials:
        name = t.candidate.name
        say(f"  + {name}: held-out RMSE {t.heldout.rmse:.3f} N m (p = {t.p_value:.2g}, adjusted {p_adj[name]:.2g})"
            + (f"; not admissible: {t.inadmissible}" if t.inadmissible else "")
            + (f"; {refusal(list(t.refused))}" if t.refused else ""))
        if name not in journal.rows:
            journal.rows[name] = CandidateResult(name, True, screening.visible[name], t.heldout.rmse, t.p_value,
                                                 t.model.report(t.fit.x), t.fit.h, t.inadmissible, p_adj[name],
                                                 None if t.inadmissible else refusal(list(t.refused)))
    threshold = rules.alpha
    passing = [t for t in trials if p_adj[t.candidate.name] < threshold and rules.cuts(t.heldout, stage.heldout)]
    ok = [t for t in passing if t.usable]
    for t in passing:
        if t.inadmissible is not None:
            journal.warnings.append(f"{t.candidate.name} would cut the held-out RMSE {stage.heldout.rmse:.3f} -> "
                                    f"{t.heldout.rmse:.3f} N m but is not admissible: {t.inadmissible}")
        elif t.refused:
            journal.warnings.append(f"{refusal(list(t.refused))} (it would cut the held-out RMSE "
                                    f"{stage.heldout.rmse:.3f} -> {t.heldout.rmse:.3f} N m)")
            journal.refused.extend({**r, "rmse_after_nm": t.heldout.rmse, "h_m": t.fit.h, "model": t.model.name,
                                    "text": refusal([r])} for r in t.refused)
    step = {"model": stage.model.name, "rmse_nm": stage.heldout.rmse, "threshold_p": threshold,
            "correction": "max-T over the step's candidates (sign flips of whole blocks)",
            "tried": [{"effect": t.candidate.name, "rmse_after_nm": t.heldout.rmse, "p_value": t.p_value,
                       "p_adjusted": p_adj[t.candidate.name], "h_m": t.fit.h,
                       **({"inadmissible": t.inadmissible} if t.inadmissible else {}),
                       **({"refused": refusal(list(t.refused))} if t.refused and not t.inadmissible else {})}
                      for t in trials]}
    refused_passing = [t.candidate.name for t in passing if t.inadmissible is None and t.refused]
    if refused_passing:
        step["refused"] = refused_passing
    if not ok:
        step["selected"] = None
        journal.steps.append(step)
        return None
    best = min(ok, key=lambda t: t.heldout.rmse)
    if TIE_BREAK == "prior":
        # among the candidates the held-out data cannot tell apart from the best one, prefer the explanation
        # that needs the least implausible parameters (each parameter in units of its typical magnitude,
        # ParamInfo.scale): a prior-weighted tie-break, reported as such
        tied = [t for t in ok if t is best or paired_block_test(t.heldout, best.heldout) >= AMBIGUITY_ALPHA]
        best = min(tied, key=lambda t: implausibility(t.candidate, t.fit.x[-t.candidate.n_params:]
                                                      if t.candidate.n_params else []))
    step["selected"] = best.candidate.name
    tied = tied_trials(setup, stage, best, trials, rules)
    step["ambiguous_with"] = [t.candidate.name for t, _, _ in tied if t is not best]
    step["tied"] = [{**t.tied_record(why), **extra} for t, why, extra in tied]
    journal.steps.append(step)
    say(f"selected {best.candidate.name}: held-out RMSE {stage.heldout.rmse:.3f} -> {best.heldout.rmse:.3f} N m"
        + (f" (tied with {', '.join(step['ambiguous_with'])})" if step["ambiguous_with"] else ""))
    return best


def tied_trials(setup: Setup, stage: Stage, best: Trial, trials: Sequence[Trial], rules: Rules
                ) -> list[tuple[Trial, str, dict]]:
    """The usable trials the data cannot tell from ``best`` (``best`` first), each with why and its measures.

    ``held-out``: the paired block test does not find ``best`` better at :data:`AMBIGUITY_ALPHA`;
    ``confounded``: the two contributions have nearly the same shape once h is projected out, so that what
    tells them apart is below the residual's noise (:func:`~.selection.confounding`, at the same level),
    even when one held-out realisation happens to prefer one (a rider's pitch-inertia error and a mass
    error, whose h differ by 8 cm). Also trials that did not pass the family-wise test against the
    current model on their own; each must cut the held-out RMSE by the minimum gain.
    """
    out: list[tuple[Trial, str, dict]] = [(best, "selected", {})]
    for t in trials:
        if t is best or not t.usable or not rules.cuts(t.heldout, stage.heldout):
            continue
        p_best = paired_block_test(t.heldout, best.heldout)
        if p_best >= AMBIGUITY_ALPHA:
            out.append((t, "held-out", {"p_value_best_better": p_best}))
            continue
        conf = confounding(stage.model, stage.x, (best.model, best.fit.x), (t.model, t.fit.x), setup.recs,
                           best.fit.rmse, AMBIGUITY_ALPHA)
        if conf.tied:
            out.append((t, "confounded", {"p_value_best_better": p_best, "cosine": conf.cosine,
                                          "chi2": conf.chi2}))
    return out


def radius_step(setup: Setup, candidates: Sequence[Candidate], stage: Stage, use_geometry: bool, journal: Journal,
                say: Callable[[str], None]) -> tuple[dict, Stage]:
    """Step 5: the rolling radius from the floor; returns the geometry's JSON record and the stage.

    Only a flat floor measures the rolling radius, which the residual cannot separate from h (quasi-static
    riding): a significant offset of a flat floor is a wheel_radius_error found by geometry; a sloped or
    uneven floor is reported, never read as a radius.
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


def discovery_alternative(setup: Setup, stage: Stage, rules: Rules, journal: Journal) -> Alternative:
    """Step 6a: the discovered alternative to the named dynamic effects (from the model without them).

    A named effect is dropped for the discovered alternative when that is significantly better (the same
    paired test at alpha) by the minimum gain. Without the gain, a tilted mocap frame's true ground_slope
    (0.342 N m) lost to one discovered term, a force cos(psi) at the rider CoG (0.341 N m, p = 0.002): the
    basis mimics library effects (speed at the contact is viscous friction), so a near-equal fit is a tie,
    not a better explanation. A tie (the named not significantly better either) is reported: the
    alternative is listed with the h it implies.
    """
    root = Model([c for c in stage.model.effects if getattr(c, "geometric", False)])
    root_fit = fit_model(root, setup.recs, setup.h0)
    root_ho = held_out(root, setup.recs, setup.h0, setup.folds, start=root_fit.x)
    alt = discover_terms(root, root_fit.x, setup.recs, setup.folds, setup.h0, root_ho, setup.h_geo)
    sel = alt["info"].pop("selection_heldout", None)
    pair = None if sel is None else common_samples(stage.heldout, sel)
    if pair is None or not pair[0].residual.size:
        return Alternative(stage, {})
    # on the samples both models have (a named time offset drops some at the runs' ends)
    named_ho, sel = pair
    p_alt = paired_block_test(named_ho, sel)
    record = {"rmse_after_nm": sel.rmse, "p_value_against_named": p_alt,
              "fitted_rmse_after_nm": alt["heldout"].rmse if alt.get("heldout") is not None else None,
              "terms": ([r["formula"] for r in alt["model"].effects[-1].describe(
                  alt["x"][-alt["model"].effects[-1].n_params:])] if alt.get("model") is not None else []),
              "linearised_at_h_m": alt["info"].get("linearised_at_h_m"),
              "linearisations_tried_h_m": alt["info"].get("linearisations_tried_h_m")}
    name, rmse = stage.model.name, named_ho.rmse
    if p_alt < rules.alpha and rules.cuts(sel, named_ho):
        journal.warnings.append(f"named {name} not reported: a discovered combination explains "
                                f"significantly more (held-out {rmse:.3f} -> {sel.rmse:.3f} N m, p = {p_alt:.2g})")
        journal.steps.append({"model": name, "rmse_nm": rmse, "selected": None, "dropped_for_discovery": name,
                              "p_value": p_alt})
        return Alternative(Stage(root, root_ho, root_fit.x), record)
    if alt.get("model") is not None and paired_block_test(sel, named_ho) >= AMBIGUITY_ALPHA:
        # statistically tied: the named effect is kept (the physical hypothesis of the library) and the
        # discovered alternative is listed with the h it implies
        terms = record["terms"]
        label = "discovered: " + "; ".join(terms)
        h_alt = float(alt["x"][0])
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


def named_equal_to_discovery(stage: Stage, last: LastStep | None, sel_ho: HeldOut, rules: Rules
                             ) -> tuple[Trial, float, list[Trial]] | None:
    """A named effect of the last selection step that explains the discovered structure as well as the terms.

    The discovery showed structure at alpha (one test: the terms were chosen within the folds); a named
    effect that cuts the residual as much (its own test at alpha now that structure is shown, not
    Bonferroni over the library) and that the discovered terms do not beat significantly is the physical
    explanation of it. Returns ``(trial, p that the terms explain more, the trials tied with it)`` or None.
    """
    if last is None or last.model is not stage.model:
        return None
    equal = []
    for t in last.trials:
        pair = common_samples(t.heldout, sel_ho)
        if t.usable and t.p_value < rules.alpha and rules.cuts(t.heldout, stage.heldout) and pair is not None:
            p_better = paired_block_test(*pair)
            if p_better >= AMBIGUITY_ALPHA:
                equal.append((t, p_better))
    if not equal:
        return None
    best, p_best = min(equal, key=lambda e: e[0].heldout.rmse)
    # the named effects the data cannot tell apart from the best one
    tied = [t for t, _ in equal if t is best or paired_block_test(t.heldout, best.heldout) >= AMBIGUITY_ALPHA]
    return best, p_best, tied


def discovery_step(setup: Setup, alternative: Alternative, last: LastStep | None, rules: Rules, journal: Journal,
                   say: Callable[[str], None]) -> Discovery:
    """Step 6b: structure left above what the named effects explain (held out, consistent across runs)."""
    stage = alternative.stage
    disc = discover_terms(stage.model, stage.x, setup.recs, setup.folds, setup.h0, stage.heldout, setup.h_geo)
    info = disc.pop("info")
    info["alternative_to_named"] = alternative.record
    if disc.get("model") is None:
        return Discovery(stage, stage, info, [], 1.0)
    sel = info.pop("selection_heldout", None)
    p_disc = paired_block_test(stage.heldout, sel if sel is not None else disc["heldout"])
    gain_ok = rules.cuts(disc["heldout"], stage.heldout)
    why = admissibility(disc["model"], disc["x"], setup.h_geo)
    info.update({"p_value": p_disc, "rmse_after_nm": disc["heldout"].rmse, "threshold_p": rules.alpha,
                 "inadmissible": why})
    d_eff = disc["model"].effects[-1]
    # the discovered functions' 95 % bands from the block sandwich of the joint fit
    cov, n_blocks = sandwich_covariance(disc["model"], setup.recs, disc["x"])
    rows_found = d_eff.describe(disc["x"][-d_eff.n_params:], cov[-d_eff.n_params:, -d_eff.n_params:],
                                n_blocks - disc["x"].size)
    say(f"discovery: {'; '.join(r['formula'] for r in rows_found)}: held-out RMSE {stage.heldout.rmse:.3f} -> "
        f"{disc['heldout'].rmse:.3f} N m (p = {p_disc:.2g})")
    equal = None
    if p_disc < rules.alpha and gain_ok:
        # (the structure test stands even when the discovered model itself is not admissible)
        equal = named_equal_to_discovery(stage, last, sel if sel is not None else disc["heldout"], rules)
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
            f"terms {disc['heldout'].rmse:.3f} N m)")
        info["named_instead"] = t.candidate.name
        named = Stage(t.model, t.heldout, t.fit.x)
        # the structure is the named effect's: what is left is judged on its own
        return Discovery(named, named, info, [], 1.0)
    if p_disc < rules.alpha and gain_ok and why is None:
        for row in rows_found:
            row["rmse_after_nm"] = disc["heldout"].rmse
        journal.steps.append({"model": stage.model.name, "rmse_nm": stage.heldout.rmse, "selected": "discovered",
                              "p_value": p_disc, "rmse_after_nm": disc["heldout"].rmse,
                              "terms": [r["formula"] for r in rows_found]})
        return Discovery(Stage(disc["model"], disc["heldout"], disc["x"]), stage, info, rows_found, p_disc)
    if why is not None and p_disc < rules.alpha and gain_ok:
        journal.warnings.append(f"discovered terms would cut the held-out RMSE but are not admissible: {why}")
    # structure is what the terms would cut by the minimum gain: a significant cut of a few per cent (a slightly
    # different h, the filter's distortion) is the noise floor's business, not an effect left unexplained
    return Discovery(stage, stage, info, [], p_disc if gain_ok else 1.0)


def conclude(setup: Setup, base: Stage, found: Discovery, geometry: dict,
             noise_floor_of: Callable[[Model, np.ndarray], float] | None, rules: Rules,
             journal: Journal) -> ResidualResult:
    """Step 7: the noise floor, the final fit, the h range of the tied models, and the result."""
    current, named = found.stage, found.named
    noise = float("nan")
    if noise_floor_of is not None:
        try:
            noise = float(noise_floor_of(named.model, named.x))
        except Exception as exc:  # noqa: BLE001 - a floor we cannot measure is reported, not fatal
            journal.warnings.append(f"noise floor not measured: {exc}")
    above_noise = math.isfinite(noise) and named.heldout.rmse > NOISE_FLOOR_FACTOR * noise
    # a refused name passed the family-wise test in a step that then named nothing: structure is there
    refused_left = any(s_.get("refused") and s_.get("selected") is None for s_ in journal.steps) \
        and not named.model.effects
    residual_significant = bool(found.p_value < rules.alpha or above_noise or refused_left)
    still_above = math.isfinite(noise) and current.heldout.rmse > NOISE_FLOOR_FACTOR * noise
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
    """wheel_radius_error with its parameter measured (wheel-centre height), not fitted."""

    name = "wheel_radius_error"
    params = ()

    def __init__(self, delta: float):
        self.delta = float(delta)

    def modify(self, ctx, theta):
        ctx.overrides["R"] = ctx.params.R + self.delta

    def report(self, theta):
        return {"delta_r_m": self.delta}
