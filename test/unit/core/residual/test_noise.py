"""The pose-noise estimate of :mod:`euc_ros.core.residual.noise` against a known answer.

A smooth 120 Hz trajectory plus white noise of known sigma: the fourth difference of the trajectory
is ~a4 dt^4 (1e-8 m here, far below the noise), that of the noise has variance 70 sigma^2, so the
robust estimate must return sigma within its sampling error (MAD of n Gaussian samples: ~1.1 / sqrt(n)
relative; 5 of those allowed). A quaternion track with sign flips (q and -q are one rotation) must
give the same noise as the track without them.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from euc_ros.core.mocap.noise import pose_noise
from euc_ros.core.mocap.series import MocapSeries

N = 6000


def series(sigma_p, sigma_q, flips=False, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(N) / 120.0
    pos = np.stack([3 * np.sin(0.3 * t), 0.5 * np.cos(0.7 * t), 1.0 + 0.02 * np.sin(2.0 * t)], axis=1)
    ang = 0.3 * np.sin(0.5 * t)
    quat = np.stack([np.cos(ang / 2), np.zeros(N), np.sin(ang / 2), np.zeros(N)], axis=1)
    quat = quat + rng.normal(0, sigma_q, quat.shape)
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    if flips:
        quat[N // 3:2 * N // 3] *= -1
        quat[5 * N // 6:] *= -1
    pos = pos + rng.normal(0, sigma_p, pos.shape)
    return MocapSeries(t=t, frame=np.arange(N), bodies=["b"], position=pos[None], quat=quat[None],
                       tracked=np.ones((1, N), bool), mean_marker_error=np.zeros((1, N)), name="n", meta={})


def test_white_noise_is_recovered():
    sp, sq = pose_noise(series(2e-4, 1e-3))
    rel = 5 * 1.1 / np.sqrt(3 * N)
    assert abs(sp[0] / 2e-4 - 1) < rel
    # each component carries sigma_q before normalisation; normalisation removes the radial part only
    assert abs(sq[0] / 1e-3 - 1) < 0.15


def test_sign_flips_of_quaternions_are_not_noise():
    a = pose_noise(series(2e-4, 1e-3, flips=False, seed=3))[1]
    b = pose_noise(series(2e-4, 1e-3, flips=True, seed=3))[1]
    # the flip samples themselves are excluded by nothing: the fourth differences around 3 flips touch 12
    # of 6000 samples, which the median ignores
    assert abs(b[0] / a[0] - 1) < 0.02
    s = series(0.0, 0.0)
    assert pose_noise(dataclasses.replace(s))[0][0] < 1e-7


def residual_change(states_a, states_b, params, x) -> float:
    """RMS [N m] of the base model's residual (parameters ``x``) of ``states_a`` minus that of ``states_b``, the
    same recordings with and without what is measured, over the samples both have."""
    from euc_ros.core.model.extended import Model
    from euc_ros.core.states.contexts import prepare

    diffs = []
    for sa, sb, ra, rb in zip(states_a, states_b, prepare(states_a, params), prepare(states_b, params)):
        a, b = np.full(len(sa.t), np.nan), np.full(len(sb.t), np.nan)
        va, ma = Model().residual(ra, x)
        vb, mb = Model().residual(rb, x)
        a[ra.index[ma]], b[rb.index[mb]] = va[ma], vb[mb]
        d = a - b
        diffs.append(d[np.isfinite(d)])
    return float(np.sqrt(np.mean(np.concatenate(diffs) ** 2)))


def test_the_noise_floor_is_the_noise_contribution_of_a_simulated_ride():
    """Known answer from the simulator: the residual of the noisy recording minus that of the same
    recording without noise (``mocap_clean``) is the noise's contribution. One re-noised realisation
    estimates its RMS with a relative standard error of about 1/sqrt(2 n_blocks), n_blocks ~ 60
    independent ~0.35 s stretches of filtered noise in 3 x 7 s (~0.09); 3 of those allowed."""
    from euc_ros.core.model.extended import Model
    from euc_ros.core.model.terms import EucParams
    from euc_ros.core.residual.noise import make_noise_floor
    from euc_ros.core.residual.selection import fit_base_h
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.states.contexts import prepare
    from euc_ros.core.states.kinematics import reconstruct_states

    ride = simulate_ride(RideConfig(maneuver="deceleration", runs=3, seed=11))
    p = EucParams.from_session(ride.session)
    noisy = [reconstruct_states(r.mocap, ride.session) for r in ride.runs]
    clean = [reconstruct_states(r.mocap_clean, ride.session) for r in ride.runs]
    x = np.array([fit_base_h(prepare(noisy, p))])
    truth = residual_change(noisy, clean, p, x)
    estimate = make_noise_floor([r.mocap for r in ride.runs], noisy, ride.session, p)(Model(), x)
    assert abs(estimate / truth - 1) < 3 * 0.09, (estimate, truth)


#: Rides of the sliding-floor test: drawn from a range by a fixed generator, not picked.
SLIDING_SEEDS = tuple(int(s) for s in np.random.default_rng(8061).choice(np.arange(300, 400), 2, replace=False))


@pytest.mark.parametrize("seed", SLIDING_SEEDS)
def test_the_sliding_floor_is_the_sliding_contribution_of_a_simulated_ride(seed):
    """Known answer: the residual of a recording with soft-tissue sliding minus that of the same recording
    without it (the simulator's poses, same pose noise) is the sliding's contribution. The floor's sliding
    part is one surrogate of the sliding the links measure (each body's RMS from ~14 links by non-negative
    least squares, about +-30 % per body; one realisation of 0.3-3 Hz sliding over 3 x 7 s, about +-10 %
    each for the truth and the surrogate): its ratio to the truth has a log-sd of about 0.33, and a factor
    of 2 either way is two of those. The artefact generator (:mod:`euc_ros.core.ridesim.artefacts`) shares
    no code with the analysis; its sliding is independent per body here (the floor's own model) and the
    rotation sliding its default pairing (0.4 deg per mm), which the surrogate does not add.
    The floor without the sliding part (the white pose noise only) is far below: it is what made every
    no-effect ride with sliding `unexplained`."""
    from euc_ros.core.model.extended import Model
    from euc_ros.core.model.terms import EucParams
    from euc_ros.core.residual.noise import make_noise_floor
    from euc_ros.core.residual.selection import fit_base_h
    from euc_ros.core.ridesim.artefacts import SoftTissueArtefacts, apply_artefacts
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.states.contexts import prepare
    from euc_ros.core.states.kinematics import reconstruct_states
    from euc_ros.core.states.link_sliding import estimate_sliding

    rng = np.random.default_rng(seed)
    mm = float(rng.uniform(2.0, 5.0))
    ride = simulate_ride(RideConfig(maneuver=("deceleration", "acceleration")[seed % 2], runs=3, seed=seed))
    p = EucParams.from_session(ride.session)
    art = SoftTissueArtefacts(slide_rms_m=1e-3 * mm, slide_rot_rms_deg=0.4 * mm, accel_share=0.0,
                              noise_pos_rms_m=0.0, noise_rot_rms_deg=0.0)
    slid = [apply_artefacts(r.mocap, art, rng)[0] for r in ride.runs]
    st_slid = [reconstruct_states(s, ride.session) for s in slid]
    st_plain = [reconstruct_states(r.mocap, ride.session) for r in ride.runs]
    x = np.array([fit_base_h(prepare(st_slid, p))])
    truth = residual_change(st_slid, st_plain, p, x)
    floor_of = make_noise_floor(slid, st_slid, ride.session, p, sliding=estimate_sliding(slid, ride.session))
    total = floor_of(Model(), x)
    parts = floor_of.parts
    assert 0.5 < parts["sliding"] / truth < 2.0, (mm, parts, truth)
    assert total == pytest.approx(np.hypot(parts["pose_noise"], parts["sliding"]))
    assert parts["pose_noise"] < 0.5 * truth, (parts, truth)
