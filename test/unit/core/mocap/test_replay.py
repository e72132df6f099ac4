"""Replay schedule and replay clock (euc_ros.core.mocap.replay), with time as an argument.

Replay stamps are integers computed from float seconds exactly as the node computed them inline
(the same expression), so they compare with ``==``.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.mocap.replay import ReplayClock, replay_schedule

S0 = 1_700_000_000 * 10**9


def test_replay_schedule_scales_with_rate():
    t = np.array([10.0, 10.5, 11.0])
    np.testing.assert_allclose(replay_schedule(t, 2.0), [0, 0.25, 0.5])
    with pytest.raises(ValueError):
        replay_schedule(t, 0.0)


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
