"""The live skeleton CoG benchmark's measurements (euc_ros.bench.skeleton), on a short recording.

Timings are the benchmark's (``euc-ros bench --only skeleton``), not asserted here: only that every pass is
timed on the frames after the calibration, for each method.
"""
from __future__ import annotations

import pytest

from euc_ros.bench import BENCHMARKS
from euc_ros.bench import skeleton as bench


def test_each_method_is_timed_per_frame(short_ride):
    out, _ = short_ride
    args = {"csv": str(next(out.glob("*.csv"))), "session_file": str(out / "session.yaml")}
    assert "skeleton" in BENCHMARKS
    for method in ("skeleton", "reference", "segments"):
        r = bench.measure(method=method, frames=10, repeats=2, **args)
        assert len(r["ms_per_frame"]) == 2 and all(t > 0 for t in r["ms_per_frame"])
        assert r["frames"] == 10 and r["bodies"] == 14
    with pytest.raises(ValueError, match="frames"):
        bench.measure(method="segments", frames=10_000, **args)
