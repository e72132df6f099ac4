"""Frame assembly from per-body poses, tracking statistics, start stamps, NatNet frames (euc_ros.core.mocap.ingest).

Tolerances: assembled frames carry the poses of the messages; positions go through float32 where
the message type is float32 (1e-6 of a ~1.5 m value is 17x its half-ulp 6e-8); rates are ratios
of counts (one division: exact to an ulp).
"""
from datetime import datetime, timezone

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from euc_ros.core.io.natnet import FrameOfData, RigidBodyData
from euc_ros.core.mocap.ingest import (
    PoseSynchronizer,
    TrackingStats,
    capture_start_ns,
    format_capture_start,
    frame_from_natnet,
    natnet_capture_stamp,
    replay_schedule,
)

MS = 1_000_000
Q0 = [0, 0, 0, 1]


def test_frame_completes_when_every_body_reported():
    sync = PoseSynchronizer(["A", "B"], tolerance_s=0.002, timeout_s=0.05)
    assert sync.push("A", 100 * MS, [1, 2, 3], Q0) == []
    out = sync.push("B", 100 * MS + 500_000, [4, 5, 6], Q0)   # within tolerance
    assert len(out) == 1
    f = out[0]
    assert f.stamp_ns == 100 * MS and f.tracked.tolist() == [True, True] and f.frame_number == -1
    np.testing.assert_array_equal(f.position, [[1, 2, 3], [4, 5, 6]])


def test_missing_body_is_untracked_never_zero():
    sync = PoseSynchronizer(["A", "B"], tolerance_s=0.002, timeout_s=0.02)
    sync.push("A", 0, [1, 1, 1], Q0)             # B never reports for this frame
    out = sync.push("A", 30 * MS, [2, 2, 2], Q0)  # 30 ms later (stamp time): first frame expired
    assert len(out) == 1
    assert out[0].tracked.tolist() == [True, False]
    assert np.all(np.isnan(out[0].position[1])) and np.all(np.isnan(out[0].quat[1]))


def test_flush_uses_arrival_time_not_stamps():
    # stamps from another clock (a bag of 2024 replayed now): only the arrival clock decides expiry
    sync = PoseSynchronizer(["A", "B"], tolerance_s=0.002, timeout_s=0.05)
    bag = 1_714_644_900 * 10**9
    arrival = 5_000 * MS
    sync.push("A", bag, [1, 1, 1], Q0, arrival_ns=arrival)
    sync.push("A", bag + 8 * MS, [1, 1, 1], Q0, arrival_ns=arrival + 8 * MS)
    sync.push("B", bag + 8 * MS, [2, 2, 2], Q0, arrival_ns=arrival + 9 * MS)   # second frame complete, waits
    assert sync.flush(arrival + 40 * MS) == []                                # first frame still has time
    out = sync.flush(arrival + 51 * MS)
    assert [f.stamp_ns for f in out] == [bag, bag + 8 * MS]                   # expired one, then the complete one
    assert out[0].tracked.tolist() == [True, False] and out[1].tracked.tolist() == [True, True]


def test_duplicates_out_of_order_and_late_poses_are_counted():
    sync = PoseSynchronizer(["A", "B"], tolerance_s=0.002, timeout_s=0.05)
    sync.push("A", 10 * MS, [0, 0, 0], Q0)
    assert sync.push("A", 10 * MS, [9, 9, 9], Q0) == []              # duplicate while pending
    out = sync.push("B", 10 * MS, [1, 1, 1], Q0)
    assert len(out) == 1 and out[0].position[0].tolist() == [0, 0, 0]  # first pose kept
    assert sync.push("B", 10 * MS + 100, [1, 1, 1], Q0) == []         # duplicate of an emitted frame
    assert sync.push("A", 5 * MS, [0, 0, 0], Q0) == []                # older than the last frame
    assert (sync.duplicates, sync.out_of_order, sync.restarts) == (2, 1, 0)
    # a frame emitted by timeout without B: B's pose arriving afterwards is late, not a duplicate
    sync.push("A", 20 * MS, [0, 0, 0], Q0)
    assert len(sync.push("A", 80 * MS, [0, 0, 0], Q0)) == 1
    assert sync.push("B", 20 * MS, [0, 0, 0], Q0) == []
    assert (sync.duplicates, sync.out_of_order) == (2, 2)
    assert sync.late_dropped == 4


