"""Block-by-block reconstruction and re-noising (issue 15, memory) give what the whole-array code gives.

The references below are the whole-array versions the block code replaced (bridging and
``frame_geometry`` of the whole recording; ``add_pose_noise`` and ``renoise`` drawing all their
noise at once). Blocks are made small (64 frames) so a 3 s recording spans several, with gaps of
every length up to beyond ``max_gap`` placed across block edges.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from euc_ros.core.euc import blockwise

BLOCK = 64


@pytest.fixture(scope="module")
def ride(short_ride):
    from euc_ros.core.io.motive_csv import read_motive_csv
    from euc_ros.core.session import load_session

    out, _ = short_ride
    series = read_motive_csv(next(out.glob("*.csv")), world_up="y")
    session = load_session(out / "session.yaml")
    # gaps of 1..8 frames in several bodies, some across block edges (64, 128, ...)
    pos, quat, trk = series.position.copy(), series.quat.copy(), series.tracked.copy()
    for body, start, length in ((0, 62, 3), (1, 127, 1), (2, 190, 6), (3, 250, 8), (4, 5, 2), (0, 300, 5),
                                (5, 319, 4), (6, 0, 3)):
        trk[body, start:start + length] = False
        pos[body, start:start + length] = np.nan
        quat[body, start:start + length] = np.nan
    return dataclasses.replace(series, position=pos, quat=quat, tracked=trk), session


@pytest.fixture()
def small_blocks(monkeypatch):
    monkeypatch.setattr(blockwise, "BLOCK_FRAMES", BLOCK)


def test_block_geometry_equals_whole_recording(ride, small_blocks):
    from euc_ros.core.bridging import bridge_series
    from euc_ros.core.euc.kinematics import frame_geometry

    series, session = ride
    assert series.n_frames > 4 * BLOCK
    whole, bridged = bridge_series(series, 5)
    ref = frame_geometry(whole.position, whole.quat, whole.tracked, session, whole.bodies)
    geo, n_samples, n_frames = blockwise.block_geometry(series, session, 5)
    assert n_samples == int(bridged.sum()) > 0
    assert n_frames == int(bridged.any(axis=0).sum())
    for key in blockwise.GEOMETRY_KEYS:
        np.testing.assert_allclose(geo[key], ref[key], rtol=1e-12, atol=1e-12, err_msg=key)
        assert geo[key].dtype == np.asarray(ref[key]).dtype


def _add_pose_noise_whole(series, sigma_pos, sigma_rot, rng):
    from euc_ros.core.rotations import quat_from_rotvec, quat_multiply

    pos = series.position.copy()
    quat = series.quat.copy()
    for i in range(len(series.bodies)):
        if np.isfinite(sigma_pos[i]):
            pos[i] = pos[i] + rng.normal(0.0, sigma_pos[i], pos[i].shape)
        if np.isfinite(sigma_rot[i]):
            ok = np.all(np.isfinite(quat[i]), axis=1)
            dq = quat_from_rotvec(rng.normal(0.0, sigma_rot[i], (int(ok.sum()), 3)))
            qi = quat[i, ok] / np.linalg.norm(quat[i, ok], axis=1, keepdims=True)
            quat[i, ok] = quat_multiply(qi, dq)
    return pos, quat


def _renoise_whole(series, rng):
    from euc_ros.core.residual.noise import pose_noise

    sp, sq = pose_noise(series)
    pos = series.position + rng.normal(size=series.position.shape) * sp[:, None, None]
    quat = series.quat + rng.normal(size=series.quat.shape) * sq[:, None, None]
    quat /= np.linalg.norm(quat, axis=2, keepdims=True)
    return pos, quat


def _blocks(noisy, n, spans):
    pos = np.full((len(noisy.bodies), n, 3), np.nan)
    quat = np.full((len(noisy.bodies), n, 4), np.nan)
    for lo, hi in spans:
        p, q, _ = noisy.pose_block(lo, hi)
        pos[:, lo:hi], quat[:, lo:hi] = p, q
    return pos, quat


def test_pose_noise_series_is_add_pose_noise(ride, small_blocks):
    from euc_ros.core.euc.uncertainty import pose_noise_series

    series, _ = ride
    b, n = len(series.bodies), series.n_frames
    sp = np.full(b, 2e-4)
    sr = np.full(b, 0.008)
    sp[3], sr[5] = np.nan, np.nan                 # a body without position noise, one without rotation noise
    ref_rng, rng = np.random.default_rng(4), np.random.default_rng(4)
    ref = _add_pose_noise_whole(series, sp, sr, ref_rng)
    noisy = pose_noise_series(series, sp, sr, rng)
    assert rng.normal() == ref_rng.normal()          # the generator is left where the whole draw leaves it
    # odd spans across block edges, overlapping, in any order
    pos, quat = _blocks(noisy, n, [(100, 200), (0, 70), (60, 101), (199, n)])
    np.testing.assert_array_equal(pos, ref[0])
    np.testing.assert_array_equal(quat, ref[1])
    whole = noisy.materialize()
    np.testing.assert_array_equal(whole.position, ref[0])
    assert whole.tracked is series.tracked or np.array_equal(whole.tracked, series.tracked)


def test_renoised_is_renoise(ride, small_blocks):
    from euc_ros.core.residual.noise import renoised

    series, _ = ride
    n = series.n_frames
    ref_rng, rng = np.random.default_rng(9), np.random.default_rng(9)
    ref = _renoise_whole(series, ref_rng)
    noisy = renoised(series, rng)
    assert rng.normal() == ref_rng.normal()
    pos, quat = _blocks(noisy, n, [(0, 1), (1, 65), (65, 300), (300, n)])
    np.testing.assert_array_equal(pos, ref[0])
    np.testing.assert_array_equal(quat, ref[1])


def test_reconstruct_states_of_a_perturbed_series(ride, small_blocks):
    from euc_ros.core.euc.kinematics import reconstruct_states
    from euc_ros.core.residual.noise import renoised

    series, session = ride
    noisy = renoised(series, np.random.default_rng(1))
    a = reconstruct_states(noisy, session)
    b = reconstruct_states(noisy.materialize(), session)
    for key in ("gamma", "phi", "phi_ddot", "x_ddot", "C", "G", "valid"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    assert a.meta["bridged_samples"] == b.meta["bridged_samples"] > 0
