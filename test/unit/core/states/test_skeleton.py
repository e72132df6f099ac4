"""Skeleton-constrained CoG, against hand-built chains with known joints.

The poses are built here by hand (joint vectors in each bone's frame, rotations per frame), not by the
ride simulator: a tree chain whose joints bend over time (custom links) and a rigid rider in the
default link table (which has loops: pelvis, chest, head on both shoulders). Without noise the fitted
chain must be the measured one and G exact; with noise the fit is a weighted least-squares estimator
that uses every body's own measurement plus the joints, so its G error cannot exceed the per-segment
G's (both linear and unbiased; the fit's weights equal the noise), whose RMS follows from the noise
propagation written out below.
"""
# covers: euc_ros/core/identify/sliding.py
# covers: euc_ros/core/states/link_sliding.py
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.online.estimators import RiderStateEstimator
from euc_ros.core.rotations import quat_from_yaw_tilt_pitch
from euc_ros.core.session import Euc, Rider, Segment, Session, default_session
from euc_ros.core.states.geometry import frame_geometry
from euc_ros.core.states.kinematics import DEFAULT_WINDOW_S, reconstruct_states
from euc_ros.core.states.settings import ReconstructionSettings
from euc_ros.core.states.skeleton import OnlineSkeleton, SkeletonFitConfig, SkeletonModel, skeleton_cog

RATE = 120.0

# ---------------------------------------------------------------------------------------------------------------
# A tree chain with bending joints: E -> shank S -> thigh T -> trunk K -> arm U (custom links)
# ---------------------------------------------------------------------------------------------------------------
TREE_LINKS = (("E", "S"), ("S", "T"), ("T", "K"), ("K", "U"))
#: b's pivot in a's frame (the joint vectors) [m]
TREE_U = {("E", "S"): (0.0, 0.0, 0.05), ("S", "T"): (0.05, 0.0, 0.42), ("T", "K"): (-0.12, 0.0, 0.40),
          ("K", "U"): (0.05, -0.2, 0.45)}


def _tree_session():
    segs = {"S": Segment(0.2, (0.0, 0.0, 0.18)), "T": Segment(0.25, (0.0, 0.0, 0.2)),
            "K": Segment(0.45, (0.02, 0.0, 0.25)), "U": Segment(0.1, (0.0, 0.0, -0.15))}
    return Session(world_up="z", rate_hz=RATE, rider=Rider(65.0, 16.6, segs), euc=Euc())


