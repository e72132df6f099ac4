"""View decimation (euc_ros.core.mocap.decimation), with time as an argument.

NatNet frames are stamped with the receive time minus the reported latency, so their
stamps jitter by milliseconds around the 8.3 ms period of a 120 Hz capture. A real 120 Hz capture lost
the poses of 20-26 of 518 frames to the stamp rule (3/4 of the view period since the last frame shown);
decimated by frame number, every frame of a 120 Hz source is shown and every 3rd of a 360 Hz one,
whatever the jitter. The jitter here (2 ms rms, Gaussian, seeded) makes the stamp rule lose frames too
(asserted, so the test would notice if it stopped exercising the problem).
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.mocap.decimation import ViewDecimator

S0 = 1_700_000_000 * 10**9


def jittered(rate_hz: float, n: int, seed: int = 5, rms_s: float = 0.002, first: int = 1000) -> tuple:
    """Frame numbers and receive-minus-latency stamps [ns] of ``n`` frames at ``rate_hz``."""
    rng = np.random.default_rng(seed)
    k = np.arange(n)
    stamps = S0 + np.round((k / rate_hz + 0.004 + rng.normal(0.0, rms_s, n)) * 1e9).astype(np.int64)
    return first + k, stamps


def shown(dec: ViewDecimator, numbers, stamps) -> list[int]:
    return [int(n) for n, s in zip(numbers, stamps) if dec.due(int(n), int(s))]


def test_120hz_jittered_stamps_every_frame_shown():
    numbers, stamps = jittered(120.0, 600)
    assert shown(ViewDecimator(120.0), numbers, stamps) == numbers.tolist()            # rate measured
    assert shown(ViewDecimator(120.0, 120.0), numbers, stamps) == numbers.tolist()     # rate known
    by_stamp = shown(ViewDecimator(120.0), [-1] * len(stamps), stamps)
    assert len(by_stamp) < len(stamps) - 10                 # what the stamp rule did to such a capture


def test_360hz_jittered_stamps_every_third_frame():
    numbers, stamps = jittered(360.0, 1800, rms_s=0.001)
    dec = ViewDecimator(120.0, 360.0)                       # known rate: every 3rd from the first
    assert shown(dec, numbers, stamps) == numbers[::3].tolist()
    dec = ViewDecimator(120.0)                              # measured: every frame for 1 s, then every 3rd
    got = shown(dec, numbers, stamps)
    assert dec.factor == 3 and dec.source_rate_hz == pytest.approx(360.0, rel=0.01)
    measuring = [n for n, s in zip(numbers, stamps) if (s - stamps[0]) * 1e-9 < ViewDecimator.MEASURE_S]
    assert got[:len(measuring)] == measuring
    assert set(np.diff(got[len(measuring):])) == {3}


@pytest.mark.parametrize("rate, factor", [(30.0, 1), (100.0, 1), (120.0, 1), (180.0, 2), (240.0, 2), (360.0, 3),
                                          (480.0, 3), (479.5, 3), (480.5, 3)])
def test_factor_is_the_stamp_rule_for_regular_stamps(rate, factor):
    """At regular stamps the frame-number rule shows what the stamp rule showed (a measured 480.5 Hz is 480)."""
    assert ViewDecimator(120.0, rate).factor == factor
    if rate in (30.0, 100.0, 120.0, 180.0, 240.0, 360.0):
        n = 300
        stamps = S0 + np.round(np.arange(n) / rate * 1e9).astype(np.int64)
        by_stamp = shown(ViewDecimator(120.0), [-1] * n, stamps)
        by_number = shown(ViewDecimator(120.0, rate), np.arange(n), stamps)
        assert len(by_stamp) == len(by_number)


def test_dropped_frames_restart_and_no_decimation():
    dec = ViewDecimator(120.0, 360.0)
    numbers = [0, 1, 2, 3, 5, 7, 8, 9, 10, 13]              # 4, 6, 11, 12 dropped
    assert shown(dec, numbers, [S0] * len(numbers)) == [0, 3, 7, 10, 13]
    assert dec.due(2, S0) and not dec.due(3, S0) and dec.due(5, S0)     # numbering restarted at 2
    dec = ViewDecimator(0.0, 360.0)
    assert all(dec.due(n, S0) for n in range(10))


def test_measurement_restarts_with_the_numbering():
    numbers, stamps = jittered(360.0, 800, rms_s=0.0005)
    dec = ViewDecimator(120.0)
    shown(dec, numbers, stamps)
    assert dec.factor == 3
    assert dec.due(5, stamps[-1] + 10**9)                   # restart: shown, and measured again
    assert dec.factor is None and dec.due(6, stamps[-1] + 10**9 + 2_777_778)


def test_frames_without_numbers_are_decimated_by_stamp():
    stamps = S0 + np.round(np.arange(30) / 360.0 * 1e9).astype(np.int64)
    dec = ViewDecimator(120.0)
    assert [s for s in stamps if dec.due(-1, int(s))] == stamps[::3].tolist()
    assert dec.due(-1, int(stamps[0]))                      # stamps went back: shown
