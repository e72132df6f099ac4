"""The demo's live step records every frame of the replayed CSV, whatever the timing of its nodes.

``euc-ros demo`` streams one simulated run through the pipeline (recorder, monitor, torque_estimator,
rider_state, mocap_ingest: five processes over DDS) and reads the bag back. The bag loses frames when:

* a consumer is not matched when the replay starts: start-up times of the five processes spread by
  seconds on a loaded 2-core host (imports compiled from source on a cold start, CPU shared with
  other work), and a replay that starts after a fixed delay misses the first frames of whichever
  node comes up last;
* the recorder's middleware is starved of CPU for longer than the publisher's history lasts (a
  reliable KEEP_LAST writer repairs losses from its history only);
* mocap_ingest exits before the recorder has every frame: the history goes with its process.

The test runs the demo's ``_live`` from a cold start (an empty bytecode prefix and numba cache for
the node processes) with the recorder made the last node up: its process starts
:data:`RECORDER_AFTER_S` after mocap_ingest said it is ready to replay (a fixed 3 s start delay
would then begin the replay before the recorder even exists). It is then stopped (SIGSTOP) for
:data:`STALL_S` from 1.5 s into the replay, past the moment mocap_ingest would exit. The bag must hold
every frame of the CSV in order and a transform per frame, and the states and torques computed
from them with no hole and up to the last one.
"""
from __future__ import annotations

import io
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from euc_ros.cli import demo
from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.core.online.estimators import RiderStateEstimator
from euc_ros.core.session import load_session
from euc_ros.ros import launcher

pytestmark = [pytest.mark.ros, pytest.mark.integration]

#: The recorder process starts this long after mocap_ingest logs that it is ready to replay [s].
RECORDER_AFTER_S = 3.0
#: Log line of mocap_ingest once it has read the CSV and is ready to replay.
READY = "[mocap_ingest]: replaying "
#: How long the recorder is stopped (SIGSTOP) during and after the replay [s]; at 240 frames/s that is
#: far more frames than a 256-deep history holds, and it covers mocap_ingest's exit.
STALL_S = 4.0
#: Log line after which the stall starts: mocap_ingest's up-axis check, 3 s of data (1.5 s of a 2x replay).
STALL_AFTER = "up axis checked"


@pytest.fixture(scope="module")
def demo_ride(tmp_path_factory):
    """One 7 s deceleration run as the demo simulates it (840 frames at 120 Hz), CSV + session."""
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    out = tmp_path_factory.mktemp("demo_ride")
    result = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=7, duration_s=7.0))
    write_ride(result, out)
    return out / "deceleration_01.csv", out / "session.yaml"


def _gated(executable: str, gate: Path, folder: Path) -> str:
    """A program that waits until the file ``gate`` exists (60 s at most) and then becomes ``executable``
    (same process, same arguments)."""
    script = folder / f"gated_{Path(executable).name}"
    script.write_text(f'#!/bin/sh\ni=0\nwhile [ ! -e "{gate}" ] && [ $i -lt 1200 ]; do sleep 0.05; i=$((i+1)); done\n'
                      f'exec "{executable}" "$@"\n', encoding="utf-8")
    script.chmod(0o755)
    return str(script)


def _recorder_pids() -> list[int]:
    import psutil

    pids = []
    for proc in psutil.Process().children(recursive=True):
        try:
            argv = proc.cmdline()
        except psutil.Error:
            continue
        if any(Path(a).name == "recorder" for a in argv[:2]):
            pids.append(proc.pid)
    return pids


class _Timing:
    """The launch log's stream (tee): opens ``gate`` :data:`RECORDER_AFTER_S` after mocap_ingest is ready,
    and stops the recorder for :data:`STALL_S` once :data:`STALL_AFTER` appears."""

    def __init__(self, stream, gate: Path) -> None:
        self.stream, self.gate = stream, gate
        self.log = io.StringIO()
        self.ready, self.stall = threading.Event(), threading.Event()
        self.stopped: list[int] = []
        self.threads = [threading.Thread(target=self._open_gate, daemon=True),
                        threading.Thread(target=self._stall, daemon=True)]
        for t in self.threads:
            t.start()

    def write(self, text: str) -> None:
        self.log.write(text)
        if READY in text:
            self.ready.set()
        if STALL_AFTER in text:
            self.stall.set()
        self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()

    def _open_gate(self) -> None:
        self.ready.wait(timeout=120)
        time.sleep(RECORDER_AFTER_S)
        self.gate.touch()

    def _stall(self) -> None:
        if not self.stall.wait(timeout=120):
            return
        self.stopped = _recorder_pids()
        try:
            for pid in self.stopped:
                os.kill(pid, signal.SIGSTOP)
            time.sleep(STALL_S)
        finally:
            for pid in self.stopped:
                try:
                    os.kill(pid, signal.SIGCONT)
                except ProcessLookupError:
                    pass