def _tree_poses(n=400, seed=0):
    """Bodies E, S, T, K, U over n frames: each joint bends and twists by its own slow angles."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE
    R = {"E": Rotation.from_euler("ZXY", np.stack([0.3 + 0.2 * np.sin(0.7 * t), 0.05 * np.sin(1.3 * t),
                                                   0.1 * np.sin(2.1 * t)], -1))}
    P = {"E": np.stack([0.5 * t, 0.1 * np.sin(t), 0.6 + 0.0 * t], -1)}
    for a, b in TREE_LINKS:
        ph = rng.uniform(0, 2 * np.pi, 3)
        rel = Rotation.from_euler("xyz", np.stack([0.3 * np.sin(1.1 * t + ph[0]), 0.5 * np.sin(0.8 * t + ph[1]),
                                                   0.2 * np.sin(1.7 * t + ph[2])], -1))
        P[b] = P[a] + R[a].apply(TREE_U[(a, b)])
        R[b] = R[a] * rel
    bodies = ["S", "T", "K", "U", "E"]
    pos = np.stack([P[k] for k in bodies])
    quat = np.stack([R[k].as_quat() for k in bodies])
    return bodies, pos, quat


def _true_cog(session, bodies, pos, quat):
    names, fr, off = session.segment_arrays()
    G = 0.0
    for nm, f, o in zip(names, fr, off):
        i = bodies.index(nm)
        G = G + f * (pos[i] + Rotation.from_quat(quat[i].reshape(-1, 4)).apply(o).reshape(pos[i].shape))
    return G / fr.sum()


def test_tree_chain_exact_without_noise():
    session = _tree_session()
    bodies, pos, quat = _tree_poses()
    model = SkeletonModel.from_poses([pos], [quat], [None], bodies, session, links=TREE_LINKS)
    assert model.links == TREE_LINKS
    for (a, b), v in zip(model.links, model.vectors):
        np.testing.assert_allclose(v, TREE_U[(a, b)], atol=1e-12)
    out = skeleton_cog(pos, quat, None, session, bodies, model)
    np.testing.assert_allclose(out["G"], _true_cog(session, bodies, pos, quat), atol=1e-10)
    assert out["n_faults"].sum() == 0
    for i, nm in enumerate(model.bodies):
        j = bodies.index(nm)
        np.testing.assert_allclose(out["P_fit"][i], pos[j], atol=1e-10)
        np.testing.assert_allclose(out["R_fit"][i], Rotation.from_quat(quat[j]).as_matrix(), atol=1e-10)
    # one frame at a time (the live path) gives the same
    one = skeleton_cog(pos[:, 17], quat[:, 17], None, session, bodies, model)
    np.testing.assert_allclose(one["G"], out["G"][17], atol=1e-12)


# ---------------------------------------------------------------------------------------------------------------
# A rigid rider in the default link table (13 bodies + E), hand-built pivots and segment pitches
# ---------------------------------------------------------------------------------------------------------------
#: body -> (pivot in the rider frame [m], segment pitch [deg]); written for this test
RIDER = {
    "H": ((0.05, 0.0, 1.60), 5.0), "CHR": ((0.0, -0.19, 1.30), 8.0), "CHL": ((0.0, 0.19, 1.30), 8.0),
    "UAR": ((0.08, -0.22, 1.02), -10.0), "UAL": ((0.08, 0.22, 1.02), -10.0),
    "LAR": ((0.25, -0.21, 0.82), -45.0), "LAL": ((0.25, 0.21, 0.82), -45.0),
    "HR": ((-0.05, -0.1, 0.82), 0.0), "HL": ((-0.05, 0.1, 0.82), 0.0),
    "TR": ((0.12, -0.1, 0.43), -20.0), "TL": ((0.12, 0.1, 0.43), -20.0),
    "LR": ((0.0, -0.11, 0.0), 12.0), "LL": ((0.0, 0.11, 0.0), 12.0),
}


def _rider_series(n=600, seed=1, pos_sigma=0.0, rot_sigma=0.0):
    """Rigid rider on E: hinge A = E + (0, 0, 0.05), rider frame pitched by phi(t), plus white noise on
    the rider bodies."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE
    psi, theta, gamma = 0.2 * np.sin(0.5 * t), 0.03 * np.sin(1.1 * t), 0.05 * np.sin(1.9 * t)
    phi = 0.08 * np.sin(1.3 * t) + 0.03 * np.sin(3.1 * t)
    R_E = Rotation.from_quat(quat_from_yaw_tilt_pitch(psi, theta, gamma))
    R_L = Rotation.from_quat(quat_from_yaw_tilt_pitch(psi, theta, phi))
    E = np.stack([0.8 * t, 0.2 * np.sin(0.4 * t), 0.45 + 0.0 * t], -1)
    A = E + R_E.apply([0.0, 0.0, 0.05])
    bodies = list(RIDER) + ["E"]
    pos, quat = [], []
    for nm in RIDER:
        p, beta = RIDER[nm]
        pos.append(A + R_L.apply(p))
        quat.append((R_L * Rotation.from_euler("y", math.radians(beta))).as_quat())
    pos.append(E)
    quat.append(R_E.as_quat())
    pos, quat = np.stack(pos), np.stack(quat)
    clean = MocapSeries(t=t, frame=np.arange(n), bodies=bodies, position=pos.copy(), quat=quat.copy(),
                        tracked=np.ones((len(bodies), n), bool), mean_marker_error=np.zeros((len(bodies), n)),
                        name="hand", meta={"rate_hz": RATE})
    # the rider bodies slide; E (a hard shell, which the fit holds at its measurement) does not
    noisy_pos = pos + rng.normal(0.0, pos_sigma, pos.shape)
    rv = rng.normal(0.0, rot_sigma, pos.shape)
    noisy_pos[-1] = pos[-1]
    rv[-1] = 0.0
    noisy_q = (Rotation.from_quat(quat.reshape(-1, 4)) * Rotation.from_rotvec(rv.reshape(-1, 3))).as_quat()
    noisy = MocapSeries(t=t, frame=np.arange(n), bodies=bodies, position=noisy_pos, quat=noisy_q.reshape(quat.shape),
                        tracked=np.ones((len(bodies), n), bool), mean_marker_error=np.zeros((len(bodies), n)),
                        name="hand", meta={"rate_hz": RATE})
    return clean, noisy


@pytest.fixture(scope="module")
def session():
    return default_session("z")


