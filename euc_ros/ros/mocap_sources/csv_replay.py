"""Source ``csv``: a Motive CSV export replayed at real time times ``rate_factor``.

Stamps are the replay start plus ``(frame - first frame) / rate`` (``stamp_mode: replay``) or the
file's capture start time plus ``frame / rate`` (``stamp_mode: file``); ``stamp_source`` FILE_TIME.
When frames are due and what they are stamped is :class:`~euc_ros.core.mocap.ingest.ReplayClock`; this
module waits for the start (``start_delay``, ``wait_subscribers``), publishes, and ends the node
(``exit_when_done``).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from euc_msgs.msg import MocapFrame

from euc_ros.core.errors import ConfigError
from euc_ros.core.mocap.ingest import Frame, ReplayClock, capture_start_ns
from euc_ros.ros import interfaces as itf
from euc_ros.ros.matching import MatchGate
from euc_ros.ros.mocap_sources.base import MocapSource


class CsvReplay(MocapSource):
    """Replay a Motive CSV export (parameters ``csv_path``, ``rate_factor``, ``loop``, ``stamp_mode``,
    ``start_delay``, ``wait_subscribers``, ``exit_when_done``, ``linger``).

    Attributes
    ----------
    series : MocapSeries
        The recording (selected bodies, world Z-up).
    clock : ReplayClock
    """

    stamp_source = MocapFrame.STAMP_FILE_TIME

    @property
    def hardware_id(self) -> str:
        return f"csv:{Path(self.config['csv_path']).name}"

    def setup(self) -> None:
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
        self.start_gate = MatchGate(lambda: [(itf.MOCAP_FRAME, node.frame_pub.get_subscription_count(),
                                              cfg["wait_subscribers"])])
        self._done_at: float | None = None
        tick = min(0.5 / max(series.rate_hz * cfg["rate_factor"], 1.0), 0.005)
        node.create_timer(tick, self._tick)
        node.get_logger().info(f"replaying {cfg['csv_path']}: {series.n_frames} frames, {len(node.bodies)} bodies, "
                               f"x{cfg['rate_factor']}, stamps {cfg['stamp_mode']}")

    def _ready_to_start(self, now: float) -> bool:
        cfg, node = self.config, self.node
        if now < self._created + cfg["start_delay"]:
            return False
        want = cfg["wait_subscribers"]
        return want <= 0 or self.start_gate.ready(now, lambda _: node.get_logger().info(
            f"waiting for {want} subscription(s) of {itf.MOCAP_FRAME}", throttle_duration_sec=5.0))

    def _tick(self) -> None:
        node, cfg, clock, s = self.node, self.config, self.clock, self.series
        now = time.monotonic()
        if not clock.started:
            if not self._ready_to_start(now):
                return
            clock.start(now, node.get_clock().now().nanoseconds)
        if self._done_at is not None:
            if cfg["exit_when_done"] and now >= self._done_at + cfg["linger"]:
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
