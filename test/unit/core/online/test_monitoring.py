"""Health rules of the monitor (ROS-free): rate, dropouts, tracking, consistency, limits, staleness."""
from __future__ import annotations

import math

import numpy as np
import pytest

from euc_ros.core.online.monitoring import (
    ERROR,
    OK,
    STALE,
    WARN,
    Limit,
    PeakAbs,
    StreamWindow,
    consistency_health,
    limits_health,
    mocap_health,
    stale_health,
)


def _feed(window, rate_hz, seconds, *, start=0.0, skip_every=0, first_frame=0, lost=None):
    """Frames at ``rate_hz``; every ``skip_every``-th frame number is missing (never arrives)."""
    n = int(round(seconds * rate_hz))
    k = first_frame
    for i in range(n):
        if skip_every and k % skip_every == skip_every - 1:
            k += 1
        window.push(start + i / rate_hz, k, ["E", "CHL"], [True, not (lost and lost(k))])
        k += 1
    return start + (n - 1) / rate_hz


def test_a_healthy_stream_is_ok_and_its_rate_is_measured():
    w = StreamWindow(2.0)
    now = _feed(w, 120.0, 3.0)
    st = w.stats(now)
    # a count over a span of stamps i / 120 (< 3 s, ulp 4e-16 s): ~1e-15 relative; rel 1e-9 leaves 1e6x
    assert st["rate_hz"] == pytest.approx(120.0, rel=1e-9)
    assert st["frames"] == pytest.approx(240, abs=1) and st["missing"] == 0 and st["untracked"] == {}
    h = mocap_health(st, 120.0)
    assert h.level == OK and "120.0 Hz" in h.message and h.values["total_frames"] == 360


@pytest.mark.parametrize("rate, level", [(110.0, OK), (100.0, WARN), (59.0, ERROR), (240.0, OK)])
def test_rate_against_the_expected_rate(rate, level):
    w = StreamWindow(2.0)
    now = _feed(w, rate, 2.5)
    h = mocap_health(w.stats(now), 120.0, rate_tolerance=0.1)
    assert h.level == level
    assert h.values["rate_hz"] == pytest.approx(rate, rel=1e-6)


@pytest.mark.parametrize("skip_every, level", [(0, OK), (200, OK), (50, WARN), (5, ERROR)])
def test_dropouts_are_counted_from_the_frame_numbers(skip_every, level):
    w = StreamWindow(2.0)
    now = _feed(w, 120.0, 3.0, skip_every=skip_every)
    st = w.stats(now)
    # the window holds 240 received frames; one number in every skip_every is missing between them
    assert st["frames"] == pytest.approx(240, abs=1)
    expected = 0 if not skip_every else st["frames"] / (skip_every - 1)
    assert st["missing"] == pytest.approx(expected, abs=1)
    assert st["dropout_fraction"] == pytest.approx(st["missing"] / (st["frames"] + st["missing"]))
    h = mocap_health(st, 120.0, rate_tolerance=0.5, max_dropout_fraction=0.01)
    assert h.level == level
    assert ("dropped" in h.message) == (level != OK)


def test_a_restarted_numbering_is_not_a_dropout():
    w = StreamWindow(2.0)
    now = _feed(w, 120.0, 1.0, first_frame=5000)
    now = _feed(w, 120.0, 1.0, start=now + 1 / 120, first_frame=0)
    st = w.stats(now)
    assert st["missing"] == 0 and st["restarts"] == 1


def test_untracked_bodies_are_named():
    w = StreamWindow(2.0)
    now = _feed(w, 120.0, 2.0, lost=lambda k: k % 4 == 0)     # CHL lost in a quarter of the frames
    st = w.stats(now)
    assert st["untracked"]["CHL"] == pytest.approx(0.25, abs=0.01) and "E" not in st["untracked"]
    h = mocap_health(st, 120.0, max_untracked_fraction=0.1)
    assert h.level == WARN and "CHL" in h.message
    assert mocap_health(st, 120.0, max_untracked_fraction=0.3).level == OK


def test_staleness():
    w = StreamWindow(1.0)
    assert w.age(5.0) is None
    assert stale_health(w.age(5.0), 1.0, "frames").level == STALE
    _feed(w, 100.0, 0.5)
    assert stale_health(w.age(0.6), 1.0, "frames") is None
    h = stale_health(w.age(3.0), 1.0, "frames")
    assert h.level == STALE and "2.5 s" in h.message
    assert w.stats(3.0)["frames"] == 0 and math.isnan(w.stats(3.0)["rate_hz"])


@pytest.mark.parametrize("rmse, level", [(1.0, OK), (5.5, WARN), (10.5, ERROR), (float("nan"), WARN)])
def test_model_consistency_against_the_threshold(rmse, level):
    h = consistency_health(rmse, 5.0, residual_nm=0.3, h_online_m=0.6, model="3dof")
    assert h.level == level
    assert h.values["threshold_nm"] == 5.0 and h.values["model"] == "3dof"


def test_limits_use_the_peak_and_name_the_quantity():
    lean = limits_health([Limit("phi", -21.0, 20.0, "deg", latest=3.0)])
    assert lean.level == ERROR and "phi" in lean.message and "21.0 deg" in lean.message
    assert lean.values["phi_latest"] == 3.0
    att = limits_health([Limit("gamma", 5.0, 15.0, "deg"), Limit("theta", 26.0, 30.0, "deg")], warn_fraction=0.8)
    assert att.level == WARN and "theta" in att.message and "gamma" not in att.message
    ok = limits_health([Limit("M_d1", 50.0, 120.0, "N m")])
    assert ok.level == OK and "within limits" in ok.message
    gone = limits_health([Limit("phi", float("nan"), 20.0, "deg")], missing="rider not tracked")
    assert gone.level == WARN and "rider not tracked" in gone.message


def test_peak_tracker_keeps_the_largest_magnitude_per_period():
    p = PeakAbs()
    for v in (0.1, -0.5, float("nan"), 0.3):
        p.push(v)
    peak, latest, n, n_nan = p.take()
    assert (peak, latest, n, n_nan) == (-0.5, 0.3, 4, 1)
    assert np.isnan(p.take()[0])          # a new period starts empty