def test_restart_of_the_source_is_not_out_of_order():
    sync = PoseSynchronizer(["A"], tolerance_s=0.002, timeout_s=0.05, restart_s=1.0)
    for k in range(300):
        assert len(sync.push("A", 5_000 * MS + k * 10 * MS, [k, 0, 0], Q0)) == 1
    out = sync.push("A", 0, [0, 0, 0], Q0)              # stamps start again (replay looped, driver restarted)
    assert len(out) == 1 and out[0].stamp_ns == 0
    assert [len(sync.push("A", k * 10 * MS, [k, 0, 0], Q0)) for k in range(1, 5)] == [1, 1, 1, 1]
    assert (sync.restarts, sync.out_of_order, sync.duplicates) == (1, 0, 0)


@pytest.mark.parametrize("pos, quat", [([np.nan, 0, 0], Q0), ([0, 0, 0], [np.nan] * 4), ([0, 0, 0], [0, 0, 0, 0]),
                                       ([0, 0, 0], [0, 0, 0.5, 0.5])])
def test_invalid_pose_completes_the_frame_as_untracked(pos, quat):
    sync = PoseSynchronizer(["A", "B"])
    sync.push("A", 0, [1, 2, 3], Q0)
    out = sync.push("B", 0, pos, quat)
    assert len(out) == 1 and out[0].tracked.tolist() == [True, False]
    assert np.isnan(out[0].position[1]).all() and np.isnan(out[0].quat[1]).all()
    assert sync.invalid == 1


def test_quaternion_is_normalised_and_unknown_body_ignored():
    sync = PoseSynchronizer(["A"])
    assert sync.push("Z", 0, [0, 0, 0], Q0) == [] and sync.unknown_body == 1
    q = np.array([0.1, 0.2, 0.3, 0.9])
    q = q / np.linalg.norm(q) * (1 + 5e-4)
    f = sync.push("A", 0, [0, 0, 0], q)[0]
    assert abs(np.linalg.norm(f.quat[0]) - 1) < 1e-15


def test_tracking_stats_counts_gaps_duplicates_and_lost():
    st_ = TrackingStats(["A", "B"], window=10, lost_after=3)
    seq = [0, 1, 2, 5, 5, 4, 6]          # 3,4 dropped; duplicate 5; 4 out of order
    accepted = [n for n in seq if st_.accept(n)]
    assert accepted == [0, 1, 2, 5, 6]
    assert (st_.dropped, st_.duplicates, st_.out_of_order, st_.restarts) == (2, 1, 1, 0)
    for k in range(5):
        st_.update(np.array([True, k < 1]), k * 8_333_333)
    np.testing.assert_allclose(st_.tracking_rate(), [1.0, 0.2])
    assert st_.lost().tolist() == [False, True]
    assert abs(st_.frame_rate_hz() - 120.0) < 0.01


def test_frame_number_reset_is_a_restart_not_a_drop():
    st_ = TrackingStats(["A"], restart_frames=100)
    for n in range(5000, 5300):
        assert st_.accept(n, n * 8_333_333)
        st_.update(np.array([True]), n * 8_333_333)
    assert st_.accept(0, 0)                                        # Motive (or the replay) restarted
    st_.update(np.array([True]), 0)
    assert all(st_.accept(n, n * 8_333_333) for n in range(1, 50))
    assert (st_.restarts, st_.dropped, st_.out_of_order) == (1, 0, 0)
    assert not st_.accept(40) and st_.out_of_order == 1           # small step back: out of order
    assert np.isnan(st_.frame_rate_hz())                          # rate window started again (1 stamp)


def test_drops_from_stamps_when_there_is_no_frame_number():
    st_ = TrackingStats(["A"])
    stamps = [k * 10 * MS for k in range(10)] + [130 * MS, 140 * MS]    # 100, 110, 120 ms missing
    for s in stamps:
        assert st_.accept(-1, s)
        st_.update(np.array([True]), s)
    assert st_.dropped == 3 and st_.duplicates == 0
    assert st_.accept(-1, 0) and st_.restarts == 0           # stamps went back: the synchronizer counts it
    st_.update(np.array([True]), 0)
    assert np.isnan(st_.frame_rate_hz())                     # the rate window started again


def test_set_bodies_restarts_per_body_history():
    st_ = TrackingStats(["A"])
    st_.update(np.array([False]), 0)
    st_.set_bodies(["A", "B"])
    st_.update(np.array([True, True]), 10)
    assert st_.tracking_rate().tolist() == [1.0, 1.0] and st_.frames == 2


def test_replay_schedule_scales_with_rate():
    t = np.array([10.0, 10.5, 11.0])
    np.testing.assert_allclose(replay_schedule(t, 2.0), [0, 0.25, 0.5])
    with pytest.raises(ValueError):
        replay_schedule(t, 0.0)


def _utc_ns(*args) -> int:
    *whole, ms = args
    return int(datetime(*whole, tzinfo=timezone.utc).timestamp()) * 10**9 + ms * MS


