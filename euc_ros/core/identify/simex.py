"""Errors in variables: the bias of h that the recording's own pose noise gives, measured by SIMEX.

Pose noise reaches the accelerations the regressors are built from, which biases h (low: a noisy CoG
looks lower), independently of the recording's length. The bias is proportional to the noise
variance, so simulation-extrapolation measures it on the data: the noise of every body is estimated
from the recording itself (:func:`~euc_ros.core.mocap.noise.estimate_pose_noise`), the same amount is
added again, and the change of h is the bias of the data as recorded (:func:`eiv_bias`).
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.filters.derivatives import window_samples
from euc_ros.core.identify.fit import DEFAULT_H_GRID, coefficients_for, pooled_fit, pooled_h_of_states
from euc_ros.core.memory import release_free_memory
from euc_ros.core.mocap.noise import estimate_pose_noise, pose_noise_draws, pose_noise_series
from euc_ros.core.states.settings import FIXED_DEFAULT, ReconstructionSettings

#: Re-noised reconstructions of every recording in :func:`eiv_bias`: 2 antithetic pairs. Measured on
#: 6 simulated 7 s runs (seed 7), the bias' scatter over 8 seeds: 6 independent replicates 0.99 mm
#: (reported standard error 0.85 mm); 1 pair 0.31 mm, 2 pairs 0.38 mm, 3 pairs 0.38 mm (reported
#: 0.15-0.20 mm); the mean bias -3.60 +- 0.35 mm independent, -3.38 +- 0.13 mm antithetic.
SIMEX_REPLICATES = 4


#: Seed of :func:`eiv_bias` (its first replicate is also the residual's noise floor: :class:`SimexShare`).
SIMEX_SEED = 1


class SimexShare:
    """The first replicate of :func:`eiv_bias` (pair 1, ``+z``), made once for two uses.

    The residual's noise floor (:func:`euc_ros.core.residual.noise.make_noise_floor`) is one
    re-noised reconstruction of the recordings, which is what a SIMEX replicate is. Made by
    :func:`first_replicate`, its h is kept here (with the noise estimate and what it was made with),
    and :func:`eiv_bias` given the same object and the same settings takes that h instead of
    reconstructing the recordings once more. Only floats are kept, not the states.
    """

    def __init__(self) -> None:
        self.series: list | None = None
        self.noise: list | None = None
        self.key: tuple | None = None
        self.h_m: float | None = None

    def noise_of(self, series_list) -> list:
        """Per recording, :func:`estimate_pose_noise` (computed once per set of recordings).

        Parameters
        ----------
        series_list : sequence of MocapSeries
            The recordings; other objects than those kept reset what is kept.

        Returns
        -------
        list
            Per recording, its ``(sigma_pos [m], sigma_rot [rad])`` per body.
        """
        if self.series is None or len(self.series) != len(series_list) or \
                any(a is not b for a, b in zip(self.series, series_list)):
            self.series, self.noise, self.key, self.h_m = list(series_list), None, None, None
        if self.noise is None:
            self.noise = [estimate_pose_noise(s) for s in series_list]
        return self.noise

    def lookup(self, series_list, key: tuple) -> float | None:
        """The kept h of the first replicate, if it was made from these recordings with these settings.

        Parameters
        ----------
        series_list : sequence
            The recordings (the same objects the replicate was made from).
        key : tuple
            What the replicate's h depends on besides the recordings (:func:`_share_key`).

        Returns
        -------
        float or None
            The kept h [m]; None when none is kept or it was made from other recordings or with another key.
        """
        if self.h_m is None or self.key != key or self.series is None or len(self.series) != len(series_list) \
                or any(a is not b for a, b in zip(self.series, series_list)):
            return None
        return self.h_m


def _share_key(series_list, window_s, polyorder, rec: ReconstructionSettings, seed, params) -> tuple:
    """What a replicate's h depends on besides the recordings.

    The window counts in samples: ``window_s`` of 1.2 s and of 145 / 120 s are one filter.
    """
    windows = tuple(window_samples(1.0 / s.rate_hz, window_s=window_s, polyorder=polyorder) for s in series_list)
    return windows, int(polyorder), rec.phi_definition, rec.cog_method, rec.max_gap, int(seed), params


def _replicate_states(series_list, noise, draws, sign, session, rec: ReconstructionSettings):

    # the noisy recordings are made block by block as the states are reconstructed (never whole)
    return [rec.reconstruct(pose_noise_series(s, sp, sr, noise=z, sign=sign), session)
            for s, (sp, sr), z in zip(series_list, noise, draws)]


def first_replicate(series_list, session, params, *, reconstruction: ReconstructionSettings = FIXED_DEFAULT,
                    seed: int = SIMEX_SEED, share: SimexShare | None = None, use=None):
    """The states of :func:`eiv_bias`'s first replicate, or None when the noise cannot be estimated.

    The replicate is the recordings with their estimated white pose noise added once more (pair 1, ``+z``). With
    ``share`` its h is kept for :func:`eiv_bias`.

    ``use(states)``: what the caller does with the states (e.g. the residual's noise floor); then
    ``use``'s result is returned instead of the states, and the h is fitted after it with the states
    dropped (reduced to their residual coefficients first: :func:`~euc_ros.core.identify.fit.pooled_h_of_states`),
    so the states and the fit's working set are never held together. ``use`` is not called (None is
    returned) when the noise cannot be estimated.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings.
    session : Session
        Their session.
    params : EucParams
        The session's parameters.
    reconstruction : ReconstructionSettings
        How the re-noised recordings are reconstructed.
    seed : int
        Seed of the noise draws (that of :func:`eiv_bias`).
    share : SimexShare, optional
        Where the replicate's h is kept.
    use : callable, optional
        ``use(states)``, called with the replicate's states.

    Returns
    -------
    list of RiderStates, or ``use``'s result, or None
        None when the noise cannot be estimated.
    """
    share = share if share is not None else SimexShare()
    noise = share.noise_of(series_list)
    if all(not np.isfinite(sp).any() for sp, _ in noise):
        return None
    rng = np.random.default_rng(seed)
    draws = [pose_noise_draws(s, rng) for s in series_list]
    rec = reconstruction
    states = _replicate_states(series_list, noise, draws, 1.0, session, rec)
    share.key = _share_key(series_list, rec.window_s, rec.polyorder, rec, seed, params)
    if use is None:
        share.h_m = pooled_h_of_states(list(states), params)      # a copy of the list: the states are returned
        return states
    out = use(states)
    release_free_memory()                   # what ``use`` made and dropped
    share.h_m = pooled_h_of_states(states, params)
    release_free_memory()                   # the replicate's reconstruction
    return out


def eiv_bias(series_list, session, params, h: float, *, reconstruction: ReconstructionSettings = FIXED_DEFAULT,
             replicates: int = SIMEX_REPLICATES, seed: int = SIMEX_SEED, with_error: bool = False,
             antithetic: bool = True, share: SimexShare | None = None):
    """Errors-in-variables bias of h by SIMEX [m]: ``mean(h with the noise doubled) - h``.

    The noise of the recordings as given is estimated (:func:`estimate_pose_noise`); adding the same
    again doubles its variance, and the bias is linear in the variance, so the change of h equals
    the bias already in ``h``. NaN when the noise cannot be estimated. Each replicate draws its own
    noise, so the estimate carries a random error: with ``with_error`` the return value is
    ``(bias, standard error)``.

    ``antithetic`` (default): the replicates come in pairs with mirrored noise ``+z`` and ``-z``
    (``replicates`` reconstructions, ``replicates // 2`` pairs). h responds to the added noise to first
    order linearly (a random shift of zero mean, the replicates' main scatter) and to second order
    quadratically (the bias); the pair's mean cancels the linear part exactly, so it carries only
    the quadratic part's own scatter. The standard error is that of the pair means (independent).
    ``share``: a :class:`SimexShare` whose first replicate (made by :func:`first_replicate` with the
    same settings) is used instead of being made again.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings.
    session : Session
        Their session.
    params : EucParams
        The session's parameters.
    h : float
        The h fitted on the recordings as given [m].
    reconstruction : ReconstructionSettings
        How the re-noised recordings are reconstructed (its filter is the one used).
    replicates : int
        Re-noised reconstructions.
    seed : int
        Seed of the noise draws.
    with_error : bool
        Also return the bias' standard error.
    antithetic : bool
        Draw the replicates in mirrored pairs.
    share : SimexShare, optional
        The first replicate, made already.

    Returns
    -------
    float or (float, float)
        The bias [m], or ``(bias, standard error)`` [m] with ``with_error``.
    """
    rec = reconstruction
    (bias, err), = eiv_biases(series_list, session, params, [(rec.window_s, rec.polyorder, h)], reconstruction=rec,
                              replicates=replicates, seed=seed, antithetic=antithetic, share=share)
    return (bias, err) if with_error else bias


def eiv_biases(series_list, session, params, filters, *, reconstruction: ReconstructionSettings = FIXED_DEFAULT,
               replicates: int = SIMEX_REPLICATES, seed: int = SIMEX_SEED, antithetic: bool = True,
               share: SimexShare | None = None) -> list[tuple[float, float]]:
    """:func:`eiv_bias` with its standard error at several Savitzky-Golay filters, from the same replicates.

    ``filters``: ``(window_s, polyorder, h)`` per filter, ``h`` the h fitted with that filter
    (``reconstruction`` gives the rest: its own filter is not used). Every
    replicate's noisy recording is made, and its geometry evaluated, once for all filters
    (:func:`~euc_ros.core.states.kinematics.iter_states_filters`: one filter's states at a time); each
    filter's result is the one :func:`eiv_bias` gives for it alone, number for number. Returns
    ``[(bias, standard error), ...]`` in the order of ``filters``.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings.
    session : Session
        Their session.
    params : EucParams
        The session's parameters.
    filters : sequence of (float, int, float)
        ``(window_s [s], polyorder, h [m])`` per filter.
    reconstruction : ReconstructionSettings
        How the re-noised recordings are reconstructed (all but the filter).
    replicates : int
        Re-noised reconstructions.
    seed : int
        Seed of the noise draws.
    antithetic : bool
        Draw the replicates in mirrored pairs.
    share : SimexShare, optional
        The first replicate, made already (used with one filter).

    Returns
    -------
    list of (float, float)
        Per filter, the bias and its standard error [m] (NaN when the noise cannot be estimated).
    """
    filters = [(float(w), int(p), float(h)) for w, p, h in filters]
    share = share if share is not None else SimexShare()
    noise = share.noise_of(series_list)
    nan = float("nan")
    if all(not np.isfinite(sp).any() for sp, _ in noise):
        return [(nan, nan) for _ in filters]
    rng = np.random.default_rng(seed)
    release_free_memory()                   # what the steps before left freed, before the replicates
    known = share.lookup(series_list, _share_key(series_list, filters[0][0], filters[0][1], reconstruction,
                                                 seed, params)) if len(filters) == 1 else None

    def h_of(draws, sign) -> list[float]:
        # fit_h's pooled 3-DoF h per filter; each recording's states are reduced to their residual
        # coefficients as soon as they are made (never two filters' states of a recording at once)
        coefs: list[list] = [[] for _ in filters]
        fitted: list[float | None] = [None] * len(filters)     # per filter, its h once fitted
        for s, (sp, sr), z in zip(series_list, noise, draws):
            noisy = pose_noise_series(s, sp, sr, noise=z, sign=sign)
            made = reconstruction.iter_filters(noisy, session, [(w, p) for w, p, _ in filters], shared=True, lean=True)
            # a counter, not enumerate(): enumerate's reused (k, item) tuple would keep this filter's states
            # alive while the generator makes the next filter's
            for k in range(len(filters)):
                states = next(made)
                coefs[k] += coefficients_for([states], params, "3dof", None)
                del states
                if len(series_list) == 1:         # one recording: its fit now, before the next filter's states
                    fitted[k] = float(pooled_fit(coefs[k], DEFAULT_H_GRID, "3dof").h_m)
                    coefs[k] = []
                release_free_memory()             # this filter's temporaries, before the next's
            del noisy, made
            release_free_memory()           # the replicate's reconstruction
        return [h if h is not None else float(pooled_fit(c, DEFAULT_H_GRID, "3dof").h_m)
                for h, c in zip(fitted, coefs)]

    hs = []
    pairs = antithetic and replicates >= 2
    for k in range(replicates // 2 if pairs else replicates):
        draws = [pose_noise_draws(s, rng) for s in series_list]
        first = [known] if (k == 0 and known is not None) else h_of(draws, 1.0)
        hs.append([0.5 * (a + b) for a, b in zip(first, h_of(draws, -1.0))] if pairs else first)
    hs = np.array(hs, dtype=float)                     # (replicates or pairs, filters)
    out = []
    for j, (_, _, h) in enumerate(filters):
        col = hs[:, j]
        bias = float(np.nanmean(col) - h)
        err = float(np.nanstd(col, ddof=1) / np.sqrt(col.size)) if col.size > 1 else nan
        out.append((bias, err))
    return out
