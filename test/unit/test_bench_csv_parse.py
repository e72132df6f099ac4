"""The CSV parse benchmark's measurements on a short recording: every timed call made, the rate the fastest's.

Speed and memory figures are the benchmark's (``euc-ros bench --only csv_parse``), not asserted here.
"""
from __future__ import annotations

from euc_ros.bench import csv_parse


def test_each_reader_is_timed_repeatedly_and_reads_the_same_frames(short_ride):
    out, _ = short_ride
    path = str(next(out.glob("*.csv")))
    ours, floor = csv_parse.measure_ours(path), csv_parse.measure_numpy(path)
    for m in (ours, floor):
        assert len(m["walls_s"]) == csv_parse.REPEATS
        assert m["wall_s"] == min(m["walls_s"]) > 0.0
        assert m["rss"]["baseline_mb"] > 0.0
    assert ours["frames"] == floor["frames"] > 100
    assert csv_parse._spread([0.31, 0.29, 0.4]) == "0.29 s (0.29-0.40)"