def test_rigid_rider_exact_without_noise(session):
    clean, _ = _rider_series()
    model = SkeletonModel.estimate(clean, session)
    assert len(model.links) == 18
    geo_s = frame_geometry(clean.position, clean.quat, clean.tracked, session, clean.bodies)
    geo_k = frame_geometry(clean.position, clean.quat, clean.tracked, session, clean.bodies,
                           cog_method="skeleton", skeleton=model)
    np.testing.assert_allclose(geo_k["G"], geo_s["G"], atol=1e-10)
    np.testing.assert_allclose(geo_k["phi_hinge"], geo_s["phi_hinge"], atol=1e-10)
    assert geo_k["n_faults"].sum() == 0 and geo_s["n_faults"].sum() == 0


def test_noise_is_reduced_not_increased(session):
    """White pose noise, fit weights equal to it: the chain's G error <= the per-segment G error.

    Per-segment G error (independent bodies): ``Var(G_x) = sum f_i^2 (s_p^2 + s_r^2 |o_i x e_x|^2) / F^2``,
    ``F = sum f_i``, with ``s_p``, ``s_r`` per axis (a rotation vector ``w`` moves the CoM by ``R (w x o)``,
    whose variance along a world axis is ``s_r^2 (|o|^2 - (e . R o)^2)``; bounded here by ``s_r^2 |o|^2``).
    The chain fit is the weighted least-squares estimator with the same data plus exact joints, so its
    variance is at most that. Sampling tolerance of an RMS over N frames: 3 / sqrt(2 N) relative
    (frames are independent: white noise).
    """
    sp, sr = 0.004, math.radians(1.5)
    clean, noisy = _rider_series(n=600, seed=4, pos_sigma=sp, rot_sigma=sr)
    cfg = SkeletonFitConfig(pos_sigma_m=sp, rot_sigma_deg=math.degrees(sr), joint_sigma_m=1e-4)
    model = SkeletonModel.estimate(clean, session, config=cfg)
    G_true = frame_geometry(clean.position, clean.quat, None, session, clean.bodies)["G"]
    G_seg = frame_geometry(noisy.position, noisy.quat, None, session, noisy.bodies)["G"]
    G_sk = frame_geometry(noisy.position, noisy.quat, None, session, noisy.bodies, cog_method="skeleton",
                          skeleton=model)["G"]
    _, fr, off = session.segment_arrays()
    F = fr.sum()
    var_bound = np.sum(fr ** 2 * (sp ** 2 + sr ** 2 * np.sum(off ** 2, 1))) / F ** 2     # per axis
    rms_seg = np.sqrt(np.mean((G_seg - G_true) ** 2, axis=0))
    rms_sk = np.sqrt(np.mean((G_sk - G_true) ** 2, axis=0))
    tol = 1 + 3 / math.sqrt(2 * clean.n_frames)
    assert np.all(rms_seg <= math.sqrt(var_bound) * tol)
    assert np.all(rms_seg >= sp * math.sqrt(np.sum(fr ** 2)) / F / tol)   # the bound's position part alone
    assert np.all(rms_sk <= rms_seg * tol), (rms_sk, rms_seg)
    assert np.mean(rms_sk) < 0.8 * np.mean(rms_seg)                 # the joints carry real information


def _inject(series, flips=(), swaps=()):
    """Flip (180 deg about body x, pivot unchanged) or swap (pivot +jump, rotation +30 deg) bodies over frames."""
    pos, quat = series.position.copy(), series.quat.copy()
    for body, sl in flips:
        i = series.bodies.index(body)
        quat[i, sl] = (Rotation.from_quat(quat[i, sl]) * Rotation.from_rotvec([math.pi, 0, 0])).as_quat()
    for body, sl, jump in swaps:
        i = series.bodies.index(body)
        r = Rotation.from_quat(quat[i, sl])
        pos[i, sl] += r.apply(jump)
        quat[i, sl] = (r * Rotation.from_rotvec([0.0, math.radians(30.0), 0.0])).as_quat()
    return MocapSeries(series.t, series.frame, list(series.bodies), pos, quat, series.tracked.copy(),
                       series.mean_marker_error.copy(), series.name, dict(series.meta))


FLIPS = (("TR", slice(100, 103)), ("LAL", slice(200, 201)), ("CHR", slice(300, 304)), ("LR", slice(350, 352)))
SWAPS = (("CHL", slice(400, 430), (0.04, 0.0, 0.0)), ("H", slice(450, 470), (0.0, 0.03, 0.0)))


