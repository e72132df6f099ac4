"""Frame assembly from per-body poses (euc_ros.core.mocap.synchronizer).

Tolerances: assembled frames carry the poses of the messages.
"""
import numpy as np
import pytest

from euc_ros.core.mocap.synchronizer import PoseSynchronizer

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
