"""Message <-> core conversions: the only module that knows both ROS messages and core types."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from euc_msgs.msg import MocapFrame
from geometry_msgs.msg import Pose, PoseStamped, TransformStamped

from euc_ros.core.errors import InputError
from euc_ros.core.io import cdr_frame
from euc_ros.core.mocap.frame import Frame

if TYPE_CHECKING:
    from rosbags.interfaces import Qos

NAN = float("nan")


def stamp_to_ns(stamp: Time) -> int:
    """builtin_interfaces/Time -> integer nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def ns_to_stamp(ns: int) -> Time:
    """Integer nanoseconds -> builtin_interfaces/Time (negative times clamp to 0)."""
    ns = max(int(ns), 0)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _pose(position, quat) -> Pose:
    p = Pose()
    p.position.x, p.position.y, p.position.z = (float(v) for v in position)
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = (float(v) for v in quat)
    return p


def frame_to_msg(frame: Frame, frame_id: str, stamp_source: int) -> MocapFrame:
    """Core :class:`Frame` -> ``euc_msgs/MocapFrame`` (untracked bodies keep NaN poses)."""
    msg = MocapFrame()
    msg.header.stamp = ns_to_stamp(frame.stamp_ns)
    msg.header.frame_id = frame_id
    msg.stamp_source = stamp_source
    msg.frame_number = int(frame.frame_number)
    msg.body_names = list(frame.bodies)
    msg.poses = [_pose(frame.position[i], frame.quat[i]) for i in range(len(frame.bodies))]
    msg.tracked = [bool(v) for v in frame.tracked]
    msg.mean_marker_error = [float(v) for v in frame.mean_marker_error]
    return msg


def _frame(stamp_ns: int, number: int, names: list, pos: np.ndarray, quat: np.ndarray, tracked: np.ndarray,
           err: np.ndarray) -> Frame:
    """A core Frame from a message's arrays: missing flags from finiteness, NaN poses where untracked."""
    if tracked.shape[0] != pos.shape[0]:
        tracked = np.all(np.isfinite(pos), axis=1)
    if err.shape[0] != pos.shape[0]:
        err = np.full(pos.shape[0], np.nan)
    pos[~tracked] = np.nan
    quat[~tracked] = np.nan
    return Frame(int(stamp_ns), int(number), list(names), pos, quat, tracked, err)


def msg_to_frame(msg: MocapFrame) -> Frame:
    """``euc_msgs/MocapFrame`` -> core :class:`Frame`."""
    pos = np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses], float).reshape(-1, 3)
    quat = np.array([[p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w] for p in msg.poses],
                    float).reshape(-1, 4)
    return _frame(stamp_to_ns(msg.header.stamp), msg.frame_number, msg.body_names, pos, quat,
                  np.array(msg.tracked, bool), np.array(msg.mean_marker_error, float))


def deserialize(raw: bytes, msg_class):
    """A raw subscription's bytes -> a message of ``msg_class`` (rclpy's deserializer).

    Raises
    ------
    InputError
        Bytes that are not a ``msg_class`` message (rclpy raises its RMWError, a RuntimeError, for them).
    """
    from rclpy.serialization import deserialize_message

    try:
        return deserialize_message(raw, msg_class)
    except RuntimeError as exc:
        raise InputError(f"{len(raw)} bytes that are not a {msg_class.__name__}: {exc}") from None


def raw_to_frame(raw: bytes) -> tuple[Frame, str]:
    """Serialized ``euc_msgs/MocapFrame`` (a raw subscription's bytes) -> (core :class:`Frame`, frame_id).

    Little-endian CDR is read with numpy (:mod:`euc_ros.core.io.cdr_frame`); anything else goes through
    rclpy's deserializer, so every valid message is read; bytes that neither reads are an InputError
    (:func:`deserialize`).
    """
    try:
        d = cdr_frame.decode(raw)
    except cdr_frame.CdrError:
        msg = deserialize(raw, MocapFrame)
        return msg_to_frame(msg), msg.header.frame_id
    return _frame(d.stamp_ns, d.frame_number, d.bodies, d.position, d.quat, d.tracked, d.mean_marker_error), d.frame_id


_ENCODER = cdr_frame.FrameEncoder()


def frame_to_raw(frame: Frame, frame_id: str, stamp_source: int) -> bytes:
    """Core :class:`Frame` -> serialized ``euc_msgs/MocapFrame`` (what :func:`frame_to_msg` serializes to)."""
    return _ENCODER.encode(frame.stamp_ns, frame_id, stamp_source, frame.frame_number, frame.bodies,
                           frame.position, frame.quat, frame.tracked, frame.mean_marker_error)


