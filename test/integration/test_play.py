"""`euc-ros play` as a separate process against a receiving node in the test process.

The bag is written with BagWriter (known receive times, irregular spacing). The tests check what does
not depend on how busy the machine is: every message is played, once, in order, with its recorded
header stamp; the player's schedule (``--timing-log`` targets) is the recorded timing / rate; bag
time on ``/clock`` never goes back; topics, start offset and loops select the right messages. How
close to that schedule the messages leave and arrive is a timing, measured by ``euc-ros bench``
(``euc_ros/bench/play.py``): a wall-clock bound in a test fails on a loaded machine.
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


def read_timing_log(path) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """stamp_ns, topic, target_s, published_s of the player's --timing-log."""
    stamps = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(0,), dtype=np.int64, ndmin=1)
    topics = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(1,), dtype=str, ndmin=1).tolist()
    data = np.genfromtxt(path, delimiter=",", skip_header=1, usecols=(2, 3), dtype=np.float64, ndmin=2)
    return stamps, topics, data[:, 0], data[:, 1]


def schedule_tolerance(target0: float, stamps_ns: np.ndarray, rate: float) -> float:
    """Round-off of the logged schedule ``t0 + (stamp - stamp0) * 1e-9 / rate`` minus its first target.

    The log rounds each target to 1e-9 s (0.5e-9 each, two in a difference); each target carries the
    rounding of a sum at perf_counter's magnitude (the host's uptime: one ulp is 3.7e-9 s after a
    year) and of the offset; the difference of two, a few ulps of each.
    """
    offset = (stamps_ns[-1] - stamps_ns[0]) * 1e-9 / rate
    return 2 * 0.5e-9 + 4 * float(np.spacing(abs(target0) + offset)) + 4 * float(np.spacing(offset))


@pytest.mark.parametrize("rate", [1.0, 2.0])
def test_play_publishes_every_message_in_order_on_the_recorded_schedule(bag, receiver, rate, tmp_path):
    path, stamps_a, _ = bag
    log = tmp_path / "timing.csv"
    proc = play(path, "--rate", str(rate), "--topics", "/a", "--timing-log", str(log))
    try:
        receiver.spin_until(lambda: len(receiver.a) == N or proc.poll() is not None, 60)
        receiver.spin_until(lambda: len(receiver.a) == N, 5)
    finally:
        out = finish(proc, timeout=60)
    arrivals, got = zip(*receiver.a)
    assert list(got) == stamps_a.tolist()                           # every message, once, in order, its stamp
    assert receiver.b == []                                         # --topics
    assert np.all(np.diff(arrivals) >= 0)
    # the player's schedule: targets are the recorded offsets / rate from the first message
    log_stamps, topics, target, published = read_timing_log(log)
    assert log_stamps.tolist() == stamps_a.tolist() and set(topics) == {"/a"}
    np.testing.assert_allclose(target - target[0], (stamps_a - stamps_a[0]) * 1e-9 / rate, rtol=0,
                               atol=schedule_tolerance(target[0], stamps_a, rate))
    assert np.all(published >= target)                              # never published before its time
    assert np.all(np.diff(published) >= 0)
    assert f"published {N} messages on 1 topics at x{rate:g}" in out


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
    _, got = zip(*receiver.a)
    assert list(got) == want.tolist() and receiver.b == []        # offset and filter
    assert f"published {len(want)} messages on 1 topics" in out

    clock = np.array([v for _, v in receiver.clock], dtype=np.int64)
    assert clock.size >= 2
    assert np.all(np.diff(clock) >= 0)                               # bag time never goes back
    assert clock.min() >= want[0]                                    # from the first played message on ...
    assert np.any(clock == want[0])                                  # ... which it holds while waiting
    assert clock.max() > want[0]                                     # and it runs while playing


def test_play_loop_until_sigint(bag, receiver, tmp_path):
    path, stamps_a, stamps_b = bag
    offset = 1.8
    start = min(stamps_a[0], stamps_b[0]) + int(offset * 1e9)
    one_loop = stamps_a[stamps_a >= start]
    log = tmp_path / "timing.csv"
    proc = play(path, "--loop", "--topics", "/a", "--start-offset", str(offset), "--timing-log", str(log))
    try:
        got_two = receiver.spin_until(lambda: len(receiver.a) >= 2 * len(one_loop) + 3 or proc.poll() is not None, 30)
        assert proc.poll() is None, "player ended although --loop"
        proc.send_signal(signal.SIGINT)
    finally:
        out = finish(proc, timeout=10)
    assert got_two and "(stopped)" in out
    _, got = zip(*receiver.a)
    n = len(one_loop)
    assert list(got[:2 * n]) == one_loop.tolist() * 2                # the same messages again
    # each loop is scheduled from its own first message: the second loop's targets are the recorded
    # offsets from its start, and it starts when the first loop has ended (not after the bag's offset)
    log_stamps, _, target, published = read_timing_log(log)
    assert log_stamps[:2 * n].tolist() == one_loop.tolist() * 2
    second = target[n:2 * n]
    np.testing.assert_allclose(second - second[0], (one_loop - one_loop[0]) * 1e-9, rtol=0,
                               atol=schedule_tolerance(second[0], one_loop, 1.0))
    assert second[0] >= published[n - 1]


def test_play_errors(bag, tmp_path):
    from euc_ros.cli.main import main

    path, _, _ = bag
    assert main(["play", str(path), "--topics", "/nope"]) == 2
    assert main(["play", str(tmp_path)]) == 2                        # not a bag
    assert main(["play", str(path), "--rate", "0"]) == 2
    assert main(["play", str(path), "--start-offset", "100"]) == 0   # nothing to play: not an error