def test_flips_and_swaps_detected_excluded_counted(session):
    clean, noisy = _rider_series(n=600, seed=5, pos_sigma=0.001, rot_sigma=math.radians(0.3))
    bad = _inject(noisy, FLIPS, SWAPS)
    model = SkeletonModel.estimate(bad, session)        # the median ignores the few faulty frames
    out = skeleton_cog(bad.position, bad.quat, None, session, bad.bodies, model)
    expect = np.zeros(out["faults"].shape, bool)
    for body, sl in FLIPS:
        expect[model.bodies.index(body), sl] = True
    for body, sl, _ in SWAPS:
        expect[model.bodies.index(body), sl] = True
    np.testing.assert_array_equal(out["faults"], expect)
    assert int(out["n_faults"].sum()) == int(expect.sum())
    # excluded from G: the chain predicts them; the per-segment G takes the flipped poses in
    G_true = frame_geometry(clean.position, clean.quat, None, session, clean.bodies)["G"]
    G_seg = frame_geometry(bad.position, bad.quat, None, session, bad.bodies)["G"]
    G_ok = frame_geometry(noisy.position, noisy.quat, None, session, noisy.bodies)["G"]
    rows = expect.any(0)
    err_sk = np.linalg.norm(out["G"][rows] - G_true[rows], axis=1)
    err_seg = np.linalg.norm(G_seg[rows] - G_true[rows], axis=1)
    ok_rms = np.sqrt(np.mean(np.sum((G_ok - G_true) ** 2, 1)))     # the noise alone
    assert err_seg.max() > 0.02
    assert err_sk.max() < 6 * ok_rms + 1e-3, (err_sk.max(), ok_rms)
    # offline states count them, per body
    st = reconstruct_states(bad, session, cog_method="skeleton", skeleton=model)
    assert st.cog_method == "skeleton"
    assert st.meta["cog_faults"] == int(expect.sum())
    assert st.meta["cog_fault_bodies"] == {b: int(expect[model.bodies.index(b)].sum()) for b in
                                           {f[0] for f in FLIPS} | {s[0] for s in SWAPS}}


def test_option_threads_through_offline_and_live(session):
    clean, _ = _rider_series(n=500, seed=2)
    seg = reconstruct_states(clean, session)
    sk = reconstruct_states(clean, session, cog_method="skeleton")
    assert seg.cog_method == "segments" and seg.meta["cog_faults"] == 0
    ok = seg.valid & sk.valid
    assert ok.sum() > 200
    np.testing.assert_allclose(sk.phi[ok], seg.phi[ok], atol=1e-9)
    with pytest.raises(ConfigError, match="cog"):
        reconstruct_states(clean, session, cog_method="bones")
    with pytest.raises(ConfigError, match="cog"):
        frame_geometry(clean.position, clean.quat, None, session, clean.bodies, cog_method="bones")
    # live: the per-frame chain fit has no lag; states equal the offline ones (same filter, same G)
    est = RiderStateEstimator(session, 1.0 / RATE, settings=ReconstructionSettings(window_s=DEFAULT_WINDOW_S,
                              cog_method="skeleton"), skeleton_calibration_frames=120)
    assert est.cog_lag_s == 0.0
    est_seg = RiderStateEstimator(session, 1.0 / RATE)
    assert est.lag_s == est_seg.lag_s
    live = []
    for k in range(clean.n_frames):
        live += est.update(int(clean.frame[k]), float(clean.t[k]), clean.position[:, k], clean.quat[:, k],
                           clean.tracked[:, k], clean.bodies)
    phi = np.array([s.phi for s in live])
    frames = np.array([s.frame for s in live])
    good = np.isfinite(phi) & seg.valid[frames]
    assert good.sum() > 100
    np.testing.assert_allclose(phi[good], seg.phi[frames[good]], atol=1e-6)
    assert est.cog_faults == 0


