"""`euc-ros play BAG`: replay a rosbag2 bag onto live topics with the recorded timing x a rate factor.

Messages are published as raw CDR (no decode), at their bag receive times scaled by ``1/rate``;
the last millisecond before each message is busy-waited so timing holds to well under 2 ms.
With ``--clock`` a ``/clock`` message is published at the given frequency with the bag time, so
nodes started with ``use_sim_time:=true`` run on the bag's clock.
"""
from __future__ import annotations

import argparse
import importlib
import time
from pathlib import Path

from euc_ros.core.errors import InputError

HELP = "replay a bag onto live topics (recorded timing x rate, optional /clock, offset, filter, loop)"

#: Below this remaining time the player spins instead of sleeping (sleep overshoots by ~0.1-1 ms).
BUSY_WAIT_S = 0.001


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros play``."""
    parser.add_argument("bag", help="rosbag2 bag directory (or its .mcap file)")
    parser.add_argument("-r", "--rate", type=float, default=1.0, help="rate factor (2 = twice as fast)")
    parser.add_argument("--clock", type=float, nargs="?", const=100.0, default=None, metavar="HZ",
                        help="publish /clock at HZ (default 100 when given) for use_sim_time nodes")
    parser.add_argument("--start-offset", type=float, default=0.0, metavar="S",
                        help="skip the first S seconds of the bag")
    parser.add_argument("--topics", nargs="+", default=None, help="only these topics")
    parser.add_argument("-l", "--loop", action="store_true", help="start again at the end (Ctrl-C to stop)")
    parser.add_argument("--delay", type=float, default=0.5, metavar="S",
                        help="wait S seconds after creating publishers so subscribers can match")


def _msg_class(type_name: str):
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def load_messages(bag: Path, topics: list[str] | None, start_offset: float):
    """Return (connections {topic: type}, [(stamp_ns, topic, raw bytes)] sorted by stamp)."""
    from rosbags.highlevel import AnyReader

    path = bag.parent if bag.suffix == ".mcap" else bag
    if not (path / "metadata.yaml").exists():
        raise InputError("not a rosbag2 directory (no metadata.yaml)", path=path)
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        if topics:
            missing = set(topics) - {c.topic for c in reader.connections}
            if missing:
                raise InputError(f"topics not in bag: {', '.join(sorted(missing))} "
                                 f"(bag has: {', '.join(sorted({c.topic for c in reader.connections}))})", path=path)
        start = reader.start_time + int(start_offset * 1e9)
        msgs = [(ts, c.topic, bytes(raw)) for c, ts, raw in reader.messages(connections=conns, start=start)]
        types = {c.topic: c.msgtype for c in conns}
    msgs.sort(key=lambda m: m[0])
    return types, msgs


def main(args: argparse.Namespace) -> int:
    """Replay the bag; returns 0 (also on Ctrl-C)."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rosgraph_msgs.msg import Clock

    from euc_ros.nodes.convert import ns_to_stamp

    if args.rate <= 0:
        raise InputError(f"--rate must be > 0, got {args.rate}", key="--rate")
    types, msgs = load_messages(Path(args.bag), args.topics, args.start_offset)
    if not msgs:
        print("play: nothing to play")
        return 0
    rclpy.init()
    node = rclpy.create_node("player")
    try:
        pubs = {}
        for topic, type_name in types.items():
            try:
                pubs[topic] = node.create_publisher(_msg_class(type_name), topic, 1000)
            except (ImportError, AttributeError, ValueError):
                node.get_logger().warning(f"skipping {topic}: no Python type for {type_name}")
        clock_pub = node.create_publisher(Clock, "/clock", 10) if args.clock else None
        clock_period = 1.0 / args.clock if args.clock else None
        time.sleep(args.delay)
        while True:
            t0_bag = msgs[0][0]
            t0_wall = time.perf_counter()
            next_clock = t0_wall
            for stamp, topic, raw in msgs:
                target = t0_wall + (stamp - t0_bag) * 1e-9 / args.rate
                while True:
                    now = time.perf_counter()
                    if clock_pub is not None and now >= next_clock:
                        bag_now = t0_bag + int((now - t0_wall) * args.rate * 1e9)
                        clock_pub.publish(Clock(clock=ns_to_stamp(bag_now)))
                        next_clock += clock_period
                    remaining = target - now
                    if remaining <= 0:
                        break
                    if remaining > BUSY_WAIT_S:
                        wait = remaining - BUSY_WAIT_S
                        if clock_pub is not None:
                            wait = min(wait, max(next_clock - now, 0.0))
                        time.sleep(wait)
                pub = pubs.get(topic)
                if pub is not None:
                    pub.publish(raw)
            if not args.loop:
                break
        print(f"play: published {len(msgs)} messages on {len(pubs)} topics")
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0
