"""Each body's short gaps are bridged before the geometry, offline and live alike."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from euc_ros.core.mocap.bridging import PoseBridge, bridge_series, slerp
from euc_ros.core.mocap.series import MocapSeries

EPS = np.finfo(float).eps


def _series(n=200, seed=0):
    """Two bodies: one moving linearly, one rotating at a constant rate about a fixed axis."""
    frame = np.arange(n, dtype=np.int64)
    t = frame / 120.0
    pos = np.zeros((2, n, 3))
    pos[0] = np.column_stack([1.0 + 2.0 * t, -0.5 * t, 0.3 + 0 * t])
    pos[1] = np.column_stack([0 * t, 0 * t, 1.0 + 0 * t])
    axis = np.array([0.3, -0.4, 0.866])
    axis /= np.linalg.norm(axis)
    quat = np.zeros((2, n, 4))
    quat[0] = Rotation.from_rotvec(np.outer(0.1 * t, [0, 0, 1])).as_quat()
    quat[1] = Rotation.from_rotvec(np.outer(1.7 * t, axis)).as_quat()   # 1.7 rad/s
    tracked = np.ones((2, n), bool)
    return MocapSeries(t, frame, ["A", "B"], pos, quat, tracked, np.full((2, n), np.nan), "s", {})


def _blank(s, body, frames):
    s = dataclasses.replace(s, position=s.position.copy(), quat=s.quat.copy(), tracked=s.tracked.copy())
    s.tracked[body, frames] = False
    s.position[body, frames] = np.nan
    s.quat[body, frames] = np.nan
    return s


def test_linear_motion_and_constant_rate_rotation_are_bridged_exactly():
    ref = _series()
    gappy = _blank(_blank(ref, 0, [50, 51, 52]), 1, [80, 81, 82, 83, 84])
    out, bridged = bridge_series(gappy, max_gap=5)
    assert bridged.sum() == 8 and out.tracked.all()
    # linear interpolation of a linear motion, slerp of a rotation at constant rate about a fixed axis:
    # exact up to round-off (a few ulps of the ~3 m positions; slerp's trig: ~10 eps)
    np.testing.assert_allclose(out.position, ref.position, rtol=0, atol=16 * EPS * 4.0)
    dots = np.abs(np.sum(out.quat * ref.quat, axis=-1))
    assert np.all(1.0 - dots < 64 * EPS)


def test_gaps_longer_than_max_gap_stay_missing():
    gappy = _blank(_series(), 0, list(range(60, 66)))        # 6 frames
    out, bridged = bridge_series(gappy, max_gap=5)
    assert not bridged.any() and not out.tracked[0, 60:66].any() and np.isnan(out.position[0, 60:66]).all()
    # a gap at the very start or end has no neighbour on one side: never extrapolated
    edge = _blank(_series(), 1, [0, 1, 199])
    out, bridged = bridge_series(edge, max_gap=5)
    assert not bridged.any()


def test_skipped_frame_numbers_count_in_the_gap_length():
    s = _series()
    keep = np.ones(s.n_frames, bool)
    keep[[100, 101, 102]] = False                        # three frames never recorded
    s = MocapSeries(s.t[keep], s.frame[keep], s.bodies, s.position[:, keep], s.quat[:, keep], s.tracked[:, keep],
                    s.mean_marker_error[:, keep], "s", {})
    s = _blank(s, 0, [100, 101, 102])                      # rows 100-102 = frames 103-105: a 6-frame gap
    _, bridged = bridge_series(s, max_gap=5)
    assert not bridged.any()
    _, bridged = bridge_series(s, max_gap=6)
    assert bridged[0, 100:103].all()


@pytest.mark.parametrize("seed", range(3))
def test_live_bridge_gives_the_offline_poses(seed):
    rng = np.random.default_rng(seed)
    s = _series(n=400)
    pos = s.position + rng.normal(0, 1e-3, s.position.shape)
    quat = s.quat * np.where(rng.random(s.quat.shape[:2]) < 0.5, 1.0, -1.0)[..., None]   # sign flips
    lost = rng.random(s.tracked.shape) < 0.15              # runs of all lengths
    s = dataclasses.replace(s, position=np.where(lost[..., None], np.nan, pos), quat=quat, tracked=~lost)
    off, bridged = bridge_series(s, max_gap=3)
    br = PoseBridge(3)
    got = []
    for k in range(s.n_frames):
        got += br.push(int(s.frame[k]), float(s.t[k]), s.position[:, k], s.quat[:, k], s.tracked[:, k], s.bodies)
    got += br.reset()
    assert [g[0] for g in got] == list(s.frame)           # every frame, in order
    for g in got:
        k = g[0]
        np.testing.assert_array_equal(g[4], off.tracked[:, k])
        np.testing.assert_array_equal(g[5], bridged[:, k])
        np.testing.assert_allclose(g[2], off.position[:, k], rtol=0, atol=8 * EPS)
        ok = off.tracked[:, k]
        np.testing.assert_allclose(g[3][ok], off.quat[:, k][ok], rtol=0, atol=8 * EPS)


def test_slerp_takes_the_short_arc():
    q0 = np.array([0, 0, 0, 1.0])
    q1 = -Rotation.from_rotvec([0, 0, 0.2]).as_quat()      # same rotation as +q1
    mid = slerp(q0, q1, np.array(0.5))
    assert Rotation.from_quat(mid).magnitude() == pytest.approx(0.1, abs=1e-12)


# --- the examples, end to end ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def ride(tmp_path_factory):
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.session import save_session

    d = tmp_path_factory.mktemp("gaps")
    result = simulate_ride(RideConfig(runs=1, seed=5))
    save_session(dataclasses.replace(result.session, world_up="z"), d / "session.yaml")
    return d, result.runs[0].mocap


def _identify(d, rec, tmp_path):
    from euc_ros.cli.main import main

    out = tmp_path / f"{rec.name}.json"
    # one fixed filter for both files: the samples a recording gives depend on the window, which
    # identify otherwise chooses from each file's own spectrum
    assert main(["identify", str(d / "session.yaml"), str(rec), "--json", str(out), "--no-progress",
                 "--window-s", "1.2"]) == 0
    return json.loads(out.read_text())


def _flicker(series, rate, seed):
    rng = np.random.default_rng(seed)
    lost = rng.random(series.tracked.shape) < rate
    lost[:, 1:] &= ~lost[:, :-1]                            # single-frame flicker
    tracked = series.tracked & ~lost
    return dataclasses.replace(series, tracked=tracked, position=np.where(tracked[..., None], series.position, np.nan))


def test_one_blank_frame_of_the_euc_costs_no_sample(ride, tmp_path):
    """One interpolated frame: no sample lost, h unmoved (without bridging 551 of 696 samples are used and
    h moves 13 mm)."""
    from euc_ros.core.io.motive_csv import write_motive_csv

    d, series = ride
    clean = _identify(d, write_motive_csv(series, tmp_path / "clean.csv", world_up="z"), tmp_path)
    e = series.bodies.index("E")
    blank = dataclasses.replace(series, tracked=series.tracked.copy(), position=series.position.copy())
    blank.tracked[e, 420] = False
    blank.position[e, 420] = np.nan
    got = _identify(d, write_motive_csv(blank, tmp_path / "blank.csv", world_up="z"), tmp_path)
    a, b = clean["per_recording"][0], got["per_recording"][0]
    assert b["samples_used"] == a["samples_used"] and b["bridged_frames"] == 1
    # one interpolated pose among ~700 samples: h moves far less than its noise (~4 mm per run)
    assert abs(got["h_m"] - clean["h_m"]) < 1e-3


@pytest.mark.parametrize("rate", [0.01, 0.03, 0.05])
@pytest.mark.parametrize("kind", ["csv_flicker", "vrpn_loss"])
def test_flicker_and_message_loss_cost_at_most_the_bridged_samples(ride, tmp_path, rate, kind):
    """Before: 1 % flicker made identify fail; 1 % vrpn loss left 24 of 696 samples, h = 0.564."""
    from euc_ros.core.io.bags import write_mocap_bag
    from euc_ros.core.io.motive_csv import write_motive_csv

    d, series = ride
    clean = _identify(d, write_motive_csv(series, tmp_path / "clean.csv", world_up="z"), tmp_path)
    if kind == "csv_flicker":
        rec = write_motive_csv(_flicker(series, rate, 1), tmp_path / "f.csv", world_up="z")
    else:   # independent loss per body and message: runs of any length, published as PoseStamped per body
        rng = np.random.default_rng(2)
        lost = rng.random(series.tracked.shape) < rate
        s = dataclasses.replace(series, tracked=series.tracked & ~lost,
                                position=np.where(lost[..., None], np.nan, series.position))
        write_mocap_bag(s, tmp_path / "vrpn", frame_topic=None)
        rec = tmp_path / "vrpn"
    got = _identify(d, rec, tmp_path)
    a, b = clean["per_recording"][0], got["per_recording"][0]
    # independent loss leaves a run longer than max_gap = 5 with probability ~rate^6 per body-frame
    # (~2e-5 at 5 %): the only samples lost are at the recording's ends, where nothing follows a gap
    assert b["samples_used"] >= a["samples_used"] - 2
    assert b["bridged_frames"] > 0
    assert abs(got["h_m"] - clean["h_m"]) < 4e-3      # within one per-run noise sigma of h
    assert not got["warnings"]


def test_fewer_than_half_the_samples_used_is_a_warning(ride, tmp_path, capsys):
    from euc_ros.core.io.motive_csv import write_motive_csv

    d, series = ride
    e = series.bodies.index("E")
    s = dataclasses.replace(series, tracked=series.tracked.copy(), position=series.position.copy())
    s.tracked[e, 150:700] = False                          # the EUC lost for 4.6 s of 7
    s.position[e, 150:700] = np.nan
    got = _identify(d, write_motive_csv(s, tmp_path / "lost.csv", world_up="z"), tmp_path)
    err = capsys.readouterr().err
    assert got["per_recording"][0]["samples_used_fraction"] < 0.5
    assert any("lost" in w and "usable" in w for w in got["warnings"]) and "warning:" in err
