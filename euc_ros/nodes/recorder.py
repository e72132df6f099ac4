"""Node ``recorder``: topics -> rosbag2 bag with MCAP storage (through rosbags), nothing lost on SIGINT.

Takes CDR bytes (raw) so they go straight into the bag without a decode/encode round trip. Topics
are subscribed as soon as they appear in the graph (a discovery timer), with a reliability that
matches their publishers (reliable unless a publisher is best effort).

The subscriptions are not rclpy callbacks: they form one :class:`SubscriptionDrain`, a waitable of
the executor. When any of them has data, the executor wakes once and the drain takes every message
every subscription holds (until rcl has none left); the recorder writes them per topic in one
:meth:`~euc_ros.core.io.bags.BagWriter.write_raw_many` batch. An executor cycle (wait-set rebuild,
task, callback) costs tens of microseconds; per message it was the recorder's limit, per wake it is
shared by every message that arrived meanwhile. On shutdown what the subscriptions still hold is
taken and written before the bag closes.

Transport: the console script runs the recorder with a deep Fast DDS shared-memory port
(:data:`euc_ros.ros.fastdds.RECORDER_PROFILE`) unless the transports were chosen already, and first
removes the Fast DDS shared-memory files that no process maps (:mod:`euc_ros.ros.shm_clean`): Fast
DDS reuses a stale port file of the same number unresized, which would give the recorder a
512-descriptor port whatever its profile asks.
"""
from __future__ import annotations

import importlib
import os
import time
from pathlib import Path

from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from euc_ros.core.io.bags import BagWriter
from euc_ros.ros import interfaces as itf
from euc_ros.ros.convert import bag_qos
from euc_ros.ros.drain import SubscriptionDrain
from euc_ros.ros.fastdds import transport_env, uses_fast_dds
from euc_ros.ros.params import ParamSpec, declare_params
from euc_ros.ros.runtime import main_for
from euc_ros.ros.shm_clean import SHM_CLEAN_ENV, remove_stale_fastdds_files

SPECS = (
    ParamSpec("output", "", "bag directory to create (default: bags/euc_<UTC time>); must not exist"),
    ParamSpec("topics", list(itf.PIPELINE_TOPICS), "topics to record (relative names resolve in the node's namespace)"),
    ParamSpec("all_topics", False, "record every topic that appears (except /rosout and parameter events)"),
    ParamSpec("chunk_size", 1 << 16, "MCAP chunk size: what a SIGKILL can lose (~0.2 s of the pipeline at 64 KiB)", "bytes",  # noqa: E501
              4096, 1 << 28),
    ParamSpec("discovery_period", 0.1, "how often to look for new topics", "s", 0.01, 10.0),
    ParamSpec("queue_depth", 10000, "subscription queue depth: how far the recorder may fall behind per topic "
              "(1.8 s at 100k msgs/s over 18 topics)", "messages", 1, 100000),
)

_SKIP = {"/rosout", "/parameter_events"}

def _msg_class(type_name: str):
    pkg, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


#: A wanted topic seen only through subscribers is subscribed after this wait at the latest [s]: a
#: publisher that appears meanwhile gives its offered QoS to the bag's metadata (as rosbag2 records it).
PUBLISHER_WAIT_S = 1.0

