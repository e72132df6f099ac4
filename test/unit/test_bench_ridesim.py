"""The ride-simulator benchmark's measurements (euc_ros.bench.ridesim), on one short run."""
from __future__ import annotations

from euc_ros.bench import BENCHMARKS
from euc_ros.bench import ridesim as bench


def test_measurements_report_cpu_time_and_real_time_factor():
    ride = bench.measure_ride(1, "compiled", repeats=2, duration_s=1.0)
    floor = bench.measure_integration(1, repeats=1, duration_s=1.0)
    assert "ridesim" in BENCHMARKS
    assert len(ride["cpu_s"]) == len(ride["wall_s"]) == len(ride["rtf"]) == 2
    assert ride["recorded_s"] == floor["recorded_s"] == 1.0
    for r in (ride, floor):
        assert all(c > 0 for c in r["cpu_s"])
        assert r["rtf"][0] == r["recorded_s"] / r["cpu_s"][0]
