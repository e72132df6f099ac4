"""`euc-ros play BAG`: replay a rosbag2 bag onto live topics with the recorded timing x a rate factor.

Messages are published as raw CDR (no decode) at their bag receive times scaled by ``1/rate``,
relative to the first message played. Before starting, the player waits until every publisher has
matched ``--wait-subscribers`` subscriptions (at most ``--wait-timeout`` s), then ``--delay`` s more:
DDS discovery is asymmetric, the subscriber may match a little after the publisher did, and a
VOLATILE reader drops what arrives before. The bag is streamed (not loaded into memory); each wait
sleeps until ``BUSY_WAIT_S`` before the message and spins the rest, so messages leave within a few
tenths of a millisecond of their target at modest CPU cost (the measured publish lateness is printed
at the end).

With ``--clock`` a ``/clock`` message (rosgraph_msgs/Clock) carrying the bag time is published at
the given frequency (wall time) from the moment the player waits for subscribers, so nodes started
with ``use_sim_time:=true`` run on the bag's clock. ``--loop`` starts again at the end; SIGINT or
SIGTERM stop the player cleanly (exit code 0).
"""
from __future__ import annotations

import argparse
import gc
import importlib
import threading
import time
from pathlib import Path

import numpy as np

from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.cli.play_source import BagSource
from euc_ros.cli.stop import StopSignals
from euc_ros.core.errors import InputError
from euc_ros.sched import set_realtime as _set

HELP = "replay a bag onto live topics (recorded timing x rate, optional /clock, offset, filter, loop)"

