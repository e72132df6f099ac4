"""The selection of named effects: which library candidates the residual supports, and in which order.

A :class:`Selector` is what :func:`~euc_ros.core.residual.analysis.analyze` takes as its ``selector``: its
:meth:`Selector.select` grows the model of a :class:`~.records.Stage` by library candidates and reports each
step in the :class:`~.records.Journal`. :class:`ForwardSelector`, the default, is the greedy forward selection
by held-out error: each detectable candidate's parameters are fitted jointly with h on training data and
evaluated on held-out data; a step selects by a one-sided paired test over blocks (family-wise over the
step's candidates: max-T) and a minimum relative gain that holds with any one recording (with one recording:
any one of its held-out segments) left out, and the selection repeats until nothing significant remains. With
the session's tolerances (``session``) every step is judged against the current model with the rider's pitch
offset free within them. A fit outside its parameter's plausible range is refused as a name; candidates the data
cannot tell from the selected one (held out, or confounded in shape) are its ties.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from euc_ros.core.model.candidate import Candidate
from euc_ros.core.residual.records import Journal, LastStep, Screening, Selection, Setup, Stage, Trial
from euc_ros.core.residual.result import CandidateResult
from euc_ros.core.residual.selection import (
    HeldOut,
    Model,
    admissibility,
    block_offsets,
    confounding,
    fit_model,
    held_out,
    implausibility,
    plausibility,
    refusal,
)
from euc_ros.core.residual.session_reference import session_reference
from euc_ros.core.residual.significance import AMBIGUITY_ALPHA, max_t_adjusted, paired_block_test

#: Significance level of the selection test (family-wise over the candidates of one step).
DEFAULT_ALPHA = 0.01
#: A selected effect must cut the held-out RMSE by at least this fraction.
DEFAULT_MIN_GAIN = 0.10
#: Most named effects the default selection names.
DEFAULT_MAX_EFFECTS = 3
#: Which of the candidates the held-out data cannot tell apart is named (all of them are reported as tied with
#: the h each implies): "heldout", the lowest held-out RMSE; "prior", the one needing the most typical parameter
#: values (each in units of ParamInfo.scale). Measured on the power rides (README, statistical power; seeds
#: 100-109 per family): the truth named in 74/80 trials with "heldout", 60/80 with "prior" (which named
#: viscous_friction for aero_drag in 8/10 and rider_inertia_error for rider_mass_error in 6/10; it helped only
#: viscous_friction against its twin mocap_time_offset, 9/10 against 6/10); both pass every undeclared-effect case.
TIE_BREAK = "heldout"


@dataclass(frozen=True)
class Selector:
    """The selection of named effects: its significance level and minimum gain, and the selection itself.

    The level and the gain are the analysis' rules beyond the selection too (the discovery's structure test,
    the discovered alternative to the named effects); subclasses implement :meth:`select`.

    Parameters
    ----------
    alpha : float
        Significance level (family-wise over the candidates of a step).
    min_gain : float
        Minimum relative cut of the held-out RMSE.
    """

    alpha: float = DEFAULT_ALPHA
    min_gain: float = DEFAULT_MIN_GAIN

    def cuts(self, heldout: HeldOut, reference: HeldOut) -> bool:
        """Whether ``heldout`` cuts the held-out RMSE of ``reference`` by at least :attr:`min_gain`.

        Parameters
        ----------
        heldout, reference : HeldOut

        Returns
        -------
        bool
        """
        return heldout.rmse <= (1 - self.min_gain) * reference.rmse

    def select(self, setup: Setup, stage: Stage, remaining: list[Candidate], screening: Screening,
               journal: Journal, say: Callable[[str], None]) -> Selection:
        """Grow the model of ``stage`` by candidates of ``remaining``.

        Parameters
        ----------
        setup : Setup
            The prepared recordings, folds and base fit.
        stage : Stage
            Where the selection starts (the base model, or the floor's geometry).
        remaining : list of Candidate
            The detectable candidates not in the model.
        screening : Screening
            Each candidate's detectability.
        journal : Journal
            Where the steps are reported (rows, selection steps, warnings, refused names).
        say : callable
            Progress lines.

        Returns
        -------
        Selection
            The stage reached and the last step's trials (None when no step was tried).
        """
        raise NotImplementedError


@dataclass(frozen=True)
class ForwardSelector(Selector):
    """Greedy forward selection by held-out error, with the paired block test (max-T) and a minimum gain.

    Parameters
    ----------
    alpha : float
        Family-wise significance level of each step (max-T over the step's candidates,
        :func:`~euc_ros.core.residual.significance.max_t_adjusted`).
    min_gain : float
        Minimum relative cut of the held-out RMSE for a selection.
    max_effects : int
        Most named effects in the model.
    session : Candidate, optional
        What the session's stated tolerances can mimic
        (:func:`~euc_ros.core.residual.session_reference.session_tolerances`): the selection starts from the
        residual it leaves, so a name must explain more than the session's uncertainty can
        (:func:`~euc_ros.core.residual.session_reference.session_reference`). None: from the base model's.
    """

    max_effects: int = DEFAULT_MAX_EFFECTS
    session: Candidate | None = None

    def select(self, setup: Setup, stage: Stage, remaining: list[Candidate], screening: Screening,
               journal: Journal, say: Callable[[str], None]) -> Selection:
        """Add the best significant candidate (:func:`selection_step`) until none is left or passes.

        Parameters
        ----------
        setup : Setup
        stage : Stage
        remaining : list of Candidate
        screening : Screening
        journal : Journal
        say : callable

        Returns
        -------
        Selection
        """
        last, stand_in = None, {}
        while remaining and len(stage.model.effects) < self.max_effects:
            trials = [try_candidate(c, stage, setup) for c in remaining]
            last = LastStep(stage.model, tuple(trials))
            best = selection_step(setup, stage, trials, screening, self, journal, say)
            if best is None:
                break
            plain = Stage(best.model, best.heldout, best.fit.x)
            # the next name must explain more than the session's tolerances can beside this one, as the first had to
            stage = plain if self.session is None else session_reference(setup, plain, self.session, say)
            if stage is not plain:
                stand_in[id(stage)] = plain
            remaining = [c for c in remaining if c is not best.candidate]
        return Selection(stage, last, stand_in)


def try_candidate(candidate: Candidate, stage: Stage, setup: Setup) -> Trial:
    """``candidate`` added to the model of ``stage``: fitted, held out, tested and checked for admissibility.

    Fitted with the current parameters fixed as the start; tested against the current model.

    Parameters
    ----------
    candidate : Candidate
        The candidate.
    stage : Stage
        The current model, its held-out residual and fit.
    setup : Setup
        The prepared recordings, folds, start h and geometric h.

    Returns
    -------
    Trial
    """
    model = Model(stage.model.effects + [candidate])
    full = fit_model(model, setup.recs, setup.h0, fixed=stage.x)
    ho = held_out(model, setup.recs, setup.h0, setup.folds, start=full.x)
    return Trial(candidate, model, ho, paired_block_test(stage.heldout, ho), full,
                 admissibility(model, full.x, setup.h_geo), tuple(plausibility(model, full.x)))


def holds_without_any_recording(setup: Setup, reference: HeldOut, heldout: HeldOut, rules: Selector) -> bool:
    """Whether ``heldout`` cuts ``reference``'s held-out RMSE by the minimum gain with any one recording left out.

    A name is stable when the recordings agree on it: a constant force that one run's offset calls for, or a fit
    that one run's artefact carries, stops cutting the residual once that run is left out. With one recording its
    held-out segments (the folds') are left out in turn instead; with one segment there is nothing to leave out
    (True).

    Parameters
    ----------
    setup : Setup
        The prepared recordings (their blocks' numbering, :func:`~euc_ros.core.residual.selection.block_offsets`)
        and folds.
    reference, heldout : HeldOut
        The current model's and the candidate's held-out residuals.
    rules : Selector
        The minimum gain.

    Returns
    -------
    bool
    """
    for left_out in stability_units(setup):
        keep_ref = ~np.isin(reference.block, left_out)
        keep = ~np.isin(heldout.block, left_out)
        if keep_ref.any() and keep.any() and not rules.cuts(heldout.restricted(keep), reference.restricted(keep_ref)):
            return False
    return True


def stability_units(setup: Setup) -> list[np.ndarray]:
    """The parts a stable name must hold without, as their blocks (numbered across the recordings).

    Every recording when there are two or more; with one, each fold's held-out segment of it; none with one
    segment.

    Parameters
    ----------
    setup : Setup
        The prepared recordings (``recs``, their ``block``) and, for one recording, its ``folds``.

    Returns
    -------
    list of ndarray of int
    """
    offsets = block_offsets(setup.recs)
    if len(setup.recs) >= 2:
        return [np.unique(rec.block) + off for rec, off in zip(setup.recs, offsets)]
    if not setup.recs:
        return []
    rec = setup.recs[0]
    units = [np.unique(rec.block[np.asarray(f.test[0], bool)]) + offsets[0] for f in setup.folds]
    units = [u for u in units if u.size]
    return units if len(units) >= 2 else []


def selection_step(setup: Setup, stage: Stage, trials: list[Trial], screening: Screening, rules: Selector,
                   journal: Journal, say: Callable[[str], None]) -> Trial | None:
    """One step of :meth:`ForwardSelector.select`: the trial selected (None: nothing passes), reported in ``journal``.

    A trial that passes the test but is not admissible, or whose fit leaves a plausible range (refused),
    is not selected; a refused trial is reported as such (``refused``: it explains the residual only with
    parameters no rider has, so it is no explanation, and what it would cut is left to the discovery).
    The selected trial is reported as tied (``tied``, ``ambiguous_with``) with every usable trial the
    data cannot tell from it (:func:`tied_trials`).

    Parameters
    ----------
    setup : Setup
        The prepared recordings and folds.
    stage : Stage
        The current model.
    trials : list of Trial
        Each remaining candidate added to it (:func:`try_candidate`).
    screening : Screening
        Each candidate's detectability.
    rules : Selector
        The significance level and the minimum gain.
    journal : Journal
        Gets the candidates' rows, the step's record, warnings and refused names.
    say : callable
        Progress lines.

    Returns
    -------
    Trial or None
        The selected trial; None when no usable trial passes.
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
    significant = [t for t in trials if p_adj[t.candidate.name] < threshold and rules.cuts(t.heldout, stage.heldout)]
    # a name must hold on every recording's company: with any one recording left out, it still cuts the rest
    unstable = [t for t in significant if not holds_without_any_recording(setup, stage.heldout, t.heldout, rules)]
    passing = [t for t in significant if t not in unstable]
    for t in unstable:
        say(f"  {t.candidate.name}: not stable (with one recording left out it no longer cuts the held-out RMSE by "
            f"{rules.min_gain:.0%})")
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
    if unstable:
        step["unstable"] = [t.candidate.name for t in unstable]
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


def tied_trials(setup: Setup, stage: Stage, best: Trial, trials: Sequence[Trial], rules: Selector
                ) -> list[tuple[Trial, str, dict]]:
    """The usable trials the data cannot tell from ``best`` (``best`` first), each with why and its measures.

    ``held-out``: the paired block test does not find ``best`` better at :data:`AMBIGUITY_ALPHA`;
    ``confounded``: the two contributions have nearly the same shape once h is projected out, so that what
    tells them apart is below the residual's noise (:func:`~.selection.confounding`, at the same level),
    even when one held-out realisation happens to prefer one (a rider's pitch-inertia error and a mass
    error, whose h differ by 8 cm). Also trials that did not pass the family-wise test against the
    current model on their own; each must cut the held-out RMSE by the minimum gain.

    Parameters
    ----------
    setup : Setup
        The prepared recordings.
    stage : Stage
        The current model.
    best : Trial
        The selected trial.
    trials : sequence of Trial
        The step's trials.
    rules : Selector
        The minimum gain.

    Returns
    -------
    list of tuple of (Trial, str, dict)
        ``(trial, why, measures)``: why ``selected`` (``best``), ``held-out`` or ``confounded``; the measures
        ``p_value_best_better`` and, when confounded, ``cosine`` and ``chi2``.
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