class Recorder(Node):
    """Record topics into a rosbag2 MCAP bag.

    ===========  ===============================  =====================================================
    direction    topic                            what
    ===========  ===============================  =====================================================
    Subscribes   ``topics``, or every topic       raw, subscribed as they appear in the graph; reliable
                 (``all_topics``)                 unless a publisher is best effort
    Publishes    nothing
    ===========  ===============================  =====================================================

    Parameters: :data:`SPECS` (``output``, ``topics``, ``all_topics``, ``chunk_size``, ``discovery_period``,
    ``queue_depth``).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node`.

    Attributes
    ----------
    path : Path
        The bag directory.
    counts : dict of str to int
        Messages written per topic.
    """

    NAME = "recorder"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = declare_params(self, SPECS)
        out = self.config["output"] or f"bags/euc_{time.strftime('%Y%m%d_%H%M%S', time.gmtime())}"
        self.path = Path(out)
        self.writer = BagWriter(self.path, chunk_size=self.config["chunk_size"])
        self.counts: dict[str, int] = {}
        self._drain = SubscriptionDrain(self, self._on_messages)
        self.add_waitable(self._drain)
        self._subscribed: set[str] = set()
        self._wanted = {self.resolve_topic_name(t) for t in self.config["topics"]}
        self._seen: dict[str, float] = {}    # topic -> when it was first seen without a publisher
        self._unwritten: dict[str, str] = {}  # subscribed topic -> type, until its bag connection exists
        self._matched: dict[str, int] = {}    # subscribed topic -> publishers matched, as last logged
        self._timer = self.create_timer(self.config["discovery_period"], self._discover)
        self._discover()
        self.get_logger().info(f"recording to {self.path} "
                               f"({'all topics' if self.config['all_topics'] else ', '.join(sorted(self._wanted))})")

    def _discover(self) -> None:
        for topic, count in self._drain.publisher_counts().items():
            if count != self._matched.get(topic):   # who is recorded, as DDS matched it (not the graph's view)
                self._matched[topic] = count
                self.get_logger().info(f"matched {topic}: {count} publisher{'' if count == 1 else 's'}")
        for topic, types in self.get_topic_names_and_types():
            if topic in self._subscribed or topic in _SKIP:
                continue
            if not self.config["all_topics"] and topic not in self._wanted:
                continue
            try:
                cls = _msg_class(types[0])
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warning(f"skipping {topic}: no Python type for {types[0]}",
                                          throttle_duration_sec=10.0)
                continue
            pubs = self.get_publishers_info_by_topic(topic)
            if not pubs and self._seen.setdefault(topic, time.monotonic()) > time.monotonic() - PUBLISHER_WAIT_S:
                continue   # seen through a subscriber only: a publisher's offered QoS is worth a moment's wait
            best_effort = any(p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in pubs)
            qos = QoSProfile(depth=self.config["queue_depth"],
                             reliability=ReliabilityPolicy.BEST_EFFORT if best_effort else ReliabilityPolicy.RELIABLE)
            self._drain.subscribe(topic, types[0], cls, qos)
            self._subscribed.add(topic)
            self._unwritten[topic] = types[0]
            self.get_logger().info(f"subscribed {topic} [{types[0]}]{' best effort' if best_effort else ''}")

    def _connect(self, topic: str) -> None:
        """Add ``topic``'s bag connection with the offered QoS of the publishers known now.

        As ros2 bag record does, the publishers' offered QoS go into metadata.yaml (a player uses them).
        The connection is made at the topic's first message, when its publisher is known even if it
        appeared long after the topic's subscribers, or at close for a topic that got nothing.
        """
        type_name = self._unwritten.pop(topic)
        try:
            profiles = [bag_qos(p.qos_profile) for p in self.get_publishers_info_by_topic(topic)]
        except Exception:   # the context may be shut down at close: the connection without profiles
            profiles = []
        self.writer.connection(topic, type_name, offered_qos_profiles=profiles)

    def _on_messages(self, taken: list) -> None:
        """Write what one pass took (``[(topic, type name, [cdr...]), ...]``), stamped with the time of the pass."""
        stamp = self.get_clock().now().nanoseconds
        counts, write = self.counts, self.writer.write_raw_many
        for topic, type_name, datas in taken:
            if topic in self._unwritten:
                self._connect(topic)
            write(topic, type_name, datas, stamp)
            counts[topic] = counts.get(topic, 0) + len(datas)

    def close(self) -> None:
        """Close the bag (called by the runtime on shutdown): the bag is complete after this.

        What the subscriptions still hold (taken by rcl before the shutdown) is written first.
        """
        try:
            self._on_messages(self._drain.take_all())
        except Exception as exc:   # the middleware may be gone already: keep what was written
            print(f"[recorder] could not take the last messages: {exc}", flush=True)
        for topic in list(self._unwritten):
            self._connect(topic)
        self._drain.destroy()
        self.writer.close()
        total = sum(self.counts.values())
        # the context may already be shut down (rosout unavailable): print instead of the node logger
        print(f"[recorder] closed {self.path}: {total} messages "
              + ", ".join(f"{t}={n}" for t, n in sorted(self.counts.items())), flush=True)


_run = main_for(Recorder)


def main(args: list[str] | None = None) -> None:
    """Run the Recorder node (``--ros-args --params-file FILE`` to configure).

    It uses :data:`~euc_ros.ros.fastdds.RECORDER_PROFILE` unless the Fast DDS transports are chosen already
    (:func:`~euc_ros.ros.fastdds.transport_env`).
    """
    chosen = transport_env(os.environ)
    os.environ.update(chosen)          # before rclpy.init: Fast DDS reads it when the participant is created
    if chosen:
        print(f"[recorder] Fast DDS profile {chosen['FASTRTPS_DEFAULT_PROFILES_FILE']}", flush=True)
    if uses_fast_dds(os.environ):
        # a stale port file of the number the recorder's participant gets would be reused unresized
        removed = remove_stale_fastdds_files()
        if removed:
            ports = sum(p.name.startswith("fastrtps_port") for p in removed)
            print(f"[recorder] removed {len(removed)} stale Fast DDS shared-memory files ({ports} ports) that no "
                  f"process maps ({SHM_CLEAN_ENV}=0 keeps them)", flush=True)
    _run(args)
