"""Node ``mocap_ingest``: OptiTrack rigid bodies -> ``MocapFrame`` + per-body poses + TF + diagnostics.

Sources (parameter ``source``):

* ``csv``: a Motive CSV export replayed at real time times ``rate_factor``; stamps are the replay
  start plus ``(frame - first frame) / rate`` (``stamp_mode: replay``) or the file's capture start
  time plus ``frame / rate`` (``stamp_mode: file``); ``stamp_source`` FILE_TIME.
* ``topics``: one ``geometry_msgs/PoseStamped`` per body on ``<topic_prefix>/<Body>/pose``
  (vrpn_mocap convention, Z-up), assembled into frames by header stamp; frame stamp = header stamp
  (``stamp_source`` SOURCE_HEADER), frame number -1 (unknown).
* ``natnet``: live Motive over NatNet 3.x/4.x (multicast or unicast with keep-alives), stamped with
  the capture time: receive time minus the latency the server reports (``stamp_source``
  CAPTURE_TIME; RECEIVE_TIME for frames without a usable latency).

Bad input never stops the node: duplicate and out-of-order stamps or frame numbers, malformed
NatNet packets and invalid poses are dropped (or published untracked) and counted in the
diagnostics. The logic lives in :mod:`euc_ros.core.ingest`; this module only wires ROS.

Publishes
    ``mocap/frame`` (euc_msgs/MocapFrame, reliable, every frame), ``mocap/<body>/pose``
    (PoseStamped, tracked bodies only) and ``/tf`` (world -> body, same stamps), both at most about
    ``view_rate`` (default 120 Hz: every frame up to 120 Hz, every 3rd at 360 Hz), ``/diagnostics``
    (tracking rate, lost bodies, dropped/duplicate/out-of-order/restart/malformed counts).
Subscribes
    ``<topic_prefix>/<Body>/pose`` with the sensor-data QoS (source ``topics``).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from euc_msgs.msg import MocapFrame
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from tf2_msgs.msg import TFMessage

from euc_ros.core.errors import ConfigError
from euc_ros.core.io import cdr_frame
from euc_ros.core.mocap.ingest import (
    Frame,
    PoseSynchronizer,
    TrackingStats,
    capture_start_ns,
    frame_from_named_poses,
    frame_from_natnet,
    natnet_capture_stamp,
    replay_schedule,
)
from euc_ros.nodes import convert
from euc_ros.nodes import interfaces as itf
from euc_ros.nodes.intra import LocalFanout
from euc_ros.nodes.params import ParamSpec, declare_params
from euc_ros.nodes.runtime import main_for

SPECS = (
    ParamSpec("source", "csv", "where poses come from", choices=("csv", "topics", "natnet")),
    ParamSpec("csv_path", "", "Motive CSV export to replay (source csv)"),
    ParamSpec("world_up", "y", "up axis of the Motive world: CSV, NatNet and rigid_bodies topics (Motive's default "
              "is y)",
              choices=("y", "z")),
    ParamSpec("bodies", [""], "rigid bodies to publish, in order (empty: all in the source; required for topics)"),
    ParamSpec("rate_factor", 1.0, "replay speed relative to real time (source csv)", "", 0.01, 1000.0),
    ParamSpec("loop", False, "restart the CSV replay at the end (replay stamps keep increasing)"),
    ParamSpec("stamp_mode", "replay", "csv stamps: replay start + frame/rate, or the file's capture start time",
              choices=("replay", "file")),
    ParamSpec("start_delay", 1.0, "wait before the first CSV frame so subscribers can match", "s", 0.0, 60.0),
    ParamSpec("wait_subscribers", 0, "also wait until mocap/frame has this many subscriptions, then 0.3 s "
              "(source csv)", "", 0, 1000),
    ParamSpec("exit_when_done", False, "exit (code 0) after the CSV replay ends and linger has passed"),
    ParamSpec("linger", 1.0, "time to keep running after the last CSV frame", "s", 0.0, 3600.0),
    ParamSpec("topic_type", "pose_stamped", "message of source topics: one geometry_msgs/PoseStamped per body "
              "(vrpn_mocap), or mocap4r2_msgs/RigidBodies per frame (the MOCAP4ROS2 OptiTrack driver)",
              choices=("pose_stamped", "rigid_bodies")),
    ParamSpec("rigid_bodies_topic", "/rigid_bodies", "mocap4r2_msgs/RigidBodies input (source topics, topic_type "
              "rigid_bodies)"),
    ParamSpec("input_reliability", "best_effort", "QoS of the source topics: best_effort matches every driver; "
              "reliable loses nothing on a loaded host but matches reliable publishers only (euc-ros play)",
              choices=("best_effort", "reliable")),
    ParamSpec("topic_prefix", itf.VRPN_PREFIX, "prefix of the per-body PoseStamped inputs (source topics)"),
    ParamSpec("sync_tolerance", 0.002, "poses closer than this belong to one frame (source topics)", "s",
              0.0, 1.0),
    ParamSpec("sync_timeout", 0.05, "a partial frame is published with missing bodies untracked after this "
              "(source topics)", "s", 0.001, 10.0),
    ParamSpec("restart_jump", 1.0, "stamps jumping back by more than this mean the source restarted (source topics)",
              "s", 0.01, 3600.0),
    ParamSpec("restart_frames", 100, "frame numbers jumping back by more than this mean the source restarted",
              "frames", 1, 1_000_000_000),
    ParamSpec("server_ip", "127.0.0.1", "Motive host (source natnet)"),
    ParamSpec("local_ip", "0.0.0.0", "local interface for NatNet (source natnet)"),
    ParamSpec("multicast", True, "NatNet multicast (true) or unicast with keep-alives (false)"),
    ParamSpec("multicast_group", "239.255.42.99", "NatNet multicast group"),
    ParamSpec("command_port", 1510, "NatNet command port", "", 1, 65535),
    ParamSpec("data_port", 1511, "NatNet data port", "", 1, 65535),
    ParamSpec("keepalive_period", 1.0, "period of NatNet keep-alives in unicast", "s", 0.05, 60.0),
    ParamSpec("max_latency", 1.0, "NatNet latencies above this are not trusted (receive time is used)", "s",
              0.0, 10.0),
    ParamSpec("poll_period", 0.001, "how often the NatNet sockets are drained", "s", 0.0002, 0.1),
    ParamSpec("frame_id", "world", "world frame of the published poses (REP-105)"),
    ParamSpec("publish_poses", True, "publish one PoseStamped per body", live=True),
    ParamSpec("publish_tf", True, "publish world -> body transforms on /tf"),
    ParamSpec("view_rate", 120.0, "poses and /tf at most about this rate, by whole-frame decimation (viewers "
              "refresh at 60 Hz or less); mocap/frame always carries every frame; 0: poses and /tf every frame",
              "Hz", 0.0, 100000.0),
    ParamSpec("diagnostics_period", 1.0, "period of the diagnostics", "s", 0.05, 60.0),
)

#: Wait after the wanted subscriptions matched before the CSV replay starts (asymmetric DDS discovery) [s].
SETTLE_S = 0.3


class MocapIngest(Node):
    """Publish OptiTrack rigid bodies as MocapFrame, poses, TF and diagnostics.

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ``namespace``...).

    Attributes
    ----------
    stats : TrackingStats
        Frame and tracking counters (``frames``, ``dropped``, ``duplicates``, ``out_of_order``,
        ``restarts``, ``malformed``).
    published : int
        MocapFrame messages published.
    received : int
        Inputs handled (poses for ``topics``, NatNet messages for ``natnet``, frames for ``csv``).
    errors : int
        Inputs that raised while being handled (dropped; the node goes on).
    """

    NAME = "mocap_ingest"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = cfg = declare_params(self, SPECS)
        self.bodies = [b for b in cfg["bodies"] if b]
        self.frame_pub = self.create_publisher(MocapFrame, itf.MOCAP_FRAME, itf.RELIABLE_QOS,
                                               event_callbacks=itf.pub_events())
        self.tf_pub = self.create_publisher(TFMessage, itf.TF, itf.RELIABLE_QOS,
                                            event_callbacks=itf.pub_events()) if cfg["publish_tf"] else None
        self.diag_pub = self.create_publisher(DiagnosticArray, itf.DIAGNOSTICS, itf.DIAGNOSTICS_QOS,
                                              event_callbacks=itf.pub_events())
        self.pose_pubs: dict[str, object] = {}
        self.stats = TrackingStats(self.bodies, restart_frames=cfg["restart_frames"])
        self.published = 0
        self.received = 0
        self.errors = 0
        self.stamp_source = MocapFrame.STAMP_FILE_TIME
        self._last_frame_wall: float | None = None
        self._last_view_ns: int | None = None
        self.view_published = 0
        self.client = None
        self.sync = None
        getattr(self, f"_setup_{cfg['source']}")()
        #: what the stream diagnostics concern (diagnostic_updater's hardware_id): the capture system
        self.hardware_id = {"natnet": f"natnet://{cfg['server_ip']}", "csv": f"csv:{Path(cfg['csv_path']).name}",
                            "topics": f"topics:{cfg['topic_prefix']}"}.get(cfg["source"], cfg["source"])
        self.create_timer(cfg["diagnostics_period"], self._publish_diagnostics)

    # -- csv -------------------------------------------------------------------------------------
    def _setup_csv(self) -> None:
        from euc_ros.core.io.motive_csv import read_motive_csv

        cfg = self.config
        if not cfg["csv_path"]:
            raise ConfigError("parameter 'csv_path' is required with source 'csv'", key="csv_path")
        series = read_motive_csv(cfg["csv_path"], world_up=cfg["world_up"])
        if self.bodies:
            series = series.select(self.bodies)
        self.series = series
        self._set_bodies(list(series.bodies))
        self._schedule = replay_schedule(series.t, cfg["rate_factor"])
        n = series.n_frames
        period = 1.0 / series.rate_hz if np.isfinite(series.rate_hz) and series.rate_hz > 0 else 0.0
        self._loop_span_s = (float(series.t[-1] - series.t[0]) if n else 0.0) + period   # data time per loop
        self._file_start_ns = capture_start_ns(series.meta.get("start_time"))
        if cfg["stamp_mode"] == "file" and self._file_start_ns is None:
            self.get_logger().warning(f"no readable Capture Start Time in {cfg['csv_path']}: file stamps start at 0")
            self._file_start_ns = 0
        self._created = time.monotonic()
        self._matched_at: float | None = None
        self._t0_wall: float | None = None
        self._t0_stamp = 0
        self._loop_index = 0
        self._next = 0
        self._done_at: float | None = None
        tick = min(0.5 / max(series.rate_hz * cfg["rate_factor"], 1.0), 0.005)
        self.create_timer(tick, self._replay_tick)
        self.get_logger().info(f"replaying {cfg['csv_path']}: {n} frames, {len(self.bodies)} bodies, "
                               f"x{cfg['rate_factor']}, stamps {cfg['stamp_mode']}")

    def _ready_to_start(self, now: float) -> bool:
        cfg = self.config
        if now < self._created + cfg["start_delay"]:
            return False
        want = cfg["wait_subscribers"]
        if want <= 0:
            return True
        if self._matched_at is None:
            if self.frame_pub.get_subscription_count() < want:
                self.get_logger().info(f"waiting for {want} subscription(s) of {itf.MOCAP_FRAME}",
                                       throttle_duration_sec=5.0)
                return False
            self._matched_at = now
        return now >= self._matched_at + SETTLE_S

    def _replay_tick(self) -> None:
        cfg, s = self.config, self.series
        now = time.monotonic()
        if self._t0_wall is None:
            if not self._ready_to_start(now):
                return
            self._t0_wall = now
            self._t0_stamp = self.get_clock().now().nanoseconds
        if self._done_at is not None:
            if cfg["exit_when_done"] and now >= self._done_at + cfg["linger"]:
                self.get_logger().info(f"replay finished: {self.published} frames published")
                raise SystemExit(0)
            return
        t0 = float(s.t[0]) if s.n_frames else 0.0
        loop_wall = self._loop_index * self._loop_span_s / cfg["rate_factor"]
        elapsed = now - self._t0_wall - loop_wall
        while self._next < s.n_frames and self._schedule[self._next] <= elapsed:
            k = self._next
            if cfg["stamp_mode"] == "file":
                stamp = self._file_start_ns + int(round(float(s.t[k]) * 1e9))
            else:
                stamp = self._t0_stamp + int(round((float(s.t[k]) - t0 + self._loop_index * self._loop_span_s) * 1e9))
            self.received += 1
            self._publish(Frame(stamp, int(s.frame[k]), self.bodies, s.position[:, k], s.quat[:, k],
                                s.tracked[:, k], s.mean_marker_error[:, k]))
            self._next += 1
        if self._next >= s.n_frames:
            if cfg["loop"] and s.n_frames:
                self._next = 0
                self._loop_index += 1
                self.stats.restart()   # frame numbers start again: a restart, not out-of-order frames
            else:
                self._done_at = now

    # -- topics ----------------------------------------------------------------------------------
    def _setup_topics(self) -> None:
        cfg = self.config
        if cfg["topic_type"] == "rigid_bodies":
            return self._setup_rigid_bodies()
        if not self.bodies:
            raise ConfigError("parameter 'bodies' must list the rigid bodies with source 'topics'", key="bodies")
        self.stamp_source = MocapFrame.STAMP_SOURCE_HEADER
        self.sync = PoseSynchronizer(self.bodies, cfg["sync_tolerance"], cfg["sync_timeout"], cfg["restart_jump"])
        self._set_bodies(self.bodies)
        prefix = cfg["topic_prefix"].rstrip("/")
        for body in self.bodies:
            self.create_subscription(PoseStamped, f"{prefix}/{body}/pose",
                                     lambda msg, b=body: self._on_pose(b, msg),
                                     itf.mocap_input_qos(cfg["input_reliability"]))
        self.create_timer(min(cfg["sync_timeout"] / 2, 0.01), self._flush)
        self.get_logger().info(f"assembling frames of {', '.join(self.bodies)} from {prefix}/<Body>/pose")

    def _on_pose(self, body: str, msg: PoseStamped) -> None:
        self.received += 1
        try:
            stamp, pos, quat = convert.pose_from_msg(msg)
            for frame in self.sync.push(body, stamp, pos, quat, arrival_ns=time.monotonic_ns()):
                self._publish(frame)
        except Exception as exc:   # never die on input
            self._input_error(exc)

    def _flush(self) -> None:
        try:
            for frame in self.sync.flush(time.monotonic_ns()):
                self._publish(frame)
        except Exception as exc:
            self._input_error(exc)

    def _setup_rigid_bodies(self) -> None:
        cfg = self.config
        try:
            from mocap4r2_msgs.msg import RigidBodies
        except ImportError:
            raise ConfigError("topic_type 'rigid_bodies' needs the mocap4r2_msgs interfaces: install them "
                              "(ros-jazzy-mocap4r2-msgs, or ./run setup builds extra_interfaces/mocap4r2_msgs)",
                              key="topic_type") from None
        self.stamp_source = MocapFrame.STAMP_SOURCE_HEADER
        self.unknown_bodies: set[str] = set()
        if self.bodies:
            self._set_bodies(self.bodies)
        self.create_subscription(RigidBodies, cfg["rigid_bodies_topic"], self._on_rigid_bodies,
                                 itf.mocap_input_qos(cfg["input_reliability"]))
        which = ", ".join(self.bodies) if self.bodies else "the bodies of the first message"
        self.get_logger().info(f"frames of {which} from {cfg['rigid_bodies_topic']} (mocap4r2_msgs/RigidBodies, "
                               f"world {cfg['world_up']}-up)")

    def _on_rigid_bodies(self, msg) -> None:
        self.received += 1
        try:
            names, pos, quat = convert.rigid_bodies_arrays(msg)
            if not self.bodies:               # the first message names the bodies (their order kept)
                self._set_bodies(list(dict.fromkeys(names)))
            frame, unknown = frame_from_named_poses(convert.stamp_to_ns(msg.header.stamp), int(msg.frame_number),
                                                    names, pos, quat, self.bodies, self.config["world_up"])
            if unknown and not set(unknown) <= self.unknown_bodies:
                self.unknown_bodies.update(unknown)
                self.get_logger().warning(f"ignoring bodies not in 'bodies': {', '.join(sorted(self.unknown_bodies))}")
            self._publish(frame)
        except Exception as exc:   # never die on input
            self._input_error(exc)

    # -- natnet ----------------------------------------------------------------------------------
    def _setup_natnet(self) -> None:
        from euc_ros.core.io.natnet_client import NatNetClient

        cfg = self.config
        self.stamp_source = MocapFrame.STAMP_CAPTURE_TIME
        self._configured_bodies = list(self.bodies)
        self.names_by_id: dict[int, str] = {}
        self.no_names_dropped = 0
        self.client = NatNetClient(cfg["server_ip"], local_ip=cfg["local_ip"], multicast=cfg["multicast"],
                                   multicast_group=cfg["multicast_group"], command_port=cfg["command_port"],
                                   data_port=cfg["data_port"], keepalive_s=cfg["keepalive_period"],
                                   clock_ns=lambda: self.get_clock().now().nanoseconds)
        self.create_timer(cfg["poll_period"], self._natnet_tick)
        mode = "multicast " + cfg["multicast_group"] if cfg["multicast"] else "unicast"
        self.get_logger().info(f"NatNet: connecting to {cfg['server_ip']}:{cfg['command_port']} ({mode})")

    def _natnet_tick(self) -> None:
        from euc_ros.core.io import natnet

        try:
            messages = self.client.poll(0.0)
        except Exception as exc:   # the client does not raise on input; be safe anyway
            self._input_error(exc)
            return
        for m in messages:
            self.received += 1
            try:
                if isinstance(m, natnet.ServerInfo):
                    self.get_logger().info(f"NatNet: {m.app_name} {'.'.join(map(str, m.app_version))}, "
                                           f"NatNet {m.version[0]}.{m.version[1]}")
                elif isinstance(m, natnet.ModelDef):
                    self._on_model_def(m)
                elif isinstance(m, natnet.FrameOfData):
                    self._on_natnet_frame(m)
            except Exception as exc:
                self._input_error(exc)

    def _on_model_def(self, m) -> None:
        self.names_by_id = {int(i): str(n) for i, n in m.rigid_bodies.items()}
        names = list(self.names_by_id.values())
        if self._configured_bodies:
            missing = [b for b in self._configured_bodies if b not in names]
            if missing:
                self.get_logger().warning(f"NatNet MODELDEF lacks configured bodies {missing} (has {names})")
            self._set_bodies(self._configured_bodies)
        else:
            self._set_bodies(names)
        self.get_logger().info(f"NatNet MODELDEF: rigid bodies {self.names_by_id}")

    def _on_natnet_frame(self, m) -> None:
        from euc_ros.core.io.natnet import latency_s

        if not self.names_by_id or not self.bodies:
            self.no_names_dropped += 1      # no MODELDEF yet: names unknown, do not guess
            return
        receive = m.receive_time_ns if m.receive_time_ns is not None else self.get_clock().now().nanoseconds
        latency = latency_s(m, self.client.server_info) if self.client.server_info is not None else float("nan")
        stamp, corrected = natnet_capture_stamp(receive, latency, self.config["max_latency"])
        frame = frame_from_natnet(m, self.names_by_id, self.bodies, stamp, self.config["world_up"])
        self._publish(frame, MocapFrame.STAMP_CAPTURE_TIME if corrected else MocapFrame.STAMP_RECEIVE_TIME)

    # -- output ----------------------------------------------------------------------------------
    def _set_bodies(self, bodies: list[str]) -> None:
        """Use ``bodies`` from now on; create their pose publishers up front (subscribers match early)."""
        self.bodies = list(bodies)
        self.stats.set_bodies(self.bodies)
        if self.config["publish_poses"]:
            for body in self.bodies:
                if body not in self.pose_pubs:
                    self.pose_pubs[body] = self.create_publisher(PoseStamped, itf.body_pose_topic(body),
                                                                 itf.RELIABLE_QOS, event_callbacks=itf.pub_events())

    def _input_error(self, exc: Exception) -> None:
        self.errors += 1
        self.get_logger().warning(f"input dropped: {type(exc).__name__}: {exc}", throttle_duration_sec=5.0)

    def _publish(self, frame: Frame, stamp_source: int | None = None) -> None:
        stats = self.stats
        if not stats.accept(frame.frame_number, frame.stamp_ns):
            return
        stats.update(frame.tracked, frame.stamp_ns)
        self._last_frame_wall = time.monotonic()
        fid = self.config["frame_id"]
        source = self.stamp_source if stamp_source is None else stamp_source
        # serialized with numpy (convert.frame_to_raw): the message classes cost ~0.3 ms per 14-body frame
        raw = convert.frame_to_raw(frame, fid, source)
        if isinstance(self.frame_pub, LocalFanout):
            self.frame_pub.publish(raw, local=(frame, fid))    # composed: the Frame itself to rider_state
        else:
            self.frame_pub.publish(raw)
        self.published += 1
        if not self._view_due(frame.stamp_ns):
            return
        self.view_published += 1
        # serialized with numpy too (cdr_frame): PoseStamped/TransformStamped objects cost ~35 us each
        shown = [i for i, ok in enumerate(frame.tracked) if ok]  # untracked: absent here, never a zero pose
        for i in shown:
            pub = self.pose_pubs.get(frame.bodies[i])
            if pub is not None:
                pub.publish(cdr_frame.pose_stamped(frame.stamp_ns, fid, frame.position[i], frame.quat[i]))
        if self.tf_pub is not None and shown:
            children = [itf.sanitize(frame.bodies[i]) for i in shown]
            self.tf_pub.publish(cdr_frame.tf_message(frame.stamp_ns, fid, children, frame.position[shown],
                                                     frame.quat[shown]))

    def _view_due(self, stamp_ns: int) -> bool:
        """Whether this frame's poses and TF are published (``view_rate``): a frame is due when at least
        3/4 of the view period has passed since the last one shown, so a source at a multiple of the
        view rate is decimated by a whole factor (360 Hz -> every 3rd frame at 120 Hz)."""
        rate = self.config["view_rate"]
        last = self._last_view_ns
        if rate <= 0 or last is None or stamp_ns < last or stamp_ns - last >= 0.75e9 / rate:
            self._last_view_ns = stamp_ns
            return True
        return False

    def counters(self) -> dict:
        """Every counter of the stream, as published in the diagnostics."""
        st = self.stats
        out = {"source": self.config["source"], "frames": st.frames, "rate_hz": st.frame_rate_hz(),
               "dropped_frames": st.dropped, "duplicates_dropped": st.duplicates,
               "out_of_order_dropped": st.out_of_order, "restarts": st.restarts, "malformed_dropped": st.malformed,
               "input_errors": self.errors, "inputs": self.received, "view_frames": self.view_published}
        if self.sync is not None:
            out["duplicates_dropped"] += self.sync.duplicates
            out["out_of_order_dropped"] += self.sync.out_of_order
            out["restarts"] += self.sync.restarts
            out["invalid_poses"] = self.sync.invalid
        if self.client is not None:
            cs = self.client.stats
            out["malformed_dropped"] += cs["malformed"]
            out["dropped_before_serverinfo"] = cs["dropped_no_version"]
            out["dropped_before_modeldef"] = self.no_names_dropped
            out["natnet_version"] = ("?" if self.client.version is None
                                     else f"{self.client.version[0]}.{self.client.version[1]}")
            out["send_errors"] = cs["send_errors"]
        return out

    def _publish_diagnostics(self) -> None:
        stats = self.stats
        values = self.counters()
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        stale = self._last_frame_wall is None or time.monotonic() - self._last_frame_wall > 1.0
        if stale:
            level, message = convert.STALE, "no frames yet" if stats.frames == 0 else "no frames for > 1 s"
        else:
            level, message = convert.OK, "receiving"
        arr.status.append(convert.status("mocap_ingest: stream", level, message, values,
                                         self.hardware_id))
        rates, lost = stats.tracking_rate(), stats.lost()
        for i, body in enumerate(stats.bodies):
            arr.status.append(convert.status(
                f"mocap_ingest: {body}", convert.WARN if lost[i] else convert.OK,
                "lost tracking" if lost[i] else "tracked", {"tracking_rate": float(rates[i]), "lost": bool(lost[i])},
                hardware_id=body))
        self.diag_pub.publish(arr)

    def close(self) -> None:
        """Release the NatNet sockets, if any."""
        if self.client is not None:
            self.client.close()


main = main_for(MocapIngest)
