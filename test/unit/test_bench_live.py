"""Pieces of the live benchmarks that can be checked without running them: the probe's raw reading,
the added bodies of the sweep recordings, the CPU-use arithmetic."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("euc_msgs.msg", reason="the euc_msgs interfaces are not built (./run setup)")

from euc_ros.bench import live_sweep  # noqa: E402
from euc_ros.bench.common import cpu_fraction, cpu_seconds  # noqa: E402
from euc_ros.bench.live_sweep import extra_bodies  # noqa: E402
from euc_ros.core.mocap.frame import Frame  # noqa: E402
from euc_ros.core.mocap.series import MocapSeries  # noqa: E402


def test_the_probe_reads_stamp_and_frame_number_from_raw_frames_of_either_serializer():
    from rclpy.serialization import serialize_message

    from euc_ros.bench.probe import Probe
    from euc_ros.ros import convert

    probe = Probe.__new__(Probe)          # the callback alone: no node needed
    probe.records = {"mocap/frame": []}
    from euc_msgs.msg import MocapFrame

    cb = probe._callback("mocap/frame", MocapFrame, "frame_number")
    for fid, n in (("world", 14), ("w", 3), ("a_longer_world", 0)):
        fr = Frame(1_700_000_123_456_789_012, 987654321, [f"B{i}" for i in range(n)], np.ones((n, 3)),
                   np.tile([0, 0, 0, 1.0], (n, 1)), np.ones(n, bool), np.zeros(n))
        cb(convert.frame_to_raw(fr, fid, 1))
        cb(serialize_message(convert.frame_to_msg(fr, fid, 1)))
    for _, stamp, number in probe.records["mocap/frame"]:
        assert stamp == 1_700_000_123_456_789_012 and number == 987654321


def test_added_bodies_are_shifted_copies_with_new_names():
    n = 50
    rng = np.random.default_rng(0)
    s = MocapSeries(np.arange(n) / 120.0, np.arange(n), ["E", "H"], rng.normal(size=(2, n, 3)),
                    rng.normal(size=(2, n, 4)), rng.random((2, n)) > 0.1, np.zeros((2, n)))
    out = extra_bodies(s, 7)
    assert out.bodies == ["E", "H", "E_c1", "H_c1", "E_c2", "H_c2", "E_c3"]
    assert out.position.shape == (7, n, 3) and out.quat.shape == (7, n, 4) and out.tracked.shape == (7, n)
    np.testing.assert_array_equal(out.position[4] - s.position[0], np.broadcast_to([0.0, 6.0, 0.0], (n, 3)))
    np.testing.assert_array_equal(out.tracked[3], s.tracked[1])
    assert extra_bodies(s, 2) is s


def test_cpu_fraction_interpolates_and_refuses_intervals_outside_the_samples():
    series = [(10.0, 1.0), (11.0, 1.5), (12.0, 2.5)]
    assert cpu_fraction(series, 10.0, 12.0) == pytest.approx(0.75)
    assert cpu_fraction(series, 10.5, 11.5) == pytest.approx((2.0 - 1.25) / 1.0)
    assert np.isnan(cpu_fraction(series, 5.0, 12.0)) and np.isnan(cpu_fraction(series[:1], 10.0, 11.0))
    import os

    assert cpu_seconds(os.getpid()) > 0 and cpu_seconds(2**22 + 12345) is None


def test_the_full_sweep_is_every_rate_with_every_body_count_and_the_quick_one_a_part_of_it():
    full, quick = live_sweep.CELLS[False], live_sweep.CELLS[True]
    assert sorted(full) == sorted({(r, n) for r in live_sweep.RATES_HZ for n in live_sweep.BODIES})
    assert len(full) == len(live_sweep.RATES_HZ) * len(live_sweep.BODIES)
    assert set(quick) < set(full) and len(set(quick)) == len(quick)
    assert live_sweep.CELL_S[True] < live_sweep.CELL_S[False]
