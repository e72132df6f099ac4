"""Source ``topics``: poses from ROS topics, of either of the two drivers' conventions.

* ``topic_type: pose_stamped``: one ``geometry_msgs/PoseStamped`` per body on
  ``<topic_prefix>/<Body>/pose`` (vrpn_mocap convention, Z-up), assembled into frames by header
  stamp (:class:`~euc_ros.core.mocap.synchronizer.PoseSynchronizer`); frame number -1 (unknown).
* ``topic_type: rigid_bodies``: one ``mocap4r2_msgs/RigidBodies`` per frame (the MOCAP4ROS2 OptiTrack
  driver), converted from the session's up axis, with the driver's frame numbers.

Either way the frame stamp is the header stamp (``stamp_source`` SOURCE_HEADER).
"""
from __future__ import annotations

import time

from euc_msgs.msg import MocapFrame
from geometry_msgs.msg import PoseStamped

from euc_ros.core.errors import ConfigError, EucError
from euc_ros.core.mocap.message_frames import frame_from_named_poses
from euc_ros.core.mocap.synchronizer import PoseSynchronizer
from euc_ros.ros import convert
from euc_ros.ros import interfaces as itf
from euc_ros.ros.mocap_sources.base import MocapSource


class PoseTopics(MocapSource):
    """Frames assembled from one PoseStamped stream per body.

    Configured by the parameters ``bodies``, ``topic_prefix``, ``sync_tolerance``, ``sync_timeout``,
    ``restart_jump``, ``input_reliability``.

    Attributes
    ----------
    sync : PoseSynchronizer
    """

    stamp_source = MocapFrame.STAMP_SOURCE_HEADER

    @property
    def hardware_id(self) -> str:
        """The capture system: ``topics:<topic_prefix>``."""
        return f"topics:{self.config['topic_prefix']}"

    @property
    def up_axis(self) -> str | None:
        """None: PoseStamped topics are Z-up by contract."""
        return None                    # PoseStamped topics are Z-up by contract

    def setup(self) -> None:
        """Subscribe to one PoseStamped topic per body and synchronize them into frames.

        Raises
        ------
        ConfigError
            Without ``bodies``.
        """
        node, cfg = self.node, self.config
        if not node.bodies:
            raise ConfigError("parameter 'bodies' must list the rigid bodies with source 'topics'", key="bodies")
        self.sync = PoseSynchronizer(node.bodies, cfg["sync_tolerance"], cfg["sync_timeout"], cfg["restart_jump"])
        node.set_bodies(node.bodies)
        prefix = cfg["topic_prefix"].rstrip("/")
        for body in node.bodies:
            node.create_subscription(PoseStamped, f"{prefix}/{body}/pose", lambda msg, b=body: self._on_pose(b, msg),
                                     itf.mocap_input_qos(cfg["input_reliability"]))
        node.create_timer(min(cfg["sync_timeout"] / 2, 0.01), self._flush)
        node.get_logger().info(f"assembling frames of {', '.join(node.bodies)} from {prefix}/<Body>/pose")

    def _on_pose(self, body: str, msg: PoseStamped) -> None:
        node = self.node
        node.received += 1
        try:
            stamp, pos, quat = convert.pose_from_msg(msg)
            for frame in self.sync.push(body, stamp, pos, quat, arrival_ns=time.monotonic_ns()):
                node.publish_frame(frame)
        except EucError as exc:    # bad input: dropped, counted, warned
            node.input_error(exc)
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            node.unexpected_error()

    def _flush(self) -> None:
        try:
            for frame in self.sync.flush(time.monotonic_ns()):
                self.node.publish_frame(frame)
        except EucError as exc:
            self.node.input_error(exc)
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            self.node.unexpected_error()

    def counters(self) -> dict:
        """The synchronizer's counters for the stream diagnostics.

        Returns
        -------
        dict
            ``duplicates_dropped``, ``out_of_order_dropped``, ``restarts`` and ``invalid_poses``.
        """
        s = self.sync
        return {"duplicates_dropped": s.duplicates, "out_of_order_dropped": s.out_of_order, "restarts": s.restarts,
                "invalid_poses": s.invalid}


class RigidBodiesTopic(MocapSource):
    """Frames from ``mocap4r2_msgs/RigidBodies`` messages; bodies not in ``bodies`` are ignored.

    Configured by the parameters ``rigid_bodies_topic``, ``bodies``, ``input_reliability``; an ignored body is
    warned about once per new name.

    Attributes
    ----------
    unknown_bodies : set of str
        Names seen that are not in ``bodies``.
    """

    stamp_source = MocapFrame.STAMP_SOURCE_HEADER

    @property
    def hardware_id(self) -> str:
        """The capture system: ``topics:<topic_prefix>``."""
        return f"topics:{self.config['topic_prefix']}"

    def setup(self) -> None:
        """Subscribe to the RigidBodies topic.

        Raises
        ------
        ConfigError
            Without the mocap4r2_msgs interfaces.
        """
        node, cfg = self.node, self.config
        try:
            from mocap4r2_msgs.msg import RigidBodies
        except ImportError:
            raise ConfigError("topic_type 'rigid_bodies' needs the mocap4r2_msgs interfaces: install them "
                              "(ros-jazzy-mocap4r2-msgs, or ./run setup builds extra_interfaces/mocap4r2_msgs)",
                              key="topic_type") from None
        self.unknown_bodies: set[str] = set()
        if node.bodies:
            node.set_bodies(node.bodies)
        node.create_subscription(RigidBodies, cfg["rigid_bodies_topic"], self._on_message,
                                 itf.mocap_input_qos(cfg["input_reliability"]))
        which = ", ".join(node.bodies) if node.bodies else "the bodies of the first message"
        node.get_logger().info(f"frames of {which} from {cfg['rigid_bodies_topic']} (mocap4r2_msgs/RigidBodies, "
                               f"world {node.world_up}-up)")

    def _on_message(self, msg) -> None:
        node = self.node
        node.received += 1
        try:
            names, pos, quat = convert.rigid_bodies_arrays(msg)
            if not node.bodies:               # the first message names the bodies (their order kept)
                node.set_bodies(list(dict.fromkeys(names)))
            frame, unknown = frame_from_named_poses(convert.stamp_to_ns(msg.header.stamp), int(msg.frame_number),
                                                    names, pos, quat, node.bodies, node.world_up)
            if unknown and not set(unknown) <= self.unknown_bodies:
                self.unknown_bodies.update(unknown)
                node.get_logger().warning(f"ignoring bodies not in 'bodies': {', '.join(sorted(self.unknown_bodies))}")
            node.publish_frame(frame)
        except EucError as exc:    # bad input: dropped, counted, warned
            node.input_error(exc)
        except Exception:          # a bug: logged with its traceback; the node never dies on input
            node.unexpected_error()
