"""Replay clock, view decimation and stream silence of the ingest (euc_ros.core.mocap.ingest), with time as an argument.

View decimation: NatNet frames are stamped with the receive time minus the reported latency, so their
stamps jitter by milliseconds around the 8.3 ms period of a 120 Hz capture. A real 120 Hz capture lost
the poses of 20-26 of 518 frames to the stamp rule (3/4 of the view period since the last frame shown);
decimated by frame number, every frame of a 120 Hz source is shown and every 3rd of a 360 Hz one,
whatever the jitter. The jitter here (2 ms rms, Gaussian, seeded) makes the stamp rule lose frames too
(asserted, so the test would notice if it stopped exercising the problem).

Replay stamps are integers computed from float seconds exactly as the node computed them inline
(the same expression), so they compare with ``==``.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.mocap.ingest import ReplayClock, SilenceWatch, ViewDecimator, replay_schedule

S0 = 1_700_000_000 * 10**9


# -- ViewDecimator -----------------------------------------------------------------------------------------------------
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


# -- ReplayClock -------------------------------------------------------------------------------------------------------
RATE = 100.0
T = np.arange(10, 70) / RATE                                # frames 10..69


def inline_replay_stamp(t, k, start_ns, loop_index, span_s):
    """The expression the node used."""
    return start_ns + int(round((float(t[k]) - float(t[0]) + loop_index * span_s) * 1e9))


def test_replay_frames_are_due_on_the_schedule_with_replay_stamps():
    clock = ReplayClock(T, 2.0, 1 / RATE)
    assert clock.due(0.0) == ([], None) and not clock.started
    clock.start(100.0, S0)
    schedule = replay_schedule(T, 2.0)
    got, event = clock.due(100.0 + schedule[4] + 1e-9)
    assert [k for k, _ in got] == [0, 1, 2, 3, 4] and event is None
    got2, _ = clock.due(100.0 + schedule[-1] - 1e-6)
    assert [k for k, _ in got2] == list(range(5, 59))
    got3, event = clock.due(100.0 + schedule[-1])
    assert [k for k, _ in got3] == [59] and event == "end" and clock.done
    stamps = [s for _, s in got + got2 + got3]
    assert stamps == [inline_replay_stamp(T, k, S0, 0, clock.loop_span_s) for k in range(60)]
    assert np.all(np.diff(stamps) == 10_000_000)
    assert clock.due(1e9) == ([], None)


def test_file_stamps_are_the_capture_start_plus_the_recorded_time():
    clock = ReplayClock(T, 4.0, 1 / RATE, file_start_ns=S0)
    clock.start(5.0, 123)
    got, event = clock.due(1e6)
    assert event == "end" and [s for _, s in got] == [S0 + int(round(float(t) * 1e9)) for t in T]


def test_a_looping_replay_keeps_replay_stamps_increasing_by_one_period():
    clock = ReplayClock(T, 1.0, 1 / RATE, loop=True)
    clock.start(0.0, S0)
    stamps, events = [], []
    for now in np.arange(0.0, 1.5, 0.003):
        got, event = clock.due(float(now))
        stamps += [s for _, s in got]
        events.append(event)
    assert events.count("loop") == 2 and "end" not in events and not clock.done
    assert np.all(np.diff(stamps) == 10_000_000)            # across the seams too
    assert len(stamps) == 60 * 2 + 30                         # loops of 0.6 s; 0.297 s into the third


def test_an_empty_recording_ends_at_once():
    clock = ReplayClock(np.array([]), 1.0, 0.0, loop=True)
    clock.start(0.0, S0)
    assert clock.due(0.0) == ([], "end")


# -- SilenceWatch ------------------------------------------------------------------------------------------------------
def test_silence_warns_after_the_delay_repeats_and_reports_the_return():
    w = SilenceWatch(3.0, 10.0)
    assert w.check(1.0) is None                             # not started
    w.start(0.0)
    assert w.check(2.9) is None
    assert w.check(3.0) == pytest.approx(3.0)
    assert w.check(5.0) is None and w.check(12.9) is None   # throttled
    assert w.check(13.0) == pytest.approx(13.0)
    assert w.data(14.0) == pytest.approx(14.0)              # back after a warned silence: news
    assert w.data(14.1) is None and w.check(16.0) is None
    assert w.check(17.2) == pytest.approx(3.1)              # a new silence


def test_first_data_is_news_even_without_a_warning():
    w = SilenceWatch(3.0, 10.0)
    w.start(10.0)
    assert w.data(10.5) == pytest.approx(0.5)
    assert w.data(10.6) is None and w.check(11.0) is None
