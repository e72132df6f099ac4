"""Measured frame rate and its agreement with the session."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.mocap.rate import RateMeter, check_rate, measured_rate_hz
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.session import default_session


def _series(rate, n=600, drop=(), meta_rate=None, jitter_s=0.0, seed=0):
    frame = np.array([k for k in range(n) if k not in set(drop)], dtype=np.int64)
    t = frame / rate + np.random.default_rng(seed).normal(0.0, jitter_s, frame.size)
    b = 1
    meta = {} if meta_rate is None else {"rate_hz": meta_rate}
    return MocapSeries(t, frame, ["E"], np.zeros((b, frame.size, 3)), np.tile([0, 0, 0, 1.0], (b, frame.size, 1)),
                       np.ones((b, frame.size), bool), np.full((b, frame.size), np.nan), "rec", meta)


@pytest.mark.parametrize("rate", (30.0, 100.0, 120.0, 240.0, 359.87, 1000.0))
def test_measured_rate_ignores_dropped_frames_and_stamp_jitter(rate):
    s = _series(rate, drop=range(100, 130), jitter_s=0.2e-3)
    # slope of n stamps with jitter sigma over a span T: sd = sigma sqrt(12 / n) / T relative
    rel = 5 * 0.2e-3 * np.sqrt(12 / s.n_frames) / (s.t[-1] - s.t[0])
    assert s.rate_hz == pytest.approx(rate, rel=rel)


def test_series_rate_is_the_measured_one_not_the_header():
    s = _series(240.0, meta_rate=120.0)
    assert s.rate_hz == pytest.approx(240.0, rel=1e-9)


def test_measured_rate_without_frame_numbers_uses_the_median_spacing():
    t = np.cumsum(np.r_[0.0, np.full(299, 1 / 200)])
    t = np.delete(t, [50, 51, 120])              # lost messages
    assert measured_rate_hz(t) == pytest.approx(200.0, rel=1e-9)


def test_session_rate_off_by_more_than_one_percent_is_an_error_naming_both_rates():
    session = dataclasses.replace(default_session("z"), rate_hz=120.0)
    with pytest.raises(ConfigError) as e:
        check_rate(_series(240.0), session, "ride/run_01.csv")
    msg = str(e.value)
    assert "ride/run_01.csv" in msg and "rate_hz" in msg and "240" in msg and "120" in msg
    assert check_rate(_series(120.0 * 1.009), session, "a.csv") == []      # within 1 %


def test_header_rate_that_disagrees_with_the_frames_is_a_warning():
    session = dataclasses.replace(default_session("z"), rate_hz=240.0)
    w = check_rate(_series(240.0, meta_rate=120.0), session, "b.csv")
    assert len(w) == 1 and "b.csv" in w[0] and "120" in w[0] and "240" in w[0]


def test_rate_meter_decides_after_its_span_and_names_both_rates():
    m = RateMeter(120.0, min_span_s=0.3, min_frames=10)
    decided_at = next(k for k in range(1000) if m.add(k, int(round(k * 1e9 / 240.7))))
    assert decided_at == int(np.ceil(0.3 * 240.7))
    assert m.rate_hz == pytest.approx(240.7, rel=1e-6) and "240.7" in m.error and "120" in m.error
    ok = RateMeter(120.0, min_span_s=0.3)
    for k in range(60):
        ok.add(-1, int(round(k * 1e9 / 120.5)))   # no frame numbers, within 1 %
    assert ok.rate_hz == 120.0 and ok.error is None


@pytest.mark.shared
def test_measured_rate_of_real_motive_exports_is_their_export_rate(shared_dir):
    """Real exports from other labs (120, 360 Hz, and 240 Hz captured exported at 60 Hz)."""
    from euc_ros.core.io.motive_csv import read_motive_csv

    files = sorted((shared_dir / "data" / "motive_real").glob("*.csv"))
    assert files
    for f in files:
        s = read_motive_csv(f, world_up="y")
        assert measured_rate_hz(s.t, s.frame) == pytest.approx(s.meta["rate_hz"], rel=1e-9), f.name
        assert s.rate_hz == s.meta["rate_hz"]


def test_a_series_measures_its_rate_once_per_frames_arrays():
    """The rate is kept for the t and frame arrays it was measured on: a series given new arrays (dropped
    frames filled in, a shifted clock) is measured again, so the kept value is never a stale one."""
    n = 500
    frame = np.arange(n, dtype=np.int64)
    frame[100:] += 3                                          # three dropped frames
    s = MocapSeries(t=frame / 240.0, frame=frame, bodies=["E"], position=np.zeros((1, n, 3)),
                    quat=np.tile([0.0, 0.0, 0.0, 1.0], (1, n, 1)), tracked=np.ones((1, n), bool),
                    mean_marker_error=np.full((1, n), np.nan))
    assert s.rate_hz == pytest.approx(240.0, rel=1e-12)
    assert s.rate_hz == measured_rate_hz(s.t, s.frame)       # kept: the same value
    s.t = frame / 100.0                                       # new arrays: measured again
    assert s.rate_hz == pytest.approx(100.0, rel=1e-12)
    s.frame = np.arange(n, dtype=np.int64)                    # frames renumbered without the gap
    assert s.rate_hz == measured_rate_hz(s.t, s.frame) != pytest.approx(100.0, rel=1e-3)
