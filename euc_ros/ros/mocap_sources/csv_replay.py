"""Source ``csv``: a Motive CSV export replayed at real time times ``rate_factor``.

Stamps are the replay start plus ``(frame - first frame) / rate`` (``stamp_mode: replay``) or the
file's capture start time plus ``frame / rate`` (``stamp_mode: file``); ``stamp_source`` FILE_TIME.
When frames are due and what they are stamped is :class:`~euc_ros.core.mocap.replay.ReplayClock`; this
module waits for the start (``start_delay``, ``wait_subscribers``, ``wait_topics``), publishes, and ends
the node (``exit_when_done``).

A replay that must reach a recorder whole starts once every consumer is there, and ends once every
consumer has every frame: ``wait_subscribers`` counts the subscriptions ``mocap/frame`` has matched,
``wait_topics`` the subscriptions of further topics (the stages downstream: matched by the node's own
publisher of the topic, else as the ROS graph lists them), and at the end the node
waits until every subscription of its frame, pose and transform publishers has acknowledged all
they published (:data:`ACK_TIMEOUT_S` at most) before ``linger`` and its exit. A subscriber whose
middleware was starved of CPU is still repairing its losses from the publishers' history then, and a
publisher that exits takes that history with it.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from euc_msgs.msg import MocapFrame
from rclpy.duration import Duration

from euc_ros.core.errors import ConfigError
from euc_ros.core.mocap.capture_time import capture_start_ns
from euc_ros.core.mocap.frame import Frame
from euc_ros.core.mocap.replay import ReplayClock
from euc_ros.ros import interfaces as itf
from euc_ros.ros.matching import MatchGate
from euc_ros.ros.mocap_sources.base import MocapSource

#: Longest wait, after the last frame, for every subscriber to acknowledge every message [s]; after it
#: the node lingers and exits anyway, with a warning.
ACK_TIMEOUT_S = 30.0


def parse_wait_topics(entries) -> list[tuple[str, int]]:
    """``["topic=N", ...]`` (parameter ``wait_topics``) as ``[(topic, N), ...]``; empty entries are skipped.

    Examples
    --------
    >>> parse_wait_topics(["rider/state=3", " /tf = 1", ""])
    [('rider/state', 3), ('/tf', 1)]
    """
    out = []
    for entry in entries:
        if not entry.strip():
            continue
        topic, sep, count = entry.partition("=")
        try:
            n = int(count)
        except ValueError:
            n = -1
        if not sep or not topic.strip() or n < 0:
            raise ConfigError(f"wait_topics entry {entry!r}: expected 'topic=N' with N >= 0", key="wait_topics")
        out.append((topic.strip(), n))
    return out


class CsvReplay(MocapSource):
    """Replay a Motive CSV export.

    Configured by the parameters ``csv_path``, ``rate_factor``, ``loop``, ``stamp_mode``, ``start_delay``,
    ``wait_subscribers``, ``wait_topics``, ``exit_when_done``, ``linger``.

    Attributes
    ----------
    series : MocapSeries
        The recording (selected bodies, world Z-up).
    clock : ReplayClock
    """

    stamp_source = MocapFrame.STAMP_FILE_TIME

    @property
    def hardware_id(self) -> str:
        """The capture system: ``csv:<file name>``."""
        return f"csv:{Path(self.config['csv_path']).name}"

    def setup(self) -> None:
        """Read the CSV and start the replay timer (the start waits for :meth:`_wants`).

        Raises
        ------
        ConfigError
            Without ``csv_path``.
        """
        from euc_ros.core.io.motive_csv import read_motive_csv, require_rigid_bodies

        node, cfg = self.node, self.config
        if not cfg["csv_path"]:
            raise ConfigError("parameter 'csv_path' is required with source 'csv'", key="csv_path")
        series = read_motive_csv(cfg["csv_path"], world_up=node.world_up)
        require_rigid_bodies(series, cfg["csv_path"])
        if node.bodies:
            series = series.select(node.bodies)
        self.series = series
        node.set_bodies(list(series.bodies))
        known = np.isfinite(series.rate_hz) and series.rate_hz > 0
        self.rate_hz = float(series.rate_hz) if known else None
        file_start_ns = None
        if cfg["stamp_mode"] == "file":
            file_start_ns = capture_start_ns(series.meta.get("start_time"))
            if file_start_ns is None:
                node.get_logger().warning(f"no readable Capture Start Time in {cfg['csv_path']}: "
                                          "file stamps start at 0")
                file_start_ns = 0
        self.clock = ReplayClock(series.t, cfg["rate_factor"], 1.0 / series.rate_hz if known else 0.0,
                                 loop=cfg["loop"], file_start_ns=file_start_ns)
        self._created = time.monotonic()
        self._wait_topics = parse_wait_topics(cfg["wait_topics"])
        self.start_gate = MatchGate(self._wants)
        self._done_at: float | None = None
        self._acked_at: float | None = None
        tick = min(0.5 / max(series.rate_hz * cfg["rate_factor"], 1.0), 0.005)
        node.create_timer(tick, self._tick)
        node.get_logger().info(f"replaying {cfg['csv_path']}: {series.n_frames} frames, {len(node.bodies)} bodies, "
                               f"x{cfg['rate_factor']}, stamps {cfg['stamp_mode']}")

    def _stream_publishers(self) -> list:
        """The publishers of the frames, poses and transforms (what a recorder of the replay takes)."""
        node = self.node
        return [p for p in (node.frame_pub, node.tf_pub, *node.pose_pubs.values()) if p is not None]

    def _wants(self) -> list[tuple[str, int, int]]:
        """What the start waits for (:class:`~euc_ros.ros.matching.MatchGate`).

        The subscriptions matched by ``mocap/frame``, and per ``wait_topics`` entry its subscriptions, as
        matched by this node's own publisher of the topic, else as the ROS graph lists them.
        """
        node = self.node
        wants = [(f"{itf.MOCAP_FRAME} subscriptions", node.frame_pub.get_subscription_count(),
                  self.config["wait_subscribers"])]
        own = {p.topic_name: p for p in self._stream_publishers()}
        for topic, need in self._wait_topics:
            pub = own.get(node.resolve_topic_name(topic))
            have = pub.get_subscription_count() if pub is not None else node.count_subscribers(topic)
            wants.append((f"{topic} subscriptions", have, need))
        return wants

    def _ready_to_start(self, now: float) -> bool:
        cfg, node = self.config, self.node
        if now < self._created + cfg["start_delay"]:
            return False
        if cfg["wait_subscribers"] <= 0 and not self._wait_topics:
            return True
        return self.start_gate.ready(now, lambda missing: node.get_logger().info(
            f"waiting for {', '.join(missing)}", throttle_duration_sec=5.0))

    def _all_acked(self) -> bool:
        """Whether every subscription of the stream's publishers has acknowledged all they published."""
        now = Duration(seconds=0)
        return all(p.wait_for_all_acked(now) for p in self._stream_publishers())

    def _finished(self, now: float) -> bool:
        """After the last frame: whether every subscriber has every frame and ``linger`` has passed since.

        True once every subscriber has every frame (or :data:`ACK_TIMEOUT_S` passed) and ``linger`` has passed
        since.
        """
        if self._acked_at is None:
            acked = self._all_acked()
            if not acked and now < self._done_at + ACK_TIMEOUT_S:
                return False
            if not acked:
                self.node.get_logger().warning(f"a subscriber has not acknowledged every frame {ACK_TIMEOUT_S:.0f} s "
                                               "after the last one: it may miss the last frames")
            self._acked_at = now
        return now >= self._acked_at + self.config["linger"]

    def _tick(self) -> None:
        node, cfg, clock, s = self.node, self.config, self.clock, self.series
        now = time.monotonic()
        if not clock.started:
            if not self._ready_to_start(now):
                return
            clock.start(now, node.get_clock().now().nanoseconds)
            node.get_logger().info(f"replay started: {node.frame_pub.get_subscription_count()} subscription(s) of "
                                   f"{itf.MOCAP_FRAME}")
        if self._done_at is not None:
            if cfg["exit_when_done"] and self._finished(now):
                node.get_logger().info(f"replay finished: {node.published} frames published")
                raise SystemExit(0)
            return
        frames, event = clock.due(now)
        for k, stamp in frames:
            node.received += 1
            node.publish_frame(Frame(stamp, int(s.frame[k]), node.bodies, s.position[:, k], s.quat[:, k],
                                     s.tracked[:, k], s.mean_marker_error[:, k]))
        if event == "loop":
            node.stats.restart()   # frame numbers start again: a restart, not out-of-order frames
        elif event == "end":
            self._done_at = now