def pose_stamped(stamp_ns: int, frame_id: str, position, quat) -> PoseStamped:
    """A PoseStamped at ``stamp_ns`` in ``frame_id``."""
    msg = PoseStamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    msg.pose = _pose(position, quat)
    return msg


def transform_stamped(stamp_ns: int, parent: str, child: str, position, quat) -> TransformStamped:
    """A TransformStamped parent -> child."""
    msg = TransformStamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = parent
    msg.child_frame_id = child
    t = msg.transform.translation
    t.x, t.y, t.z = (float(v) for v in position)
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = (float(v) for v in quat)
    return msg


def pose_from_msg(msg: PoseStamped) -> tuple[int, np.ndarray, np.ndarray]:
    """PoseStamped -> (stamp_ns, position (3,), quat (4,))."""
    p, q = msg.pose.position, msg.pose.orientation
    return stamp_to_ns(msg.header.stamp), np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w])


def rigid_bodies_arrays(msg) -> tuple[list[str], np.ndarray, np.ndarray]:
    """mocap4r2_msgs/RigidBodies -> (names, positions (n, 3), quaternions (n, 4) x, y, z, w); markers ignored."""
    bodies = msg.rigidbodies
    names = [b.rigid_body_name for b in bodies]
    pos = np.array([(b.pose.position.x, b.pose.position.y, b.pose.position.z) for b in bodies], float).reshape(-1, 3)
    quat = np.array([(b.pose.orientation.x, b.pose.orientation.y, b.pose.orientation.z, b.pose.orientation.w)
                     for b in bodies], float).reshape(-1, 4)
    return names, pos, quat


def status(name: str, level: int, message: str, values: dict, hardware_id: str) -> DiagnosticStatus:
    """A DiagnosticStatus as diagnostic_updater makes them.

    ``name`` = ``"<node>: <check>"``, the ``hardware_id`` it concerns, key/value pairs (floats printed with 4
    significant digits).
    """
    st = DiagnosticStatus(level=bytes([level]) if isinstance(level, int) else level, name=name,
                          message=message, hardware_id=hardware_id)
    st.values = [KeyValue(key=k, value=(f"{v:.4g}" if isinstance(v, float) and not math.isnan(v) else str(v)))
                 for k, v in values.items()]
    return st


def publish_status(node, publisher, name: str, level: int, message: str, values: dict, hardware_id: str) -> None:
    """Publish one DiagnosticStatus in a DiagnosticArray stamped with the node's clock."""
    from diagnostic_msgs.msg import DiagnosticArray

    arr = DiagnosticArray()
    arr.header.stamp = node.get_clock().now().to_msg()
    arr.status.append(status(name, level, message, values, hardware_id))
    publisher.publish(arr)


OK, WARN, ERROR, STALE = (DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR, DiagnosticStatus.STALE)


class LocalState:
    """A rider state handed over in-process (:mod:`euc_ros.nodes.container`) instead of a RiderState message.

    Its header stamp [ns], frame id and the core sample (same field names as the message).
    """

    __slots__ = ("stamp_ns", "frame_id", "sample")

    def __init__(self, stamp_ns: int, frame_id: str, sample) -> None:
        self.stamp_ns, self.frame_id, self.sample = stamp_ns, frame_id, sample


_FLAT_KINDS = {"boolean": "bool", "double": "float64", "string": "string"}


def flat_fields(msg_class) -> list[tuple[str, str]]:
    """The fields after ``header`` of a flat message class as :class:`~euc_ros.core.io.cdr_flat.FlatEncoder` wants them.

    ``(dotted name, kind)``, nested float64 structs (``geometry_msgs/Point``) expanded.

    Raises ValueError for a field type the flat encoder cannot write (then publish the message object).
    """
    import importlib

    def walk(cls, prefix: str, out: list) -> None:
        for name, typ in cls.get_fields_and_field_types().items():
            if prefix == "" and name == "header" and typ == "std_msgs/Header":
                continue
            if typ in _FLAT_KINDS:
                out.append((prefix + name, _FLAT_KINDS[typ]))
            elif "/" in typ and "<" not in typ and "[" not in typ:
                pkg, sub = typ.split("/")
                walk(getattr(importlib.import_module(f"{pkg}.msg"), sub), f"{prefix}{name}.", out)
            else:
                raise ValueError(f"{cls.__name__}.{prefix}{name}: type {typ} is not flat")

    fields: list[tuple[str, str]] = []
    if "header" not in msg_class.get_fields_and_field_types():
        raise ValueError(f"{msg_class.__name__} has no header")
    walk(msg_class, "", fields)
    return fields


