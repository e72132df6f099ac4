"""Tracking statistics: gaps, duplicates, restarts, lost bodies, rates (euc_ros.core.mocap.tracking).

Tolerances: rates are ratios of counts (one division: exact to an ulp).
"""
import numpy as np

from euc_ros.core.mocap.tracking import TrackingStats

MS = 1_000_000


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
