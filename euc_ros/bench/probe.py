"""Latency probe: record when each pipeline message arrives, with its header stamp.

``python -m euc_ros.bench.probe --out FILE.npz [--topics mocap/frame,rider/state,euc/torque]`` runs
one node that subscribes to the given topics (reliable, depth 256: the pipeline's QoS) and notes
for every message the wall-clock arrival time (``time.time_ns()`` on entry of the callback), the
header stamp and one field per type (MocapFrame ``frame_number``, RiderState ``filter_lag``,
TorqueEstimate ``m_d1``). On SIGINT/SIGTERM it writes ``FILE.npz`` with, per topic ``T`` (slashes
as ``__``), the arrays ``T__arrival_ns``, ``T__stamp_ns`` and ``T__extra``, then exits 0.

:class:`Probe` is the same node for use in-process (tests).
"""
from __future__ import annotations

import argparse
import importlib
import struct
import sys
import time
from pathlib import Path

import numpy as np

from euc_ros.bench.relay import install_stop_handlers, spin_until_signal
from euc_ros.sched import realtime_from_env

#: topic -> (module, message class, extra field)
TOPIC_TYPES = {
    "mocap/frame": ("euc_msgs.msg", "MocapFrame", "frame_number"),
    "rider/state": ("euc_msgs.msg", "RiderState", "filter_lag"),
    "euc/torque": ("euc_msgs.msg", "TorqueEstimate", "m_d1"),
}
DEFAULT_TOPICS = ("mocap/frame", "rider/state", "euc/torque")


def key(topic: str) -> str:
    """Array-name prefix of a topic (``mocap/frame`` -> ``mocap__frame``)."""
    return topic.strip("/").replace("/", "__")


class Probe:
    """A node recording arrival time, header stamp and one field of every message on ``topics``.

    Parameters
    ----------
    topics : iterable of str
        Keys of :data:`TOPIC_TYPES`.
    context : rclpy.Context, optional
    name : str
        Node name.
    """

    def __init__(self, topics=DEFAULT_TOPICS, *, context=None, name: str = "bench_probe") -> None:
        from rclpy.node import Node

        from euc_ros.ros import interfaces as itf

        self.node = Node(name, context=context)
        self.records: dict[str, list[tuple[int, int, float]]] = {}
        for topic in topics:
            if topic not in TOPIC_TYPES:
                raise ValueError(f"unknown probe topic {topic!r} (known: {', '.join(TOPIC_TYPES)})")
            module, cls, extra = TOPIC_TYPES[topic]
            msg_type = getattr(importlib.import_module(module), cls)
            self.records[topic] = []
            # raw: the probe's own cost must not load the 2-core machine it measures (a 56-body frame
            # through the message classes costs ~1 ms); the header stamp is read from the bytes
            self.node.create_subscription(msg_type, topic, self._callback(topic, msg_type, extra), itf.RELIABLE_QOS,
                                          raw=True)

    def _callback(self, topic: str, msg_type, extra: str):
        from rclpy.serialization import deserialize_message

        rec = self.records[topic]
        frames = msg_type.__name__ == "MocapFrame"

        def on_message(raw: bytes) -> None:
            arrival = time.time_ns()
            if raw[:2] == b"\x00\x01" and frames:          # little-endian CDR: header stamp first
                sec, nsec = struct.unpack_from("<iI", raw, 4)
                (n,) = struct.unpack_from("<I", raw, 12)    # frame_id length; then uint8, int64 8-aligned
                at = 16 + n + 1
                at += (-(at - 4)) % 8
                value = float(struct.unpack_from("<q", raw, at)[0])
            else:
                msg = deserialize_message(raw, msg_type)
                sec, nsec, value = msg.header.stamp.sec, msg.header.stamp.nanosec, float(getattr(msg, extra))
            rec.append((arrival, sec * 1_000_000_000 + nsec, value))
        return on_message

    def count(self, topic: str) -> int:
        """Messages received on ``topic`` so far."""
        return len(self.records[topic])

    def arrays(self) -> dict[str, np.ndarray]:
        """``{T__arrival_ns, T__stamp_ns, T__extra}`` per topic."""
        out = {}
        for topic, rec in self.records.items():
            a = np.array(rec, dtype=object).reshape(-1, 3) if rec else np.zeros((0, 3), dtype=object)
            k = key(topic)
            out[f"{k}__arrival_ns"] = a[:, 0].astype(np.int64)
            out[f"{k}__stamp_ns"] = a[:, 1].astype(np.int64)
            out[f"{k}__extra"] = a[:, 2].astype(float)
        return out

    def save(self, path: str | Path) -> None:
        """Write :meth:`arrays` to an ``.npz`` file (atomically)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez(tmp, **self.arrays())
        tmp.replace(path)


def load(path: str | Path) -> dict[str, dict[str, np.ndarray]]:
    """Read a probe file: ``{topic_key: {"arrival_ns", "stamp_ns", "extra"}}``."""
    data = np.load(path)
    out: dict[str, dict[str, np.ndarray]] = {}
    for name in data.files:
        for field in ("arrival_ns", "stamp_ns", "extra"):
            if name.endswith("__" + field):
                out.setdefault(name[:-len(field) - 2], {})[field] = data[name]
    return out


def main(argv: list[str] | None = None) -> int:
    """Run the probe until SIGINT/SIGTERM, then save."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from euc_ros.ros.executor import LeanExecutor

    parser = argparse.ArgumentParser(prog="python -m euc_ros.bench.probe", description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, type=Path, help="npz file written at shutdown")
    parser.add_argument("--topics", default=",".join(DEFAULT_TOPICS), help="comma-separated topics")
    args, ros_args = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    realtime_from_env("probe")
    rclpy.init(args=["probe", *ros_args], signal_handler_options=SignalHandlerOptions.NO)
    stop = install_stop_handlers()
    probe = None
    try:
        probe = Probe([t for t in args.topics.split(",") if t])
        # the pipeline's executor: the probe is in both chains it compares, and its cost loads both
        spin_until_signal(probe.node, stop, LeanExecutor(context=probe.node.context))
    except KeyboardInterrupt:
        pass
    finally:
        if probe is not None:
            probe.save(args.out)
            counts = ", ".join(f"{t}={len(r)}" for t, r in probe.records.items())
            print(f"[probe] saved {args.out}: {counts}", flush=True)
            probe.node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
