"""Frame assembly from per-body poses and tracking statistics (euc_ros.core.ingest)."""
import numpy as np

from euc_ros.core.ingest import PoseSynchronizer, TrackingStats, replay_schedule

MS = 1_000_000


def test_frame_completes_when_every_body_reported():
    sync = PoseSynchronizer(["A", "B"], tolerance_s=0.002, timeout_s=0.05)
    assert sync.push("A", 100 * MS, [1, 2, 3], [0, 0, 0, 1]) == []
    out = sync.push("B", 100 * MS + 500_000, [4, 5, 6], [0, 0, 0, 1])   # within tolerance
    assert len(out) == 1
    f = out[0]
    assert f.stamp_ns == 100 * MS and f.tracked.tolist() == [True, True]
    np.testing.assert_array_equal(f.position, [[1, 2, 3], [4, 5, 6]])


def test_missing_body_is_untracked_never_zero():
    sync = PoseSynchronizer(["A", "B"], tolerance_s=0.002, timeout_s=0.02)
    sync.push("A", 0, [1, 1, 1], [0, 0, 0, 1])           # B never reports for this frame
    out = sync.push("A", 30 * MS, [2, 2, 2], [0, 0, 0, 1])  # 30 ms later: first frame expired
    assert len(out) == 1
    assert out[0].tracked.tolist() == [True, False]
    assert np.all(np.isnan(out[0].position[1])) and np.all(np.isnan(out[0].quat[1]))


def test_late_pose_is_dropped_and_counted():
    sync = PoseSynchronizer(["A"], tolerance_s=0.002)
    assert len(sync.push("A", 10 * MS, [0, 0, 0], [0, 0, 0, 1])) == 1
    assert sync.push("A", 5 * MS, [0, 0, 0], [0, 0, 0, 1]) == []
    assert sync.late_dropped == 1


def test_unknown_body_ignored():
    sync = PoseSynchronizer(["A"])
    assert sync.push("Z", 0, [0, 0, 0], [0, 0, 0, 1]) == []


def test_tracking_stats_counts_gaps_duplicates_and_lost():
    st = TrackingStats(["A", "B"], window=10, lost_after=3)
    seq = [0, 1, 2, 5, 5, 4, 6]          # 3,4 dropped; duplicate 5; 4 out of order
    accepted = [n for n in seq if st.accept(n)]
    assert accepted == [0, 1, 2, 5, 6]
    assert (st.dropped, st.duplicates, st.out_of_order) == (2, 1, 1)
    for k in range(5):
        st.update(np.array([True, k < 1]), k * 8_333_333)
    np.testing.assert_allclose(st.tracking_rate(), [1.0, 0.2])
    assert st.lost().tolist() == [False, True]
    assert abs(st.frame_rate_hz() - 120.0) < 0.01


def test_replay_schedule_scales_with_rate():
    t = np.array([10.0, 10.5, 11.0])
    np.testing.assert_allclose(replay_schedule(t, 2.0), [0, 0.25, 0.5])
