"""Node ``mocap_ingest``: OptiTrack rigid bodies -> ``MocapFrame`` + per-body poses + TF + diagnostics.

Sources (parameter ``source``, one class each in :mod:`euc_ros.ros.mocap_sources`): ``csv`` (a Motive
CSV export replayed, stamps from the replay start or the file's capture start), ``topics`` (per-body
PoseStamped by header stamp, or mocap4r2_msgs/RigidBodies) and ``natnet`` (live Motive, stamped with
the capture time; a server that sends nothing is said on the console after 3 s).

Bad input never stops the node: duplicate and out-of-order stamps or frame numbers, malformed
NatNet packets and invalid poses are dropped (or published untracked) and counted in the
diagnostics; an input a source cannot use (an :class:`~euc_ros.core.errors.EucError`) is dropped with a
warning (``input_errors``), and any other exception, a bug, is logged with its traceback and counted apart
(``unexpected_errors``, :class:`~euc_ros.ros.runtime.CallbackErrors`). The logic lives in
:mod:`euc_ros.core.mocap` (:mod:`~euc_ros.core.mocap.frame`, :mod:`~euc_ros.core.mocap.tracking`,
:mod:`~euc_ros.core.mocap.decimation` and the modules the sources use); this module only wires ROS. The
up axis is checked against the first seconds of data (``check_up_axis``): a contradiction ends the node
with exit code 2.
"""
from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray
from euc_msgs.msg import MocapFrame
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from tf2_msgs.msg import TFMessage

from euc_ros.core.errors import EucError
from euc_ros.core.io import cdr_frame
from euc_ros.core.mocap.decimation import ViewDecimator
from euc_ros.core.mocap.frame import Frame
from euc_ros.core.mocap.tracking import TrackingStats
from euc_ros.core.mocap.up_axis_watch import UpAxisWatch
from euc_ros.ros import convert
from euc_ros.ros import interfaces as itf
from euc_ros.ros.intra import LocalFanout
from euc_ros.ros.mocap_sources import make_source, up_axis_config
from euc_ros.ros.params import ParamSpec, declare_params
from euc_ros.ros.runtime import CallbackErrors, main_for

