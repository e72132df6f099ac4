"""Soft-tissue sliding measured on a recording, and the bias it gives h (SIMEX).

The sliding is measured by :mod:`euc_ros.core.states.link_sliding`.

White pose noise is measured from high-order differences (:func:`~.uncertainty.estimate_pose_noise`)
and its bias of h by re-noising (:func:`~.uncertainty.eiv_bias`). Sliding of the markers against the
bones is smooth, within the band of the motion, so differences do not see it. The kinematic chain
does (:mod:`.skeleton_fit`): a link's vector ``R_a^T (p_b - p_a)`` is constant for rigid bones, and
its deviation from the session's median is the two bodies' sliding (plus their white noise).

:func:`~euc_ros.core.states.link_sliding.estimate_sliding`
    Per link, the variance of the deviation minus its white part (third differences) is
    ``q_a + q_b``: the sliding variances of its two bodies (rotation sliding folded into the pivot's,
    E taken as not sliding). Non-negative least squares over the links gives every body's ``q``,
    and the links' mean power spectrum gives the sliding's colour.
:func:`sliding_bias`
    SIMEX as for the white noise: the same sliding is added once and twice again (phase-randomised
    surrogates with the measured spectrum, each body's variance ``q``, independent bodies, applied in
    the body frame), the states are reconstructed and h identified again; a parabola through the
    three h extrapolated to no sliding gives the bias of h as recorded.

What no kinematic check can see is not in it: sliding that every body shares (a rigid rider's soft
tissue following the common acceleration), and wrong CoM offsets in the session (the budget's
``rider.segments.com_offset`` covers those). Links across moving joints (trunk, neck, pelvis) that do
flex in a real ride count as sliding, which widens the interval (conservative).
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.identify.fit import pooled_h_of_states
from euc_ros.core.states.link_sliding import MIN_SLIDING_M, add_sliding, estimate_sliding
from euc_ros.core.states.settings import FIXED_DEFAULT, ReconstructionSettings
from euc_ros.core.states.skeleton import SkeletonModel


def sliding_bias(series_list, session, params, h: float, *, reconstruction: ReconstructionSettings = FIXED_DEFAULT,
                 replicates: int = 3, seed: int = 2, sliding: dict | None = None) -> dict:
    """SIMEX bias of h from the sliding the links show, extrapolated quadratically.

    The measured sliding is added once and twice again (sliding variance times 2 and 3); a parabola
    through h at variance factors 1, 2, 3 extrapolated to 0 gives ``h0 = 3 h(1) - 3 h(2) + h(3)`` and
    the bias of h as recorded ``h - h0`` (errors in variables flatten faster than linearly, so a
    straight line through two points would undershoot).

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
        How the slid recordings are reconstructed.
    replicates : int
        Slid reconstructions per variance level.
    seed : int
        Seed of the added sliding.
    sliding : dict, optional
        The measured sliding (default :func:`~euc_ros.core.states.link_sliding.estimate_sliding` of the
        recordings).

    Returns
    -------
    dict
        ``sliding_rms_max_m``, ``sliding_bias_m`` and its standard error ``sliding_bias_err_m``
        (0 and 0 below :data:`MIN_SLIDING_M`; NaN without a finite h).
    """
    sliding = sliding or estimate_sliding(series_list, session)
    out = {"sliding_rms_max_m": sliding["rms_max_m"], "sliding_bias_m": 0.0, "sliding_bias_err_m": 0.0}
    if not np.isfinite(h):
        out.update(sliding_bias_m=float("nan"), sliding_bias_err_m=float("nan"))
        return out
    if sliding["rms_max_m"] < MIN_SLIDING_M or sliding["spectrum"] is None:
        return out
    rng = np.random.default_rng(seed)
    hs = {1: [], 2: []}
    for level in (1, 2):
        scaled = dict(sliding, rms_m=[r * np.sqrt(level) for r in sliding["rms_m"]])
        for _ in range(replicates):
            noisy = [add_sliding(s, scaled, rng) for s in series_list]
            skel = SkeletonModel.estimate(noisy, session) if reconstruction.cog_method == "skeleton" else None
            # each recording's states reduced to their coefficients as they are made (no per-recording fits)
            hs[level].append(pooled_h_of_states((reconstruction.reconstruct(s, session, skeleton=skel, lean=True)
                                                 for s in noisy), params))
            del noisy, skel                   # before the next replicate's are made
    h2, h3 = float(np.nanmean(hs[1])), float(np.nanmean(hs[2]))
    h0 = 3.0 * h - 3.0 * h2 + h3
    out["sliding_bias_m"] = float(h - h0)
    if replicates > 1:
        v2 = np.nanvar(hs[1], ddof=1) / replicates
        v3 = np.nanvar(hs[2], ddof=1) / replicates
        out["sliding_bias_err_m"] = float(np.sqrt(9.0 * v2 + v3))
    else:
        out["sliding_bias_err_m"] = float("nan")
    return out