def test_live_calibration_matches_offline_and_counts_faults(session):
    _, noisy = _rider_series(n=400, seed=6, pos_sigma=0.001, rot_sigma=math.radians(0.3))
    bad = _inject(noisy, flips=(("TR", slice(300, 303)),))
    live = OnlineSkeleton(session, calibration_frames=200)
    assert live.lag_s == 0.0
    G = []
    for k in range(bad.n_frames):
        G.append(live.update(bad.position[:, k], bad.quat[:, k], bad.tracked[:, k], bad.bodies)["G"])
        if k == 198:
            assert not live.calibrated
    assert live.calibrated
    off = SkeletonModel.estimate(bad, session, max_frames=200)
    np.testing.assert_allclose(live.model.vectors, off.vectors, atol=1e-12)
    np.testing.assert_allclose(live.model.threshold_m, off.threshold_m, atol=1e-12)
    assert live.fault_counts == {"TR": 3}
    offline = skeleton_cog(bad.position[:, 200:], bad.quat[:, 200:], None, session, bad.bodies, off)["G"]
    np.testing.assert_allclose(np.array(G[200:]), offline, atol=1e-9)


def test_bad_config():
    with pytest.raises(ConfigError, match="pos_sigma_m"):
        SkeletonFitConfig(pos_sigma_m=0.0)
    with pytest.raises(ConfigError, match="no chain link"):
        SkeletonModel.from_poses([np.zeros((1, 3, 3))], [np.tile([0, 0, 0, 1.0], (1, 3, 1))], [None], ["X"],
                                 default_session("z"), links=(("X", "Y"),))


def test_cli_option(tmp_path, capsys):
    """`identify --cog-method skeleton` reconstructs with the chain and reports the excluded body-frames;
    `residual` accepts the option."""
    import argparse
    import json

    from euc_ros.cli import residual as residual_cmd
    from euc_ros.cli.main import main
    from euc_ros.core.io.motive_csv import write_motive_csv
    from euc_ros.core.session import save_session

    session = default_session("z")
    save_session(session, tmp_path / "session.yaml")
    _, noisy = _rider_series(n=900, seed=7, pos_sigma=0.001, rot_sigma=math.radians(0.3))
    bad = _inject(noisy, flips=(("CHR", slice(400, 404)),))
    csv = write_motive_csv(bad, tmp_path / "hand.csv", world_up="z")
    out = tmp_path / "out.json"
    rc = main(["identify", str(tmp_path / "session.yaml"), str(csv), "--cog-method", "skeleton", "--json", str(out),
               "--no-uncertainty", "--no-progress"])
    assert rc == 0
    assert "body-frames excluded from G (swapped or flipped): 4 (CHR 4)" in capsys.readouterr().out
    js = json.loads(out.read_text())
    assert js["settings"]["cog_method"] == "skeleton"
    assert js["cog"]["excluded_body_frames"] == 4 and js["cog"]["per_body"] == {"CHR": 4}
    p = argparse.ArgumentParser()
    residual_cmd.add_arguments(p)
    assert p.parse_args(["s.yaml", "a.csv", "--json", "o.json", "--cog-method", "skeleton"]).cog_method == "skeleton"
    assert p.parse_args(["s.yaml", "a.csv", "--json", "o.json"]).cog_method == "segments"


def test_sliding_is_measured_from_the_links(session):
    """Independent band-limited sliding of every rider body (the artefact generator, 8 mm RMS): the links
    give each body's RMS within 25 % (a 7.5 s run holds ~40 independent samples per axis of a 0.3-3 Hz
    signal: the variance's relative sampling error ~ sqrt(2 / 120) = 13 %, the RMS's half of it, x3 plus
    the least-squares split over the links); no sliding gives (nearly) none and no SIMEX work."""
    from euc_ros.core.identify.sliding import MIN_SLIDING_M, estimate_sliding, sliding_bias
    from euc_ros.core.model.terms import EucParams
    from euc_ros.core.ridesim.artefacts import SoftTissueArtefacts, apply_artefacts

    clean, _ = _rider_series(n=900, seed=8)
    slid, _ = apply_artefacts(clean, SoftTissueArtefacts(slide_rms_m=0.008, slide_rot_rms_deg=0.0, accel_share=0.0,
                                                         noise_pos_rms_m=0.0, noise_rot_rms_deg=0.0),
                              np.random.default_rng(3))
    model = SkeletonModel.estimate(clean, session)
    est = estimate_sliding([slid], session, skeleton=model)
    np.testing.assert_allclose(est["rms_m"], 0.008, rtol=0.25)
    f, p = est["spectrum"]
    assert p[(f >= 0.3) & (f <= 3.0)].sum() > 0.99
    none = estimate_sliding([clean], session, skeleton=model)
    assert none["rms_max_m"] < 1e-9
    out = sliding_bias([clean], session, EucParams.from_session(session), 0.6, sliding=none)
    assert out["sliding_bias_m"] == 0.0 and none["rms_max_m"] < MIN_SLIDING_M
