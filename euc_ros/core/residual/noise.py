"""The residual's noise floor: the pose noise of the recording propagated through the whole chain.

``M_d1 - M_d2`` of a perfect model is not zero: the poses carry noise, the derivative filter turns
it into noisy accelerations, and the two torque expressions weigh them differently. Its size is
measured on the data itself, not assumed:

1. the pose noise of every body is estimated from the recording (the pose-noise model,
   :mod:`euc_ros.core.mocap.noise`);
2. the recording is reconstructed once more with a second, independent noise of that size added
   (same filter, same session), and the residual of the same model recomputed. The residual
   analysis takes for this the first replicate of the h interval's SIMEX
   (:func:`euc_ros.core.identify.simex.first_replicate`: the noise estimated from third
   differences, rotations per body axis), so the one reconstruction serves both;
3. the RMS of the change is the contribution of one realisation of the recording's own noise: the
   noise floor of the residual.

Limits: noise that is coloured (slow marker sliding) has little fourth-difference energy, so it is
under-estimated here and shows as structure instead; the discovery step and the cross-run test
(:mod:`.discovery`) are what judge that.
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from euc_ros.core.identify.simex import SIMEX_SEED, first_replicate
from euc_ros.core.mocap.noise import renoised
from euc_ros.core.model.extended import Model
from euc_ros.core.model.terms import EucParams
from euc_ros.core.states.contexts import ANALYSIS_RATE_HZ, prepare
from euc_ros.core.states.floor import floor_from_states
from euc_ros.core.states.kinematics import RiderStates, reconstruct_states
from euc_ros.core.states.link_sliding import MIN_SLIDING_M, add_sliding
from euc_ros.core.states.settings import ReconstructionSettings


def noise_floor(series_list: Sequence, states: Sequence, session, residual_of, *, seed: int = 0,
                window_s: float | None = None, polyorder: int | None = None, noisy: Sequence | None = None) -> float:
    """RMS [N m] of the residual's change when the recordings' own pose noise is added once more.

    ``residual_of(states_list) -> list of (residual, mask)`` computes the residual of a fixed model
    (e.g. the selected one) on reconstructed states; ``states`` are the states of ``series_list``.
    ``noisy``: the re-noised recordings' states, made by the caller (the residual's floor takes the
    first SIMEX replicate, :func:`euc_ros.core.identify.simex.first_replicate`); without them the
    recordings are re-noised here (:func:`~euc_ros.core.mocap.noise.renoised`, ``seed``) and reconstructed.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings.
    states : sequence of RiderStates
        Their reconstructed states.
    session : Session
        Their session (for the reconstruction of the re-noised recordings).
    residual_of : callable
        ``residual_of(states_list) -> list of (residual, mask)``: per recording, the fixed model's residual
        [N m] and its usable samples (bool) over all samples.
    seed : int
        Seed of the noise drawn here (unused with ``noisy``).
    window_s : float, optional
        Savitzky-Golay window of the reconstruction [s] (default the reconstruction's).
    polyorder : int, optional
        Its polynomial order (default the reconstruction's).
    noisy : sequence of RiderStates, optional
        The re-noised recordings' states.

    Returns
    -------
    float
        The RMS of the residual's change over the samples usable in both [N m]; NaN when there is none.
    """
    if noisy is None:
        rng = np.random.default_rng(seed)
        noisy = []
        for series, st in zip(series_list, states):
            kw = {}
            if window_s is not None:
                kw["window_s"] = window_s
            if polyorder is not None:
                kw["polyorder"] = polyorder
            # the same rider CoG method as the states (the skeleton's links re-estimated on the re-noised run)
            noisy.append(reconstruct_states(renoised(series, rng), session, phi_definition=st.phi_definition,
                                            cog_method=getattr(st, "cog_method", "segments"), **kw))
    diffs = []
    for (r0, m0), (r1, m1) in zip(residual_of(states), residual_of(noisy)):
        n = min(len(r0), len(r1))
        m = m0[:n] & m1[:n]
        diffs.append((r1[:n] - r0[:n])[m])
    d = np.concatenate(diffs) if diffs else np.zeros(0)
    return float(np.sqrt(np.mean(d ** 2))) if d.size else float("nan")


def make_noise_floor(series_list: Sequence, states: Sequence[RiderStates], session, params: EucParams, *,
                     seed: int | None = None, analysis_rate_hz: float | None = ANALYSIS_RATE_HZ, share=None,
                     sliding: dict | None = None) -> Callable[[Model, np.ndarray], float]:
    """``noise_floor_of`` for :func:`analyze` from the recordings' own pose noise.

    The noise is propagated through the reconstruction, the derivative filter and the given model
    (:func:`euc_ros.core.residual.noise.noise_floor`).

    The re-noised recordings are the first replicate of the h interval's SIMEX
    (:func:`euc_ros.core.identify.simex.first_replicate`, ``seed`` default its seed); with ``share`` (a
    :class:`~euc_ros.core.identify.simex.SimexShare` later given to ``eiv_bias``) that replicate's h is
    kept so SIMEX does not reconstruct it again.

    With ``sliding`` (the soft-tissue sliding the rigid links show,
    :func:`~euc_ros.core.states.link_sliding.estimate_sliding`) above
    :data:`~euc_ros.core.states.link_sliding.MIN_SLIDING_M`, the recordings are also reconstructed once with
    an independent surrogate of that sliding added (its per-body RMS and spectrum,
    :func:`~euc_ros.core.states.link_sliding.add_sliding`), and the floor is the quadrature sum of the two
    changes: the residual a recording's own sliding leaves is at its noise floor, not missing physics.
    The returned callable keeps the parts of its last floor in its ``parts`` dict [N m]: ``pose_noise``
    and ``sliding``.

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings.
    states : sequence of RiderStates
        Their reconstructed states (the filter, phi definition and CoG method of the re-noised ones).
    session : Session
        Their session.
    params : EucParams
        The session's parameters.
    seed : int, optional
        Seed of the noise draws (default SIMEX's, :data:`~euc_ros.core.identify.simex.SIMEX_SEED`).
    analysis_rate_hz : float or None
        Sub-sampling rate of the prepared recordings (:func:`~euc_ros.core.states.contexts.prepare`); None:
        every sample.
    share : SimexShare, optional
        Where the replicate's h is kept for SIMEX.
    sliding : dict, optional
        The sliding the rigid links show (:func:`~euc_ros.core.states.link_sliding.estimate_sliding`).

    Returns
    -------
    callable
        ``noise_floor_of(model, x) -> float``: the noise floor [N m] of the model with parameters ``x``.
    """
    floor = floor_from_states(states, params.R)
    st0 = states[0]
    window_s = st0.window * st0.dt if st0.window and np.isfinite(st0.dt) else None

    def of(model: Model, x: np.ndarray) -> float:
        def residual_of(st_list):
            recs = prepare(st_list, params, floor=floor, analysis_rate_hz=analysis_rate_hz)
            out = []
            for rec, st in zip(recs, st_list):
                r, m = model.residual(rec, x)
                full, mask = np.zeros(len(st.t)), np.zeros(len(st.t), bool)
                full[rec.index], mask[rec.index] = r, m
                out.append((full, mask))
            return out

        def floor_of(noisy):
            return noise_floor(series_list, states, session, residual_of, seed=0 if seed is None else seed,
                               window_s=window_s, polyorder=st0.polyorder, noisy=noisy)

        white = None
        if window_s is not None:
            # the replicate's states go to the floor, then (dropped) to SIMEX's h: never beside its fit
            rec = ReconstructionSettings(window_s=window_s, polyorder=st0.polyorder, phi_definition=st0.phi_definition,
                                         cog_method=getattr(st0, "cog_method", "segments"))
            white = first_replicate(series_list, session, params, reconstruction=rec,
                                    seed=SIMEX_SEED if seed is None else seed, share=share, use=floor_of)
        white = floor_of(None) if white is None else white
        slid = sliding_floor(series_list, states, session, residual_of, sliding, seed=SLIDING_SEED if seed is None
                             else seed, window_s=window_s) if window_s is not None else 0.0
        of.parts = {"pose_noise": float(white), "sliding": float(slid)}
        return float(np.hypot(white, slid))

    of.parts = {}
    return of


#: Seed of the surrogate sliding the floor adds (another stream than SIMEX's and the sliding bias').
SLIDING_SEED = 7


def sliding_floor(series_list: Sequence, states: Sequence[RiderStates], session, residual_of, sliding: dict | None, *,
                  seed: int, window_s: float) -> float:
    """RMS [N m] of the residual's change when the recordings' own soft-tissue sliding is added once more.

    Every rider body slides on its own, by a Gaussian surrogate of the measured spectrum and RMS
    (:func:`~euc_ros.core.states.link_sliding.add_sliding`). Sliding the bodies share (every body moving with
    the rider's acceleration) is seen little by the links and moves the CoG more: on sliding that follows the
    segments' accelerations in full, this part is about a third of the sliding's true contribution
    (test_noise.py measures it).

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings.
    states : sequence of RiderStates
        Their states (the filter and CoG method of the slid reconstructions).
    session : Session
        Their session.
    residual_of : callable
        ``residual_of(states_list) -> list of (residual, mask)`` of the fixed model.
    sliding : dict or None
        The sliding the links show (:func:`~euc_ros.core.states.link_sliding.estimate_sliding`).
    seed : int
        Seed of the surrogate.
    window_s : float
        The states' filter window [s].

    Returns
    -------
    float
        0 without sliding above :data:`~euc_ros.core.states.link_sliding.MIN_SLIDING_M`.
    """
    if not sliding or sliding.get("spectrum") is None or float(sliding.get("rms_max_m") or 0.0) < MIN_SLIDING_M:
        return 0.0
    st0 = states[0]
    rec = ReconstructionSettings(window_s=window_s, polyorder=st0.polyorder, phi_definition=st0.phi_definition,
                                 cog_method=getattr(st0, "cog_method", "segments"))
    rng = np.random.default_rng(seed)
    slid = [rec.reconstruct(add_sliding(s, sliding, rng), session) for s in series_list]
    return noise_floor(series_list, states, session, residual_of, noisy=slid)
