"""What the session's stated tolerances can mimic: the reference a named effect or a discovered term must beat.

A session file is an estimate. Its segments' CoM offsets come from anthropometric tables, known to about a
centimetre, and an offset that is off fore and aft tilts the rider's pitch by a constant: a structured residual
that a slope of a few tenths of a degree, or a discovered constant force, mimics. Such a residual is the
session's, not missing physics.

:class:`SessionTolerances` is the nuisance model of that error: a constant pitch offset ``dphi`` free within the
CoM offsets' stated tolerance over the rider's h (every segment's offset off the same way: the worst case the
tolerance allows; :data:`~euc_ros.core.identify.budget.DEFAULT_TOLERANCES` or the user's), with h free.
:func:`session_reference` fits it on the analysis' folds, and its held-out residual is where the selection
starts (as h is freed where it is held, :func:`~euc_ros.core.residual.analysis.free_h_reference`): a candidate
is evidence only when it explains more than the session's uncertainty can. The model that is reported stays
the stage's: the offset is never named or applied.

The session's masses, inertias and lengths are not freed here: h takes up most of what they do to the residual
(the h budget, :mod:`~euc_ros.core.identify.budget`, measures it), and freed together with h and each other
their fold fits are ill-conditioned (the held-out residual of all seven with the offset was 6-9 times the
base model's on a ride where the offset alone cut it by 17 %).
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from euc_ros.core.identify.budget import DEFAULT_TOLERANCES, absolute_tolerance
from euc_ros.core.model.candidate import Candidate, ModelContext, ParamInfo
from euc_ros.core.model.extended import Model
from euc_ros.core.residual.records import Setup, Stage
from euc_ros.core.residual.selection import fit_model, h_freed, held_out

#: The budget key of the segments' CoM offsets (its tolerance bounds the pitch offset).
COM_OFFSET = "rider.segments.com_offset"


class SessionTolerances(Candidate):
    """A constant pitch offset within the session's CoM tolerance: a nuisance model, never a name.

    Parameters
    ----------
    dphi_max : float
        Bound of the offset [rad] (> 0).
    """

    name = "session_tolerances"
    formula = "phi -> phi + dphi, |dphi| <= CoM offset tolerance / h"

    def __init__(self, dphi_max: float) -> None:
        self.dphi_max = float(dphi_max)
        self.params = (ParamInfo("dphi_rad", "rad", -self.dphi_max, self.dphi_max, 0.0, self.dphi_max,
                                 reported=False),)

    def modify(self, ctx: ModelContext, theta: np.ndarray) -> None:
        """Offset the rider's pitch by ``theta[0]``.

        Parameters
        ----------
        ctx : ModelContext
            The samples and parameters (changed in place: ``phi``).
        theta : numpy.ndarray
            ``[dphi]`` [rad].
        """
        ctx.phi = ctx.phi + theta[0]


def session_tolerances(h_m: float, tolerances: dict | None = None) -> SessionTolerances | None:
    """The nuisance model of a session's stated CoM tolerance.

    Parameters
    ----------
    h_m : float
        The rider's h [m] (turns the CoM offsets' tolerance into a pitch offset).
    tolerances : dict, optional
        Half-widths by budget key (default :data:`~euc_ros.core.identify.budget.DEFAULT_TOLERANCES`).

    Returns
    -------
    SessionTolerances or None
        None when the tolerance is 0 or h is not a positive number.

    Examples
    --------
    >>> round(session_tolerances(0.6).dphi_max, 4)          # 1 cm over 0.6 m
    0.0167
    """
    com = absolute_tolerance({**DEFAULT_TOLERANCES, **(tolerances or {})}[COM_OFFSET], 0.0)
    ok = np.isfinite(h_m) and h_m > 0 and com > 0
    return SessionTolerances(com / h_m) if ok else None


def session_reference(setup: Setup, stage: Stage, nuisance: SessionTolerances, say: Callable[[str], None]) -> Stage:
    """The stage the selection starts from: ``stage``'s model, judged against the session's values freed.

    The nuisance is fitted with ``stage``'s effects and h free (a held h is freed too), on the same samples and
    folds; when it cuts the held-out residual, that is the residual a candidate must cut further.

    Parameters
    ----------
    setup : Setup
        The prepared recordings and folds.
    stage : Stage
        The current model (the base model, or the floor's geometry).
    nuisance : SessionTolerances
        The session's tolerance (:func:`session_tolerances`).
    say : callable
        Progress lines.

    Returns
    -------
    Stage
        ``stage``'s model and parameters with the nuisance model's held-out residual, or ``stage`` itself when
        the nuisance does not cut it.
    """
    free = h_freed(setup.recs)
    model = Model(list(stage.model.effects) + [nuisance])
    start = np.concatenate([stage.x, np.zeros(nuisance.n_params)])
    fit = fit_model(model, free, setup.h0, fixed=start)
    ho = held_out(model, free, setup.h0, setup.folds, start=fit.x)
    if not ho.rmse < stage.heldout.rmse:
        return stage
    say(f"reference with the rider's pitch offset free within the session's CoM tolerance: held-out RMSE "
        f"{stage.heldout.rmse:.3f} -> {ho.rmse:.3f} N m; an effect must explain more than that")
    return dataclasses.replace(stage, heldout=ho)