SPECS = (
    ParamSpec("source", "csv", "where poses come from", choices=("csv", "topics", "natnet")),
    ParamSpec("csv_path", "", "Motive CSV export to replay (source csv)"),
    ParamSpec("session_file", "", "session file: its world_up is the up axis of the Motive world (CSV, NatNet and "
              "rigid_bodies topics), and its EUC geometry lets the node check that axis against the data"),
    ParamSpec("world_up", "", "up axis of the Motive world when no session_file gives it (empty: the session's, "
              "else y, Motive's default); a value that contradicts the session is refused",
              choices=("", "y", "z")),
    ParamSpec("check_up_axis", True, "check the up axis against the first seconds of data (as every offline "
              "analysis does) and stop with an error when the data contradict it"),
    ParamSpec("bodies", [""], "rigid bodies to publish, in order (empty: all in the source; required for topics)"),
    ParamSpec("rate_factor", 1.0, "replay speed relative to real time (source csv)", "", 0.01, 1000.0),
    ParamSpec("loop", False, "restart the CSV replay at the end (replay stamps keep increasing)"),
    ParamSpec("stamp_mode", "replay", "csv stamps: replay start + frame/rate, or the file's capture start time",
              choices=("replay", "file")),
    ParamSpec("start_delay", 1.0, "wait before the first CSV frame so subscribers can match", "s", 0.0, 60.0),
    ParamSpec("wait_subscribers", 0, "also wait until mocap/frame has this many subscriptions, then 0.3 s "
              "(source csv)", "", 0, 1000),
    ParamSpec("wait_topics", [""], "also wait until each listed topic has N subscriptions: 'topic=N' entries, "
              "e.g. rider/state=3 (the stages downstream; source csv)"),
    ParamSpec("exit_when_done", False, "exit (code 0) after the CSV replay ends and linger has passed"),
    ParamSpec("linger", 1.0, "time to keep running once every subscriber has acknowledged the last CSV frame",
              "s", 0.0, 3600.0),
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


class MocapIngest(Node):
    """Publish OptiTrack rigid bodies as MocapFrame, poses, TF and diagnostics.

    ===========  ===============================  ======================================  ============================
    direction    topic                            type                                    when / QoS
    ===========  ===============================  ======================================  ============================
    Subscribes   ``<topic_prefix>/<Body>/pose``   geometry_msgs/PoseStamped               topics; input_reliability
    Subscribes   ``rigid_bodies_topic``           mocap4r2_msgs/RigidBodies               topics, rigid_bodies
    Publishes    ``mocap/frame``                  euc_msgs/MocapFrame                     every frame; reliable
    Publishes    ``mocap/<body>/pose``            geometry_msgs/PoseStamped               tracked; about view_rate
    Publishes    ``/tf``                          tf2_msgs/TFMessage (world -> body)      as the poses
    Publishes    ``/diagnostics``                 diagnostic_msgs/DiagnosticArray         diagnostics_period
    ===========  ===============================  ======================================  ============================

    Parameters: :data:`SPECS`. ``view_rate`` (120 Hz) shows every frame up to 120 Hz and every 3rd at
    360 Hz, by frame number when the frames have one (:class:`~euc_ros.core.mocap.decimation.ViewDecimator`).

    Parameters
    ----------
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``parameter_overrides``, ``namespace``...).

    Attributes
    ----------
    source : MocapSource
        Where the frames come from (:mod:`euc_ros.ros.mocap_sources`).
    stats : TrackingStats
        Frame and tracking counters (``frames``, ``dropped``, ``duplicates``, ``out_of_order``...).
    published, received : int
        MocapFrames published; inputs handled (poses, NatNet messages, CSV frames).
    drops : CallbackErrors
        Inputs dropped on bad input (:meth:`input_error`) or on an unexpected error (:meth:`unexpected_error`).
    """

    NAME = "mocap_ingest"
    SPECS = SPECS

    def __init__(self, **kwargs):
        super().__init__(self.NAME, **kwargs)
        self.config = cfg = declare_params(self, SPECS)
        self.bodies = [b for b in cfg["bodies"] if b]
        self.session, self.world_up = up_axis_config(cfg["session_file"], cfg["world_up"])
        self.frame_pub = self.create_publisher(MocapFrame, itf.MOCAP_FRAME, itf.RELIABLE_QOS,
                                               event_callbacks=itf.pub_events())
        self.tf_pub = self.create_publisher(TFMessage, itf.TF, itf.RELIABLE_QOS,
                                            event_callbacks=itf.pub_events()) if cfg["publish_tf"] else None
        self.diag_pub = itf.diagnostics_publisher(self)
        self.pose_pubs: dict[str, object] = {}
        self.stats = TrackingStats(self.bodies, restart_frames=cfg["restart_frames"])
        self.published = self.received = self.view_published = 0
        self.drops = CallbackErrors(self, "input dropped")
        self._last_frame_wall: float | None = None
        self.up_watch: UpAxisWatch | None = None
        self.source = make_source(self, cfg)
        self.source.setup()
        self.hardware_id = self.source.hardware_id
        self.view = ViewDecimator(cfg["view_rate"], self.source.rate_hz)
        self.create_timer(cfg["diagnostics_period"], self._publish_diagnostics)
        if cfg["check_up_axis"]:
            self.up_watch = UpAxisWatch(self.bodies, self.source.up_axis, self.session, label=self.hardware_id)
            self.create_timer(0.5, self._check_up_axis)

    # -- what the sources call ---------------------------------------------------------------------
    def set_bodies(self, bodies: list[str]) -> None:
        """Use ``bodies`` from now on; create their pose publishers up front (subscribers match early)."""
        self.bodies = list(bodies)
        self.stats.set_bodies(self.bodies)
        if self.up_watch is not None:
            self.up_watch.reset(self.bodies)
        if self.config["publish_poses"]:
            for body in self.bodies:
                if body not in self.pose_pubs:
                    self.pose_pubs[body] = self.create_publisher(PoseStamped, itf.body_pose_topic(body),
                                                                 itf.RELIABLE_QOS, event_callbacks=itf.pub_events())

    @property
    def errors(self) -> int:
        """Inputs dropped on bad input (:meth:`input_error`)."""
        return self.drops.errors

    def input_error(self, exc: EucError) -> None:
        """Count and log (throttled) an input that could not be used (a source's ``except EucError``)."""
        self.drops.input_error(exc)

    def unexpected_error(self) -> None:
        """Count and log (throttled, with its traceback) the exception being handled: a bug in a source's callback."""
        self.drops.unexpected_error()

    def publish_frame(self, frame: Frame, stamp_source: int | None = None) -> None:
        """Publish one frame (dropped and counted when repeated or out of order), its poses and TF."""
        stats = self.stats
        if not stats.accept(frame.frame_number, frame.stamp_ns):
            return
        stats.update(frame.tracked, frame.stamp_ns)
        if self.up_watch is not None and not self.up_watch.done:
            self.up_watch.push(frame.stamp_ns, frame.position, frame.quat, frame.tracked)
        self._last_frame_wall = time.monotonic()
        fid = self.config["frame_id"]
        source = self.source.stamp_source if stamp_source is None else stamp_source
        # serialized with numpy (convert.frame_to_raw): the message classes cost ~0.3 ms per 14-body frame
        raw = convert.frame_to_raw(frame, fid, source)
        if isinstance(self.frame_pub, LocalFanout):
            self.frame_pub.publish(raw, local=(frame, fid))    # composed: the Frame itself to rider_state
        else:
            self.frame_pub.publish(raw)
        self.published += 1
        if not self.view.due(frame.frame_number, frame.stamp_ns):
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

    # -- checks and diagnostics ---------------------------------------------------------------------
    def _check_up_axis(self) -> None:
        """Run the up-axis check once enough frames are in; a contradiction ends the node (exit 2)."""
        watch = self.up_watch
        if watch is None or not watch.due():
            return
        try:
            warnings = watch.check()
        except EucError as exc:
            self.get_logger().error(f"wrong up axis, stopping: {exc}")
            raise
        for w in warnings:
            self.get_logger().warning(w)
        if watch.done and not warnings:
            self.get_logger().info(f"up axis checked: {self.world_up}-up ({watch.result['reason']})")

    def counters(self) -> dict:
        """Every counter of the stream, as published in the diagnostics (the source's added)."""
        st = self.stats
        out = {"source": self.config["source"], "frames": st.frames, "rate_hz": st.frame_rate_hz(),
               "dropped_frames": st.dropped, "duplicates_dropped": st.duplicates,
               "out_of_order_dropped": st.out_of_order, "restarts": st.restarts, "malformed_dropped": st.malformed,
               "input_errors": self.drops.errors,
               "unexpected_errors": self.drops.unexpected, "inputs": self.received, "view_frames": self.view_published}
        for key, value in self.source.counters().items():
            out[key] = out[key] + value if key in out else value
        return out

    def _publish_diagnostics(self) -> None:
        stats = self.stats
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        stale = self._last_frame_wall is None or time.monotonic() - self._last_frame_wall > 1.0
        if stale:
            level, message = convert.STALE, "no frames yet" if stats.frames == 0 else "no frames for > 1 s"
        else:
            level, message = convert.OK, "receiving"
        arr.status.append(convert.status("mocap_ingest: stream", level, message, self.counters(), self.hardware_id))
        rates, lost = stats.tracking_rate(), stats.lost()
        for i, body in enumerate(stats.bodies):
            arr.status.append(convert.status(
                f"mocap_ingest: {body}", convert.WARN if lost[i] else convert.OK,
                "lost tracking" if lost[i] else "tracked", {"tracking_rate": float(rates[i]), "lost": bool(lost[i])},
                hardware_id=body))
        self.diag_pub.publish(arr)

    def close(self) -> None:
        """Release the source's sockets, if any."""
        self.source.close()


main = main_for(MocapIngest)