@pytest.mark.parametrize("text, expected", [
    ("2024-05-02 10.15.00.000 AM", _utc_ns(2024, 5, 2, 10, 15, 0, 0)),
    ("2020-06-16 07.51.41.245 PM", _utc_ns(2020, 6, 16, 19, 51, 41, 245)),     # real export (rbm)
    ("2023-11-28 10.27.58.765 DU.", _utc_ns(2023, 11, 28, 22, 27, 58, 765)),   # Hungarian "du." = PM (ha5dzs)
    ("2020-01-16 07.07.59.330 ", _utc_ns(2020, 1, 16, 7, 7, 59, 330)),         # no marker (grvc)
    ("2020-01-16 12.30.00.000 AM", _utc_ns(2020, 1, 16, 0, 30, 0, 0)),
    ("2020-01-16 12.30.00.000 PM", _utc_ns(2020, 1, 16, 12, 30, 0, 0)),
    ("2020-01-16 19.30.00.5", _utc_ns(2020, 1, 16, 19, 30, 0, 500)),
])
def test_capture_start_time(text, expected):
    assert capture_start_ns(text) == expected


@pytest.mark.parametrize("text", ["", None, "yesterday", "2020-13-01 10.00.00.000", "2020-01-01 25.00.00.000"])
def test_unreadable_capture_start_is_none(text):
    assert capture_start_ns(text) is None


@settings(max_examples=200, deadline=None)
@given(st.integers(min_value=0, max_value=4_000_000_000_000))
def test_capture_start_round_trip_to_the_millisecond(ms):
    ns = ms * MS
    text = format_capture_start(ns)
    assert capture_start_ns(text) == ns
    assert text == datetime.fromtimestamp(ms / 1000, timezone.utc).strftime("%Y-%m-%d %I.%M.%S.") + \
        f"{ms % 1000:03d} " + ("PM" if (ms // 3_600_000) % 24 >= 12 else "AM")


def test_natnet_capture_stamp():
    assert natnet_capture_stamp(1_000 * MS, 0.0045) == (1_000 * MS - 4_500_000, True)
    assert natnet_capture_stamp(1_000 * MS, float("nan")) == (1_000 * MS, False)
    assert natnet_capture_stamp(1_000 * MS, 2.0, max_latency_s=1.0) == (1_000 * MS, False)
    assert natnet_capture_stamp(1_000 * MS, -0.001) == (1_000 * MS, False)


def test_frame_from_natnet_maps_names_validity_and_y_up():
    s = np.sqrt(0.5)
    rbs = [RigidBodyData(7, np.float32([0.1, 1.5, -0.2]), np.float32([s, 0, 0, s]), 0.0003, True),
           RigidBodyData(2, np.float32([0.0, 0.0, 0.0]), np.float32([0, 0, 0, 0]), 0.0, False),
           RigidBodyData(99, np.float32([1, 1, 1]), np.float32([0, 0, 0, 1]), 0.0, True)]   # no name
    m = FrameOfData(frame_number=42, rigid_bodies=rbs)
    f = frame_from_natnet(m, {7: "E", 2: "H", 99: ""}, ["H", "E", "CHR"], 123, world_up="y")
    assert (f.stamp_ns, f.frame_number, f.bodies) == (123, 42, ["H", "E", "CHR"])
    assert f.tracked.tolist() == [False, True, False]
    # Motive Y-up (X, Y, Z) -> Z-up (X, -Z, Y); a rotation of +90 deg about Motive X is +90 deg about Z-up x
    np.testing.assert_allclose(f.position[1], [0.1, 0.2, 1.5], atol=1e-6)
    np.testing.assert_allclose(f.quat[1], [s, 0, 0, s], atol=1e-6)
    assert f.mean_marker_error[1] == pytest.approx(0.0003)
    assert np.isnan(f.position[[0, 2]]).all() and np.isnan(f.quat[[0, 2]]).all()
    g = frame_from_natnet(m, {7: "E"}, ["E"], 0, world_up="z")
    np.testing.assert_allclose(g.position[0], [0.1, 1.5, -0.2], atol=1e-6)


def test_format_capture_start_rounds_to_the_millisecond_with_carry():
    ns = _utc_ns(2021, 12, 31, 23, 59, 59, 999) + 600_000          # 23:59:59.9996 -> next day
    assert format_capture_start(ns) == "2022-01-01 12.00.00.000 AM"
    assert format_capture_start(_utc_ns(2021, 6, 1, 12, 0, 0, 7) + 400_000) == "2021-06-01 12.00.00.007 PM"