#: Below this remaining time the player spins instead of sleeping (sleep overshoots by ~0.1-1 ms) [s].
BUSY_WAIT_S = 0.001
#: Longest single sleep, so signals and /clock ticks are served promptly [s].
MAX_SLEEP_S = 0.05
#: QoS depth of the players' publishers (messages).
QUEUE_DEPTH = 1000
#: Longest wait for the subscribers' acknowledgements of the last messages before exiting [s].
ACK_TIMEOUT_S = 2.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros play``."""
    parser.add_argument("bag", help="rosbag2 bag directory (or its .mcap file)")
    parser.add_argument("-r", "--rate", type=float, default=1.0, help="rate factor (2 = twice as fast)")
    parser.add_argument("--clock", type=float, nargs="?", const=100.0, default=None, metavar="HZ",
                        help="publish /clock with the bag time at HZ (default 100 when given), for use_sim_time "
                             "nodes")
    parser.add_argument("--start-offset", type=float, default=0.0, metavar="S",
                        help="skip the first S seconds of the bag")
    parser.add_argument("--topics", nargs="+", default=None, metavar="TOPIC", help="only these topics")
    parser.add_argument("-l", "--loop", action="store_true", help="start again at the end (Ctrl-C to stop)")
    parser.add_argument("--wait-subscribers", type=int, default=1, metavar="N",
                        help="before playing, wait until every topic has N subscriptions (0: do not wait)")
    parser.add_argument("--wait-timeout", type=float, default=5.0, metavar="S",
                        help="wait at most S seconds for the subscriptions, then play anyway")
    parser.add_argument("--delay", type=float, default=0.3, metavar="S",
                        help="wait S seconds more after the subscriptions matched (discovery settles)")
    parser.add_argument("--linger", type=float, default=0.0, metavar="S",
                        help="stay S seconds after the last message (when a launch ends with the player, the "
                             "nodes downstream get time to process the tail)")
    parser.add_argument("--realtime", type=int, nargs="?", const=10, default=None, metavar="PRIO",
                        help="run the player with the SCHED_FIFO real-time priority PRIO (default 10 when given; "
                             "needs CAP_SYS_NICE) so that other processes cannot delay messages")
    parser.add_argument("--timing-log", default=None, metavar="CSV",
                        help="write one line per published message: bag stamp [ns], topic, target and publish "
                             "times [s, CLOCK_MONOTONIC as time.perf_counter]")


def _msg_class(type_name: str):
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def missing_subscribers(have: dict[str, int], wanted: int) -> str:
    """The topics short of ``wanted`` subscribers, with how many each has, for the log.

    Parameters
    ----------
    have : dict of str to int
        Topic -> subscriptions matched so far.
    wanted : int
        Subscriptions waited for per topic (``--wait-subscribers``).

    Returns
    -------
    str
        ``"/mocap/frame has no subscriber"``, ``"/a has 1 of 2 subscribers, /b has 0 of 2"``; empty when
        no topic is short.

    Examples
    --------
    >>> missing_subscribers({"/mocap/frame": 0, "/clock": 1}, 1)
    '/mocap/frame has no subscriber'
    >>> missing_subscribers({"/a": 1, "/b": 0}, 2)
    '/a has 1 of 2 subscribers, /b has 0 of 2'
    """
    short = [(t, n) for t, n in have.items() if n < wanted]
    if wanted == 1:
        return ", ".join(f"{t} has no subscriber" for t, _ in short)
    return ", ".join(f"{t} has {n} of {wanted}" + (" subscribers" if k == 0 else "") for k, (t, n) in enumerate(short))


def set_realtime(priority: int) -> str:
    """Switch this process to SCHED_FIFO at ``priority``; return what happened (never raises)."""
    return _set(priority, "playing")




class Player:
    """Publish a bag's messages at their recorded times divided by ``rate``, with an optional /clock."""

    def __init__(self, node, source: BagSource, rate: float, clock_hz: float | None, stop: threading.Event):
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        self.node, self.source, self.rate, self.stop = node, source, rate, stop
        self.pubs = {}
        for topic, type_name in source.types.items():
            try:
                cls = _msg_class(type_name)
            except (ImportError, AttributeError, ValueError):
                node.get_logger().warning(f"skipping {topic}: no Python type for {type_name}")
                continue
            durability = DurabilityPolicy.TRANSIENT_LOCAL if topic == "/tf_static" else DurabilityPolicy.VOLATILE
            qos = QoSProfile(depth=QUEUE_DEPTH, reliability=ReliabilityPolicy.RELIABLE, durability=durability)
            self.pubs[topic] = node.create_publisher(cls, topic, qos)
        if not self.pubs:
            raise InputError("no topic of the bag has a Python message type here", path=source.path)
        self.clock_pub = None
        self.clock_period = None
        if clock_hz:
            from rosgraph_msgs.msg import Clock

            self._clock_cls = Clock
            self.clock_pub = node.create_publisher(Clock, "/clock", 10)
            self.clock_period = 1.0 / clock_hz
        self._next_clock = 0.0
        self.lateness: list[float] = []
        self.published = 0
        self.log: list[tuple[int, str, float, float]] | None = None

    # -- helpers -------------------------------------------------------------------------------------------
    def _tick_clock(self, now: float, bag_ns: int) -> None:
        if self.clock_pub is not None and now >= self._next_clock:
            from euc_ros.ros.convert import ns_to_stamp

            self.clock_pub.publish(self._clock_cls(clock=ns_to_stamp(bag_ns)))
            self._next_clock = max(self._next_clock + self.clock_period, now - self.clock_period)

    def _sleep(self, seconds: float) -> None:
        if seconds > 0:
            self.stop.wait(min(seconds, MAX_SLEEP_S))

    def wait_for_subscribers(self, count: int, timeout_s: float, settle_s: float, first_bag_ns: int) -> None:
        """Wait until every publisher has ``count`` subscriptions (or ``timeout_s``), then ``settle_s``."""
        log = self.node.get_logger()
        t_end = time.monotonic() + timeout_s
        if count > 0:
            while not self.stop.is_set():
                have = {t: p.get_subscription_count() for t, p in self.pubs.items()}
                if all(n >= count for n in have.values()):
                    break
                if time.monotonic() >= t_end:
                    log.info(f"after {timeout_s:g} s, {missing_subscribers(have, count)}: playing anyway")
                    break
                self._tick_clock(time.perf_counter(), first_bag_ns)
                self._sleep(0.01)
        t_end = time.monotonic() + settle_s
        while not self.stop.is_set() and time.monotonic() < t_end:
            self._tick_clock(time.perf_counter(), first_bag_ns)
            self._sleep(min(t_end - time.monotonic(), self.clock_period or MAX_SLEEP_S))

    def play_once(self) -> bool:
        """Play the bag once; False if stopped by a signal."""
        t0_wall = t0_bag = None
        for stamp, topic, raw in self.source.messages():
            if t0_wall is None:
                t0_wall, t0_bag = time.perf_counter(), stamp
            target = t0_wall + (stamp - t0_bag) * 1e-9 / self.rate
            while True:
                if self.stop.is_set():
                    return False
                now = time.perf_counter()
                if self.clock_pub is not None:
                    self._tick_clock(now, t0_bag + int((now - t0_wall) * self.rate * 1e9))
                remaining = target - now
                if remaining <= 0:
                    break
                if remaining > BUSY_WAIT_S:
                    wait = remaining - BUSY_WAIT_S
                    if self.clock_pub is not None:
                        wait = min(wait, max(self._next_clock - now, 0.0))
                    self._sleep(wait)
            pub = self.pubs.get(topic)
            if pub is not None:
                pub.publish(raw)
                done = time.perf_counter()
                self.lateness.append(done - target)
                self.published += 1
                if self.log is not None:
                    self.log.append((stamp, topic, target, done))
        return True

    def wait_for_acks(self, timeout_s: float) -> list[str]:
        """Wait until every published message is acknowledged by the reliable subscribers (before exit).

        A process that exits right after its last publish can take unacknowledged messages with it.
        Returns the topics still unacknowledged after ``timeout_s`` (shared between topics).
        """
        from rclpy.duration import Duration

        pending = []
        t_end = time.monotonic() + timeout_s
        for topic, pub in self.pubs.items():
            left = max(t_end - time.monotonic(), 0.0)
            if not pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9))):
                pending.append(topic)
        return pending

    def write_log(self, path: str) -> None:
        """Write the timing log (``--timing-log``) as CSV."""
        with open(path, "w", encoding="utf-8") as fh:
            fh.write("stamp_ns,topic,target_s,published_s\n")
            for stamp, topic, target, done in self.log or []:
                fh.write(f"{stamp},{topic},{target:.9f},{done:.9f}\n")

    def summary(self) -> str:
        """One line: messages, topics and the publish lateness (target time to publish returned)."""
        if not self.lateness:
            return "play: nothing published"
        lat = np.asarray(self.lateness) * 1e3
        return (f"play: published {self.published} messages on {len(self.pubs)} topics at x{self.rate:g}; "
                f"lateness p50 {np.percentile(lat, 50):.3f} ms, p99 {np.percentile(lat, 99):.3f} ms, "
                f"max {lat.max():.3f} ms")


