"""Node ``mocap_ingest``: OptiTrack rigid bodies -> ``MocapFrame`` + per-body poses + TF + diagnostics.

Sources (parameter ``source``):

* ``csv``: a Motive CSV export replayed at real time times ``rate_factor`` (stamps: replay start or
  the file's capture start, plus frame / rate);
* ``topics``: one ``geometry_msgs/PoseStamped`` per body on ``<topic_prefix>/<Body>/pose``
  (vrpn_mocap convention), assembled into frames by stamp;
* ``natnet``: live Motive over NatNet 3.x/4.x (multicast or unicast), stamped with the capture time
  (receive time minus the latency the server reports).

Publishes
    ``mocap/frame`` (euc_msgs/MocapFrame, reliable), ``mocap/<body>/pose`` (PoseStamped, tracked
    bodies only), ``/tf`` (world -> body, same stamps), ``/diagnostics`` (tracking rate, lost
    bodies, dropped/duplicate/malformed counts).
Subscribes
    ``<topic_prefix>/<Body>/pose`` with the sensor-data QoS (source ``topics``).
"""
from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from euc_msgs.msg import MocapFrame
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from tf2_msgs.msg import TFMessage

from euc_ros.core.errors import EucError
from euc_ros.core.ingest import Frame, PoseSynchronizer, TrackingStats, replay_schedule
from euc_ros.nodes import convert
from euc_ros.nodes import interfaces as itf
from euc_ros.nodes.params import ParamSpec, declare_params
from euc_ros.nodes.runtime import main_for

SPECS = (
    ParamSpec("source", "csv", "where poses come from", choices=("csv", "topics", "natnet")),
    ParamSpec("csv_path", "", "Motive CSV export to replay (source csv)"),
    ParamSpec("world_up", "y", "up axis of the Motive world (Motive's default is y)", choices=("y", "z")),
    ParamSpec("bodies", [""], "rigid bodies to publish, in order (empty: all in the source)"),
    ParamSpec("rate_factor", 1.0, "replay speed relative to real time (source csv)", "", 0.01, 1000.0),
    ParamSpec("loop", False, "restart the CSV replay at the end"),
    ParamSpec("stamp_mode", "replay", "csv stamps: replay start + frame/rate, or the file's capture start",
              choices=("replay", "file")),
    ParamSpec("start_delay", 1.0, "wait before the first CSV frame so subscribers can match", "s", 0.0, 60.0),
    ParamSpec("exit_when_done", False, "exit (code 0) after the CSV replay ends and linger has passed"),
    ParamSpec("linger", 1.0, "time to keep running after the last CSV frame", "s", 0.0, 3600.0),
    ParamSpec("topic_prefix", itf.VRPN_PREFIX, "prefix of the per-body PoseStamped inputs (source topics)"),
    ParamSpec("sync_tolerance", 0.002, "poses closer than this belong to one frame (source topics)", "s",
              0.0, 1.0),
    ParamSpec("sync_timeout", 0.05, "a partial frame is published untracked after this (source topics)", "s",
              0.001, 10.0),
    ParamSpec("server_ip", "127.0.0.1", "Motive host (source natnet)"),
    ParamSpec("local_ip", "0.0.0.0", "local interface for NatNet (source natnet)"),
    ParamSpec("multicast", True, "NatNet multicast (true) or unicast with keep-alives (false)"),
    ParamSpec("multicast_group", "239.255.42.99", "NatNet multicast group"),
    ParamSpec("command_port", 1510, "NatNet command port", "", 1, 65535),
    ParamSpec("data_port", 1511, "NatNet data port", "", 1, 65535),
    ParamSpec("frame_id", "world", "world frame of the published poses (REP-105)"),
    ParamSpec("publish_poses", True, "publish one PoseStamped per body"),
    ParamSpec("publish_tf", True, "publish world -> body transforms on /tf"),
    ParamSpec("diagnostics_period", 1.0, "period of the diagnostics", "s", 0.05, 60.0),
)