# -- the autonomous unicycle ------------------------------------------------------------------------------------------
#: UnicycleState's state fields, in the order of the state of eq (37)
#: (:data:`~euc_ros.core.unicycle.dynamics.STATE_NAMES`).
UNICYCLE_STATE_FIELDS = ("omega1", "omega2", "omega3", "theta", "sigma", "r", "psi", "phi", "x_g", "y_g")


def unicycle_state_to_msg(x, u: float, step: int, stamp_ns: int, status: str, frame_id: str = "world"):
    """State ``x`` (10,) of eq (37) -> ``euc_msgs/UnicycleState`` (fields in :data:`UNICYCLE_STATE_FIELDS` order)."""
    from euc_msgs.msg import UnicycleState

    msg = UnicycleState()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = frame_id
    (msg.omega1, msg.omega2, msg.omega3, msg.theta, msg.sigma, msg.r, msg.psi, msg.phi, msg.x_g,
     msg.y_g) = (float(v) for v in x)
    msg.u = float(u)
    msg.step = int(step)
    msg.status = status
    return msg


def msg_to_unicycle_state(msg) -> np.ndarray:
    """``UnicycleState`` (rclpy or rosbags message) -> state (10,) of eq (37)."""
    return np.array([getattr(msg, f) for f in UNICYCLE_STATE_FIELDS], dtype=float)


# -- flat estimates, serialized without message objects (core/io/cdr_flat) ------------------------------------------
#: RiderState's fields after the header, in the message's order (what :func:`rider_state_values` gives).
RIDER_STATE_FIELDS = ("has_rider", "x", "x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot",
                      "phi_ddot", "phi_eq3", "phi_hinge", "phi_definition", "psi", "theta", "c.x", "c.y", "c.z",
                      "g.x", "g.y", "g.z", "filter_lag")
#: TorqueEstimate's fields after the header, in the message's order (what :func:`torque_values` gives).
TORQUE_FIELDS = ("valid", "m_d1", "m_d2", "m_d1_2dof", "m_d2_2dof", "h", "residual", "rmse_window", "window",
                 "h_online", "h_online_std", "model", "h_online_status")


def checked_flat_fields(msg_class, expected: tuple) -> list[tuple[str, str]]:
    """:func:`flat_fields` of ``msg_class``, which must be ``expected`` (the values functions write that order)."""
    fields = flat_fields(msg_class)
    if tuple(n for n, _ in fields) != expected:      # the interface changed: update the values function
        raise RuntimeError(f"{msg_class.__name__} fields {[n for n, _ in fields]} differ from {expected}")
    return fields


def rider_state_values(s) -> tuple:
    """A rider-state sample's field values in the order of :data:`RIDER_STATE_FIELDS` (RiderState after its header)."""
    C, G = s.C, s.G
    return (bool(s.has_rider), float(s.x), float(s.x_dot), float(s.x_ddot), float(s.gamma), float(s.gamma_dot),
            float(s.gamma_ddot), float(s.phi), float(s.phi_dot), float(s.phi_ddot), float(s.phi_eq3),
            float(s.phi_hinge), s.phi_definition, float(s.psi), float(s.theta), float(C[0]), float(C[1]),
            float(C[2]), float(G[0]), float(G[1]), float(G[2]), float(s.filter_lag_s))


def torque_values(out) -> tuple:
    """A torque sample's field values in the order of :data:`TORQUE_FIELDS` (TorqueEstimate after its header)."""
    return (True, float(out.M_d1), float(out.M_d2), float(out.M_d1_2dof), float(out.M_d2_2dof), float(out.h_m),
            float(out.residual_nm), float(out.rmse_window_nm), float(out.window_s), float(out.h_online_m),
            float(out.h_online_std_m), out.model, out.h_online_status)


def bag_qos(profile) -> "Qos":
    """A publisher's offered QoS (rclpy) as rosbag2 stores it in ``offered_qos_profiles``.

    As rosbags' Qos: the same policy numbers as rmw; durations as sec/nsec, infinite = rmw's 9223372036 s
    854775807 ns.
    """
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    def duration(d) -> QosTime:
        ns = int(d.nanoseconds)
        return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)

    return Qos(QosHistory(int(profile.history)), int(profile.depth), QosReliability(int(profile.reliability)),
               QosDurability(int(profile.durability)), duration(profile.deadline), duration(profile.lifespan),
               QosLiveliness(int(profile.liveliness)), duration(profile.liveliness_lease_duration),
               bool(profile.avoid_ros_namespace_conventions))