def main(args: argparse.Namespace) -> int:
    """Replay the bag; returns 0 (also when stopped by SIGINT/SIGTERM)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    if not args.rate > 0:
        raise InputError(f"--rate must be > 0, got {args.rate}", key="--rate")
    if not args.linger >= 0:
        raise InputError(f"--linger must be >= 0 s, got {args.linger}", key="--linger")
    if args.clock is not None and not args.clock > 0:
        raise InputError(f"--clock must be > 0 Hz, got {args.clock}", key="--clock")

    check_outputs([Output("--timing-log", args.timing_log)], [args.bag])
    source = BagSource(Path(args.bag), args.topics, args.start_offset)
    try:
        first = next(source.messages(), None)
        if first is None:
            print("play: nothing to play (empty bag, or --start-offset past its end)")
            return 0
        with StopSignals() as stop:
            if args.realtime is not None:   # before rclpy.init: the DDS threads inherit the policy
                print(f"play: {set_realtime(args.realtime)}", flush=True)
            rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
            node = rclpy.create_node("euc_player")
            try:
                player = Player(node, source, args.rate, args.clock, stop)
                if args.timing_log:
                    player.log = []
                player.wait_for_subscribers(args.wait_subscribers, args.wait_timeout, args.delay, first[0])
                gc.collect()
                gc.freeze()      # set-up objects leave the collector's scans: shorter pauses while playing
                while not stop.is_set():
                    if not player.play_once() or not args.loop:
                        break
                unacked = player.wait_for_acks(ACK_TIMEOUT_S) if not stop.is_set() else []
                if unacked:
                    node.get_logger().warning(f"not acknowledged by every subscriber after {ACK_TIMEOUT_S:g} s: "
                                              f"{', '.join(unacked)}")
                print(player.summary() + (" (stopped)" if stop.is_set() else ""), flush=True)
                if args.linger > 0:
                    stop.wait(args.linger)
                if args.timing_log:
                    player.write_log(args.timing_log)
            finally:
                node.destroy_node()
                rclpy.try_shutdown()
    finally:
        source.close()
    return 0
