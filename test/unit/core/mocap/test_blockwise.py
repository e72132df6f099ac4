"""Block-by-block reconstruction and re-noising give what the whole-array code gives.

The geometry's reference is the whole-array version the block code replaced (bridging and
``frame_geometry`` of the whole recording). The re-noised recordings draw their noise per block
(:class:`~euc_ros.core.mocap.blocks.BlockNoise`): any spans read must give the whole recording, and
the noise added must have the stated sizes. Blocks are made small (64 frames) so a 3 s recording
spans several, with gaps of every length up to beyond ``max_gap`` placed across block edges.
"""
# covers: euc_ros/core/mocap/blocks.py
# covers: euc_ros/core/mocap/noise.py
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from euc_ros.core.mocap import blocks
from euc_ros.core.states import geometry

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
    monkeypatch.setattr(blocks, "BLOCK_FRAMES", BLOCK)
    monkeypatch.setattr(blocks, "READ_FRAMES", BLOCK)


def test_block_geometry_equals_whole_recording(ride, small_blocks):
    from euc_ros.core.mocap.bridging import bridge_series
    from euc_ros.core.states.geometry import frame_geometry

    series, session = ride
    assert series.n_frames > 4 * BLOCK
    whole, bridged = bridge_series(series, 5)
    ref = frame_geometry(whole.position, whole.quat, whole.tracked, session, whole.bodies)
    geo, n_samples, n_frames = geometry.block_geometry(series, session, 5)
    assert n_samples == int(bridged.sum()) > 0
    assert n_frames == int(bridged.any(axis=0).sum())
    for key in geometry.GEOMETRY_KEYS:
        np.testing.assert_allclose(geo[key], ref[key], rtol=1e-12, atol=1e-12, err_msg=key)
        assert geo[key].dtype == np.asarray(ref[key]).dtype


def _blocks(noisy, n, spans):
    pos = np.full((len(noisy.bodies), n, 3), np.nan)
    quat = np.full((len(noisy.bodies), n, 4), np.nan)
    for lo, hi in spans:
        p, q, _ = noisy.pose_block(lo, hi)
        pos[:, lo:hi], quat[:, lo:hi] = p, q
    return pos, quat


def _z_bound(m: int) -> float:
    """Bound on |sample std / sigma - 1| of m Gaussian draws: the std's relative standard error is
    1 / sqrt(2 m); 5 of those (a false failure once in ~3.5 million runs)."""
    return 5.0 / np.sqrt(2.0 * m)


def test_pose_noise_series_blocks_are_one_recording(ride, small_blocks):
    """Any spans, overlapping and out of order, give the poses of the whole; the same seed gives the same noise."""
    from euc_ros.core.mocap.noise import pose_noise_series

    series, _ = ride
    b, n = len(series.bodies), series.n_frames
    sp, sr = np.full(b, 2e-4), np.full(b, 0.008)
    noisy = pose_noise_series(series, sp, sr, np.random.default_rng(4))
    whole = noisy.materialize()
    pos, quat = _blocks(noisy, n, [(100, 200), (0, 70), (60, 101), (199, n)])
    np.testing.assert_array_equal(pos, whole.position)
    np.testing.assert_array_equal(quat, whole.quat)
    again = pose_noise_series(series, sp, sr, np.random.default_rng(4)).materialize()
    np.testing.assert_array_equal(again.position, whole.position)
    other = pose_noise_series(series, sp, sr, np.random.default_rng(5)).materialize()
    assert not np.array_equal(np.nan_to_num(other.position), np.nan_to_num(whole.position))
    assert whole.tracked is series.tracked or np.array_equal(whole.tracked, series.tracked)


def test_a_released_recording_reads_the_same_poses(ride, small_blocks):
    """Releasing a re-noised recording (after a pass of the geometry) drops its kept noise blocks; reading it
    again draws them again, the same numbers."""
    from euc_ros.core.mocap.noise import pose_noise_draws, pose_noise_series

    series, session = ride
    draws = pose_noise_draws(series, np.random.default_rng(4))
    noisy = pose_noise_series(series, np.full(len(series.bodies), 2e-4), np.full(len(series.bodies), 0.008),
                              noise=draws)
    first = noisy.pose_block(0, 3 * BLOCK)
    assert draws._cache
    blocks.release(noisy)
    assert not draws._cache
    again = noisy.pose_block(0, 3 * BLOCK)
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)
    geometry.block_geometry(noisy, session, 5)           # a whole pass leaves nothing kept
    assert not draws._cache
    blocks.release(series)                               # a plain recording has nothing to release