def test_the_demo_live_bag_holds_every_frame(ros_domain, demo_ride, tmp_path, monkeypatch, capsys):
    csv, session_file = demo_ride
    # a cold start: the node processes compile their imports from source and have no numba cache
    monkeypatch.setenv("PYTHONPYCACHEPREFIX", str(tmp_path / "pycache"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    gate = tmp_path / "recorder_may_start"
    resolve = launcher.resolve_executable
    monkeypatch.setattr(launcher, "resolve_executable", lambda name: _gated(resolve(name), gate, tmp_path)
                        if name == "recorder" else resolve(name))
    timings: list[_Timing] = []
    run = demo.run

    def timed_run(specs, *, stream=None, **kwargs):
        timings.append(_Timing(stream, gate))
        return run(specs, stream=timings[0], **kwargs)

    monkeypatch.setattr(demo, "run", timed_run)
    t0 = time.monotonic()
    try:
        bag = demo._live(tmp_path / "live_bag", csv, session_file, 0.61, 2.0)
    except SystemExit as exc:
        pytest.fail(f"{exc}\n{timings[0].log.getvalue() if timings else ''}")
    wall = time.monotonic() - t0
    timing = timings[0]
    timing.threads[1].join(timeout=STALL_S + 1)
    log = timing.log.getvalue()
    assert timing.stopped, "the recorder was never stopped:\n" + log
    recorded = {t: [] for t in ("/mocap/frame", "/tf", "/rider/state", "/euc/torque")}
    for topic, _, _, msg in read_bag(bag, topics=list(recorded)) if bag.is_dir() else ():
        recorded[topic].append(msg)
    series = read_motive_csv(csv, world_up="y")
    frames = [m.frame_number for m in recorded["/mocap/frame"]]
    expected = [int(f) for f in series.frame]
    missing = sorted(set(expected) - set(frames))
    assert frames == expected, (f"{len(frames)} of {len(expected)} frames in the bag, missing "
                                f"{_ranges(missing)}\n{log}")
    assert check_bag(bag) == []
    # the transforms come from mocap_ingest too (one per frame with a tracked body, at this 120 Hz capture)
    assert len(recorded["/tf"]) == int(series.tracked.any(axis=0).sum())

    # the states and torques computed from those frames: none lost to the stall or at the end. Their
    # first ones depend on how soon the recorder discovers rider_state's and torque_estimator's
    # publishers, which the replay cannot see: a contiguous run up to the last one is asserted.
    session = load_session(session_file)
    core = RiderStateEstimator(session, 1 / session.rate_hz)
    want = sorted(int(s.frame) for _, s in core.update_series(series))
    row = {_stamp(m): k for k, m in enumerate(recorded["/mocap/frame"])}
    states = sorted(expected[row[_stamp(m)]] for m in recorded["/rider/state"])
    torques = sorted(expected[row[_stamp(m)]] for m in recorded["/euc/torque"])
    for name, got in (("states", states), ("torques", torques)):
        assert got and got == want[len(want) - len(got):], \
            f"{len(got)} of {len(want)} {name}, missing {_ranges(sorted(set(want) - set(got)))}"
    assert np.isfinite([m.residual for m in recorded["/euc/torque"]]).all()
    with capsys.disabled():
        print(f"\ndemo live step: {len(frames)}/{len(expected)} frames, {len(states)} states, {len(torques)} torques "
              f"in the bag; recorder started last and stopped {STALL_S:.0f} s; "
              f"wall {wall:.1f} s")


def _stamp(msg) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def _ranges(values: list[int]) -> str:
    """``[0, 1, 2, 5]`` as ``'0-2, 5'``."""
    out, start = [], None
    for i, v in enumerate(values):
        if start is None:
            start = v
        if i + 1 == len(values) or values[i + 1] != v + 1:
            out.append(f"{start}-{v}" if v != start else f"{v}")
            start = None
    return ", ".join(out) or "none"
