"""The growth benchmark's analysis (exponents, ratios) and its derived recordings, on small inputs.

Speed and memory figures are the benchmark's (``euc-ros bench --only growth``), not asserted here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from euc_ros.bench import growth


def test_exponents_of_power_laws():
    m = [1.0, 10.0, 60.0]
    assert growth.loglog_slope(m, [2.0 * x for x in m]) == pytest.approx(1.0)
    assert growth.endpoint_exponent(m, [3.0 * x ** 1.5 for x in m]) == pytest.approx(1.5)
    # a fixed cost lowers the end-to-end exponent below 1; the last step shows the linear part
    t = [5.0 + 2.0 * x for x in m]
    assert growth.endpoint_exponent(m, t) < 1.0
    assert growth.incremental_ratio(m, t) == pytest.approx(2.0)
    assert math.isnan(growth.loglog_slope([1.0], [1.0]))
    assert math.isnan(growth.endpoint_exponent([1.0, 10.0], [0.0, 1.0]))


def test_summarize_ratios():
    loads = [{"wall_s": 0.25, "arrays_mb": 6.0}, {"wall_s": 2.5, "arrays_mb": 60.0}]
    runs = {"identify": [{"wall_s": 2.0, "peak_mb": 120.0, "above_mb": 9.0, "baseline_mb": 111.0},
                         {"wall_s": 20.0, "peak_mb": 201.0, "above_mb": 90.0, "baseline_mb": 111.0}]}
    s = growth.summarize([1.0, 10.0], loads, runs)
    c = s["commands"]["identify"]
    assert c["time_exponent"] == pytest.approx(1.0)
    assert c["s_per_min"] == pytest.approx([2.0, 2.0])
    assert c["above_per_arrays"] == pytest.approx([1.5, 1.5])
    assert c["memory_per_arrays_slope"] == pytest.approx(81.0 / 54.0)
    assert c["memory_slope_mb_per_min"] == pytest.approx(9.0)
    figs = growth._figures(s)
    ratio = next(f for f in figs if "arrays' size" in f["metric"])
    assert ratio["met"] is True and ratio["value"] == pytest.approx(1.5)


def _csv(path, frames, rate=120.0):
    head = ("Format Version,1.23,Take Name,x,Export Frame Rate,120.000000,Total Frames in Take,%d,"
            "Total Exported Frames,%d,Rotation Type,Quaternion\r\n\r\n,Type,Rigid Body,Rigid Body\r\n,Name,E,E\r\n"
            ",ID,1,1\r\n,,Position,Position\r\nFrame,Time (Seconds),X,Y\r\n") % (frames[-1] + 1, len(frames))
    rows = "".join(f"{f},{f / rate:.6f},{f}.5,{f}.25\r\n" for f in frames)
    path.write_text(head + rows, encoding="utf-8", newline="")


def test_derive_csv_repeats_with_continuous_frames_and_blank_seams(tmp_path):
    base = tmp_path / "base.csv"
    _csv(base, [0, 1, 2, 4, 5])                   # frame 3 dropped: span 6
    out = tmp_path / "long.csv"
    n = growth.derive_csv(base, out, 15, 120.0, seam_frames=2)
    lines = out.read_bytes().decode("utf-8").split("\r\n")
    assert "Total Frames in Take,15,Total Exported Frames,%d" % n in lines[0]
    data = [ln.split(",") for ln in lines[7:] if ln]
    assert len(data) == n == 13                    # 5 + 5 + frames 12, 13, 14 of the third repeat
    assert [int(r[0]) for r in data] == [0, 1, 2, 4, 5, 6, 7, 8, 10, 11, 12, 13, 14]
    assert data[5] == ["6", "0.050000", "", ""] and data[6] == ["7", "0.058333", "", ""]   # seam: untracked
    assert data[7] == ["8", "0.066667", "2.5", "2.25"]                         # the base's cells
    short = tmp_path / "short.csv"
    assert growth.derive_csv(base, short, 3, 120.0) == 3


def test_series_nbytes_counts_every_array():
    from euc_ros.core.mocap.series import MocapSeries

    b, n = 2, 10
    s = MocapSeries(t=np.zeros(n), frame=np.zeros(n, np.int64), bodies=["a", "b"], position=np.zeros((b, n, 3)),
                    quat=np.zeros((b, n, 4)), tracked=np.zeros((b, n), bool), mean_marker_error=np.zeros((b, n)))
    assert growth.series_nbytes(s) == n * 16 + b * n * (24 + 32 + 1 + 8)