class MocapIngest(Node):
    """Publish OptiTrack rigid bodies as MocapFrame, poses, TF and diagnostics."""

    NAME = "mocap_ingest"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = cfg = declare_params(self, SPECS)
        self.bodies = [b for b in cfg["bodies"] if b]
        self.frame_pub = self.create_publisher(MocapFrame, itf.MOCAP_FRAME, itf.RELIABLE_QOS)
        self.tf_pub = self.create_publisher(TFMessage, itf.TF, itf.RELIABLE_QOS) if cfg["publish_tf"] else None
        self.diag_pub = self.create_publisher(DiagnosticArray, itf.DIAGNOSTICS, itf.DIAGNOSTICS_QOS)
        self.pose_pubs: dict[str, object] = {}
        self.stats: TrackingStats | None = None
        self.published = 0
        getattr(self, f"_setup_{cfg['source']}")()
        self.create_timer(cfg["diagnostics_period"], self._publish_diagnostics)

    # -- sources ---------------------------------------------------------------------------------
    def _setup_csv(self) -> None:
        from euc_ros.core.io.motive_csv import read_motive_csv

        cfg = self.config
        if not cfg["csv_path"]:
            raise EucError("parameter 'csv_path' is required with source 'csv'")
        series = read_motive_csv(cfg["csv_path"], world_up=cfg["world_up"])
        if self.bodies:
            series = series.select(self.bodies)
        self.series = series
        self.bodies = list(series.bodies)
        self.stamp_source = MocapFrame.STAMP_FILE_TIME
        self._schedule = replay_schedule(series.t, cfg["rate_factor"])
        self._next = 0
        self._t0_wall = time.monotonic() + cfg["start_delay"]
        if cfg["stamp_mode"] == "file":
            self._t0_stamp = int(series.meta.get("start_time_ns", 0) or 0)
        else:
            self._t0_stamp = self.get_clock().now().nanoseconds + int(cfg["start_delay"] * 1e9)
        self._done_at: float | None = None
        period = min(0.5 / max(series.rate_hz * cfg["rate_factor"], 1.0), 0.005)
        self.create_timer(period, self._replay_tick)
        self.get_logger().info(f"replaying {cfg['csv_path']}: {series.n_frames} frames, {len(self.bodies)} bodies, "
                               f"x{cfg['rate_factor']}")

    def _replay_tick(self) -> None:
        if self._done_at is not None:
            if self.config["exit_when_done"] and time.monotonic() >= self._done_at + self.config["linger"]:
                self.get_logger().info(f"replay finished: {self.published} frames published")
                raise SystemExit(0)
            return
        elapsed = time.monotonic() - self._t0_wall
        s = self.series
        t0 = s.t[0] if s.n_frames else 0.0
        while self._next < s.n_frames and self._schedule[self._next] <= elapsed:
            k = self._next
            stamp = self._t0_stamp + int(round((s.t[k] - t0) * 1e9))
            if self.config["stamp_mode"] == "file":
                stamp = self._t0_stamp + int(round(s.t[k] * 1e9))
            self._publish(Frame(stamp, int(s.frame[k]), self.bodies, s.position[:, k], s.quat[:, k],
                                s.tracked[:, k], s.mean_marker_error[:, k]))
            self._next += 1
        if self._next >= s.n_frames:
            if self.config["loop"] and s.n_frames:
                self._next = 0
                self._t0_wall = time.monotonic()
                self._t0_stamp = self.get_clock().now().nanoseconds
                if self.stats is not None:
                    self.stats.last_frame_number = None
            else:
                self._done_at = time.monotonic()

    def _setup_topics(self) -> None:
        if not self.bodies:
            raise EucError("parameter 'bodies' must list the rigid bodies with source 'topics'")
        cfg = self.config
        self.stamp_source = MocapFrame.STAMP_SOURCE_HEADER
        self.sync = PoseSynchronizer(self.bodies, cfg["sync_tolerance"], cfg["sync_timeout"])
        prefix = cfg["topic_prefix"].rstrip("/")
        for body in self.bodies:
            self.create_subscription(PoseStamped, f"{prefix}/{body}/pose",
                                     lambda msg, b=body: self._on_pose(b, msg), itf.MOCAP_INPUT_QOS)
        self.create_timer(cfg["sync_timeout"], self._flush)

    def _on_pose(self, body: str, msg: PoseStamped) -> None:
        stamp, pos, quat = convert.pose_from_msg(msg)
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(quat))) or abs(np.linalg.norm(quat) - 1) > 1e-3:
            self._ensure_stats().malformed += 1
            return
        for frame in self.sync.push(body, stamp, pos, quat):
            self._publish(frame)

    def _flush(self) -> None:
        for frame in self.sync.flush(self.get_clock().now().nanoseconds):
            self._publish(frame)

    def _setup_natnet(self) -> None:
        from euc_ros.core.io.natnet_client import NatNetClient

        cfg = self.config
        self.stamp_source = MocapFrame.STAMP_CAPTURE_TIME
        self.client = NatNetClient(cfg["server_ip"], local_ip=cfg["local_ip"], multicast=cfg["multicast"],
                                   multicast_group=cfg["multicast_group"], command_port=cfg["command_port"],
                                   data_port=cfg["data_port"])
        self.names_by_id: dict[int, str] = {}
        self.server_info = None
        self.create_timer(0.001, self._natnet_tick)

    def _natnet_tick(self) -> None:
        from euc_ros.core.io import natnet

        try:
            messages = self.client.poll(0.0)
        except EucError as exc:
            self._ensure_stats().malformed += 1
            self.get_logger().warning(f"NatNet: {exc}", throttle_duration_sec=5.0)
            return
        now = self.get_clock().now().nanoseconds
        for m in messages:
            if isinstance(m, natnet.ServerInfo):
                self.server_info = m
            elif isinstance(m, natnet.ModelDef):
                self.names_by_id = {int(i): str(n) for i, n in m.rigid_bodies.items()}
                if not self.bodies:
                    self.bodies = list(self.names_by_id.values())
            elif isinstance(m, natnet.FrameOfData) and self.bodies:
                self._publish(self._natnet_frame(m, now))

    def _natnet_frame(self, m, now_ns: int) -> Frame:
        from euc_ros.core.io import natnet

        b = len(self.bodies)
        index = {name: i for i, name in enumerate(self.bodies)}
        frame = Frame(now_ns, int(m.frame_number), self.bodies, np.full((b, 3), np.nan), np.full((b, 4), np.nan),
                      np.zeros(b, bool), np.full(b, np.nan))
        if self.server_info is not None:
            latency = natnet.latency_s(m, self.server_info)
            if np.isfinite(latency) and 0 <= latency < 1.0:
                frame.stamp_ns = now_ns - int(latency * 1e9)
        for rb in m.rigid_bodies:
            i = index.get(self.names_by_id.get(int(rb.id), ""))
            if i is None or not rb.tracking_valid:
                continue
            frame.position[i], frame.quat[i] = rb.position, rb.quat
            frame.tracked[i], frame.mean_marker_error[i] = True, rb.mean_error
        return frame

    # -- output ----------------------------------------------------------------------------------
    def _ensure_stats(self) -> TrackingStats:
        if self.stats is None:
            self.stats = TrackingStats(self.bodies)
        return self.stats

    def _publish(self, frame: Frame) -> None:
        stats = self._ensure_stats()
        if not stats.accept(frame.frame_number):
            return
        stats.update(frame.tracked, frame.stamp_ns)
        fid = self.config["frame_id"]
        self.frame_pub.publish(convert.frame_to_msg(frame, fid, self.stamp_source))
        self.published += 1
        transforms = []
        for i, body in enumerate(frame.bodies):
            if not frame.tracked[i]:
                continue  # an untracked body is invalid in the frame and absent here: never a zero pose
            if self.config["publish_poses"]:
                pub = self.pose_pubs.get(body)
                if pub is None:
                    pub = self.pose_pubs[body] = self.create_publisher(PoseStamped, itf.body_pose_topic(body),
                                                                       itf.RELIABLE_QOS)
                pub.publish(convert.pose_stamped(frame.stamp_ns, fid, frame.position[i], frame.quat[i]))
            if self.tf_pub is not None:
                transforms.append(convert.transform_stamped(frame.stamp_ns, fid, itf.sanitize(body),
                                                            frame.position[i], frame.quat[i]))
        if transforms:
            self.tf_pub.publish(TFMessage(transforms=transforms))

    def _publish_diagnostics(self) -> None:
        stats = self._ensure_stats()
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        rate = stats.frame_rate_hz()
        level = convert.OK if stats.frames else convert.STALE
        arr.status.append(convert.status(
            "mocap_ingest: stream", level, "receiving" if stats.frames else "no frames yet",
            {"source": self.config["source"], "frames": stats.frames, "rate_hz": rate, "dropped_frames": stats.dropped,
             "duplicates_dropped": stats.duplicates, "out_of_order_dropped": stats.out_of_order,
             "malformed_dropped": stats.malformed}))
        rates, lost = stats.tracking_rate(), stats.lost()
        for i, body in enumerate(stats.bodies):
            arr.status.append(convert.status(
                f"mocap_ingest: {body}", convert.WARN if lost[i] else convert.OK,
                "lost tracking" if lost[i] else "tracked", {"tracking_rate": float(rates[i]), "lost": bool(lost[i])},
                hardware_id=body))
        self.diag_pub.publish(arr)

    def close(self) -> None:
        """Release the NatNet sockets, if any."""
        client = getattr(self, "client", None)
        if client is not None:
            client.close()


main = main_for(MocapIngest)