def test_a_forward_pass_draws_each_block_once_and_keeps_about_one(ride, small_blocks, monkeypatch):
    """The geometry's pass over a re-noised recording (reads with margins, across the blocks' edges) draws
    every noise block once and never holds two whole blocks: the block before the one drawn keeps only its
    last READ_FRAMES frames."""
    from euc_ros.core.mocap.noise import pose_noise_draws, pose_noise_series

    monkeypatch.setattr(blocks, "READ_FRAMES", 16)      # reads of 16 frames and margins of 6: 4 reads a block
    series, session = ride
    b = len(series.bodies)
    draws = pose_noise_draws(series, np.random.default_rng(4))
    noisy = pose_noise_series(series, np.full(b, 2e-4), np.full(b, 0.008), noise=draws)
    seen, kept = [], []
    part = draws._part

    def counting(k, a):
        before = set(draws._cache)
        out = part(k, a)
        if k not in before or draws._cache[k][0] > a:
            seen.append(k)
        kept.append(sum(z.shape[1] for _, z in draws._cache.values()))
        return out

    draws._part = counting
    geometry.block_geometry(noisy, session, 5)
    n_blocks = -(-series.n_frames // BLOCK)
    assert sorted(seen) == list(range(n_blocks))         # each block drawn once
    assert max(kept) <= BLOCK + 16
    whole = pose_noise_series(series, np.full(b, 2e-4), np.full(b, 0.008), noise=draws).materialize()
    reread = _blocks(noisy, series.n_frames, [(a, min(a + 50, series.n_frames)) for a in range(0, series.n_frames, 50)])
    np.testing.assert_array_equal(reread[0], whole.position)


def test_pose_noise_series_adds_the_stated_noise(ride, small_blocks):
    """Position offsets of sigma_pos per axis, body-frame rotations of sigma_rot per axis, nothing where a
    sigma is NaN, and sign=-1 the mirror image of the same draws (antithetic SIMEX)."""
    from euc_ros.core.mocap.noise import pose_noise_draws, pose_noise_series
    from euc_ros.core.rotations import quat_conjugate, quat_multiply, rotvec_from_quat

    series, _ = ride
    b = len(series.bodies)
    sp, sr = np.full(b, 2e-4), np.full(b, 0.008)
    sp[3], sr[5] = np.nan, np.nan                 # a body without position noise, one without rotation noise
    draws = pose_noise_draws(series, np.random.default_rng(4))
    plus = pose_noise_series(series, sp, sr, noise=draws).materialize()
    minus = pose_noise_series(series, sp, sr, noise=draws, sign=-1.0).materialize()
    dp = plus.position - series.position
    fin = np.isfinite(dp)
    keep = np.ones(b, bool)
    keep[3] = False
    z = dp[keep][fin[keep]] / 2e-4
    assert abs(np.std(z) - 1.0) < _z_bound(z.size) and abs(np.mean(z)) < 5.0 / np.sqrt(z.size)
    np.testing.assert_array_equal(plus.position[3], series.position[3])
    np.testing.assert_allclose(minus.position - series.position, -dp, rtol=0, atol=1e-15)
    ok = np.all(np.isfinite(series.quat), axis=2)
    qn = series.quat / np.linalg.norm(series.quat, axis=2, keepdims=True)
    rot = rotvec_from_quat(quat_multiply(quat_conjugate(qn[ok]), plus.quat[ok]))        # body-frame rotation
    rot_minus = rotvec_from_quat(quat_multiply(quat_conjugate(qn[ok]), minus.quat[ok]))
    body = np.broadcast_to(np.arange(b)[:, None], ok.shape)[ok]
    r = rot[body != 5] / 0.008
    assert abs(np.std(r) - 1.0) < _z_bound(r.size)
    np.testing.assert_allclose(rot_minus, -rot, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(plus.quat[5], series.quat[5])


def test_renoised_blocks_are_one_recording_with_the_estimated_noise(ride, small_blocks):
    from euc_ros.core.mocap.noise import pose_noise, renoised

    series, _ = ride
    n = series.n_frames
    noisy = renoised(series, np.random.default_rng(9))
    whole = noisy.materialize()
    pos, quat = _blocks(noisy, n, [(0, 1), (1, 65), (65, 300), (300, n)])
    np.testing.assert_array_equal(pos, whole.position)
    np.testing.assert_array_equal(quat, whole.quat)
    sp, _ = pose_noise(series)
    dp = (whole.position - series.position) / sp[:, None, None]
    z = dp[np.isfinite(dp)]
    assert abs(np.std(z) - 1.0) < _z_bound(z.size)
    np.testing.assert_allclose(np.linalg.norm(whole.quat, axis=2)[np.isfinite(whole.quat[..., 0])], 1.0, atol=1e-12)


def test_reconstruct_states_of_a_perturbed_series(ride, small_blocks):
    from euc_ros.core.mocap.noise import renoised
    from euc_ros.core.states.kinematics import reconstruct_states

    series, session = ride
    noisy = renoised(series, np.random.default_rng(1))
    a = reconstruct_states(noisy, session)
    b = reconstruct_states(noisy.materialize(), session)
    for key in ("gamma", "phi", "phi_ddot", "x_ddot", "C", "G", "valid"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    assert a.meta["bridged_samples"] == b.meta["bridged_samples"] > 0


@pytest.mark.parametrize("cog_method", ["segments", "skeleton"])
def test_several_filters_from_one_geometry_are_each_filter_alone(ride, cog_method):
    """``reconstruct_states_filters`` gives, per filter, exactly the states of ``reconstruct_states``, and
    no two filters' states share an array (one may be changed without touching the other)."""
    from euc_ros.core.states.kinematics import reconstruct_states, reconstruct_states_filters

    series, session = ride
    filters = [(0.5, 4), (1.2, 6), (0.3, 2)]
    many = reconstruct_states_filters(series, session, filters, cog_method=cog_method)
    assert len(many) == len(filters)
    for (w, p), st in zip(filters, many):
        alone = reconstruct_states(series, session, window_s=w, polyorder=p, cog_method=cog_method)
        for f in dataclasses.fields(st):
            a, b = getattr(st, f.name), getattr(alone, f.name)
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b, err_msg=f"{f.name} at {(w, p)}")
            elif f.name == "meta":
                assert {k: v for k, v in a.items() if k != "cog_fault_bodies"} == \
                    {k: v for k, v in b.items() if k != "cog_fault_bodies"}
            else:
                assert a == b, f.name
    for f in ("G", "phi_hinge", "psi", "theta", "has_rider"):
        arrays = [getattr(st, f) for st in many]
        assert not any(np.shares_memory(arrays[i], arrays[j]) for i in range(3) for j in range(i + 1, 3)), f


def test_states_filter_by_filter_are_made_when_asked_for(ride):
    """``iter_states_filters`` makes each filter's states when asked for (the geometry once, at the first):
    a caller that drops each before the next never holds two, and each is the filter's states alone."""
    import gc
    import weakref

    from euc_ros.core.states.kinematics import iter_states_filters, reconstruct_states

    series, session = ride
    filters = [(0.5, 4), (1.2, 6)]
    made = iter_states_filters(series, session, filters)
    first = next(made)
    alive = weakref.ref(first)
    gamma = first.gamma.copy()
    del first
    gc.collect()
    assert alive() is None                         # nothing else holds the first filter's states
    second = next(made)
    with pytest.raises(StopIteration):
        next(made)
    np.testing.assert_array_equal(gamma, reconstruct_states(series, session, window_s=0.5, polyorder=4).gamma)
    np.testing.assert_array_equal(second.phi_ddot,
                                  reconstruct_states(series, session, window_s=1.2, polyorder=6).phi_ddot)


def test_data_filters_make_the_data_filtered_states():
    """The residual's lazily made states of the data's filter and its probe are data_filtered's."""
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.states.filter_choice import data_filtered, data_filters

    sim = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=3))
    series, session = sim.runs[0].mocap, sim.session
    chosen, probe, ratio = data_filtered([series], session, "hinge")
    make_chosen, make_probe, ratio2 = data_filters([series], session, "hinge")
    assert ratio2 == ratio or (np.isnan(ratio) and np.isnan(ratio2))
    assert (probe is None) == (make_probe is None)
    pairs = [(chosen, make_chosen())] + ([(probe, make_probe())] if probe is not None else [])
    for a, b in pairs:
        for key in ("gamma", "phi", "phi_ddot", "x_ddot", "C", "G", "valid"):
            np.testing.assert_array_equal(getattr(a[0], key), getattr(b[0], key), err_msg=key)
