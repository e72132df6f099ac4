"""The hand-written CDR codecs against rosbags' serializer, byte for byte, without ROS.

Every message the project writes or reads as raw CDR (:mod:`euc_ros.core.io.cdr_flat`,
:mod:`euc_ros.core.io.cdr_frame`, the vectorized PoseStamped codec of :mod:`euc_ros.core.io.bags`) is
built once by the codec and once as a rosbags message object serialized by the typestore of the
project's interfaces (:func:`euc_ros.core.io.msgdefs.make_typestore`); the bytes must be equal, and the
decoders must read rosbags' bytes back. Field values include NaN, negative stamps' clamping is the
codecs' own rule (rosbags is given the clamped stamp), and strings of every length modulo 4 and 8
exercise the padding.
"""
# covers: euc_ros/core/io/cdr.py
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.io import cdr_frame
from euc_ros.core.io.bags import posestamped_arrays, posestamped_cdr
from euc_ros.core.io.cdr import ENCAPSULATION_LE, HEAD, header_bytes, pad, split_stamp, write_string
from euc_ros.core.io.cdr_flat import FlatEncoder
from euc_ros.core.io.msgdefs import make_typestore

STAMP_NS = 1_700_000_123_456_789_012
FRAME_IDS = ("", "w", "map", "world", "world_frame_long")      # NUL-terminated lengths 1..17


@pytest.fixture(scope="module")
def store():
    return make_typestore()


def _time(store, stamp_ns: int):
    sec, nsec = divmod(max(int(stamp_ns), 0), 1_000_000_000)
    return store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)


def _header(store, stamp_ns: int, frame_id: str):
    return store.types["std_msgs/msg/Header"](stamp=_time(store, stamp_ns), frame_id=frame_id)


def _flat_fields(store, msgtype: str, prefix: str = "") -> list[tuple[str, str]]:
    """``(dotted name, kind)`` after the header, nested float64 structs expanded (as the nodes build them)."""
    out = []
    for name, (_node, desc) in store.fielddefs[msgtype][1]:
        if not prefix and name == "header":
            continue
        if isinstance(desc, tuple):
            out.append((prefix + name, desc[0]))
        else:
            out += _flat_fields(store, desc, f"{prefix}{name}.")
    return out


def _message(store, msgtype: str, values: dict, prefix: str = ""):
    """A rosbags message object of ``msgtype`` from dotted field values (the header from ``values['header']``)."""
    kwargs = {}
    for name, (_node, desc) in store.fielddefs[msgtype][1]:
        if not prefix and name == "header":
            kwargs[name] = values["header"]
        elif isinstance(desc, tuple):
            kwargs[name] = values[prefix + name]
        else:
            kwargs[name] = _message(store, desc, values, f"{prefix}{name}.")
    return store.types[msgtype](**kwargs)


def test_primitives():
    assert ENCAPSULATION_LE == b"\x00\x01\x00\x00" and HEAD == 4
    assert [pad(k, 8) for k in (0, 1, 7, 8, 9)] == [0, 8, 8, 8, 16]
    out = bytearray(b"x")
    write_string(out, "ab")
    assert bytes(out) == b"x\x00\x00\x00" + b"\x03\x00\x00\x00ab\x00"
    assert bytes(header_bytes(-5, "")) == b"\x00" * 8 + b"\x01\x00\x00\x00\x00"
    sec, nsec = split_stamp(np.array([-1, 10**9 + 2]))
    assert sec.tolist() == [-1, 1] and nsec.tolist() == [10**9 - 1, 2]


@pytest.mark.parametrize("msgtype", ["euc_msgs/msg/RiderState", "euc_msgs/msg/TorqueEstimate"])
@pytest.mark.parametrize("frame_id", FRAME_IDS)
def test_flat_encoder_equals_rosbags(store, msgtype, frame_id):
    fields = _flat_fields(store, msgtype)
    rng = np.random.default_rng(len(frame_id))
    values = []
    for i, (name, kind) in enumerate(fields):
        if kind == "bool":
            values.append(bool(i % 2))
        elif kind == "float64":
            values.append(float("nan") if i == 3 else float(rng.normal()))
        else:
            values.append("x" * (i % 6))
    raw = FlatEncoder(fields).encode(STAMP_NS, frame_id, values)
    msg = _message(store, msgtype, {"header": _header(store, STAMP_NS, frame_id), **dict(zip(
        [n for n, _ in fields], values))})
    assert raw == bytes(store.serialize_cdr(msg, msgtype))


def _mocap_frame(store, stamp_ns, frame_id, stamp_source, frame_number, bodies, position, quat, tracked, err):
    Pose = store.types["geometry_msgs/msg/Pose"]
    Point = store.types["geometry_msgs/msg/Point"]
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    poses = [Pose(position=Point(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                  orientation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])))
             for p, q in zip(position, quat)]
    return store.types["euc_msgs/msg/MocapFrame"](
        header=_header(store, stamp_ns, frame_id), stamp_source=stamp_source, frame_number=frame_number,
        body_names=list(bodies), poses=poses, tracked=np.asarray(tracked, dtype=np.bool_),
        mean_marker_error=np.asarray(err, dtype=np.float32))


@pytest.mark.parametrize("n_bodies", [0, 1, 3, 14])
@pytest.mark.parametrize("frame_id", FRAME_IDS[1:4])
def test_mocap_frame_both_ways_equals_rosbags(store, n_bodies, frame_id):
    rng = np.random.default_rng(n_bodies)
    bodies = [f"body{'_' * k}{k}" for k in range(n_bodies)]
    position = rng.normal(size=(n_bodies, 3))
    quat = rng.normal(size=(n_bodies, 4))
    if n_bodies:
        position[0, 1] = np.nan
    tracked = rng.random(n_bodies) > 0.3
    err = rng.random(n_bodies).astype(np.float32)
    raw = cdr_frame.FrameEncoder().encode(STAMP_NS, frame_id, 1, 123456789, bodies, position, quat, tracked, err)
    msg = _mocap_frame(store, STAMP_NS, frame_id, 1, 123456789, bodies, position, quat, tracked, err)
    ref = bytes(store.serialize_cdr(msg, "euc_msgs/msg/MocapFrame"))
    assert raw == ref
    frame = cdr_frame.decode(ref)
    assert frame.frame_number == 123456789 and list(frame.bodies) == bodies
    back = store.deserialize_cdr(raw, "euc_msgs/msg/MocapFrame")
    assert back.body_names == bodies and np.array_equal(back.tracked, tracked)


@pytest.mark.parametrize("frame_id", FRAME_IDS)
def test_pose_stamped_equals_rosbags(store, frame_id):
    position, quat = np.array([1.0, -2.0, np.nan]), np.array([0.1, 0.2, 0.3, 0.9])
    Point = store.types["geometry_msgs/msg/Point"]
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    msg = store.types["geometry_msgs/msg/PoseStamped"](
        header=_header(store, STAMP_NS, frame_id),
        pose=store.types["geometry_msgs/msg/Pose"](position=Point(x=1.0, y=-2.0, z=float("nan")),
                                                  orientation=Quaternion(x=0.1, y=0.2, z=0.3, w=0.9)))
    ref = bytes(store.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))
    assert cdr_frame.pose_stamped(STAMP_NS, frame_id, position, quat) == ref
    # the vectorized codec of the bags, both ways
    rows = posestamped_cdr(np.array([STAMP_NS, STAMP_NS]), np.stack([position] * 2), np.stack([quat] * 2), frame_id)
    assert rows == [ref, ref]
    stamp, pos, q = posestamped_arrays([ref])
    assert stamp[0] == STAMP_NS and np.array_equal(pos[0], position, equal_nan=True) and np.array_equal(q[0], quat)


@pytest.mark.parametrize("children", [[], ["a"], ["abc", "abcd", "wheel_long_name"]])
def test_tf_message_equals_rosbags(store, children):
    rng = np.random.default_rng(len(children))
    position, quat = rng.normal(size=(len(children), 3)), rng.normal(size=(len(children), 4))
    T = store.types
    transforms = [T["geometry_msgs/msg/TransformStamped"](
        header=_header(store, STAMP_NS, "world"), child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
            rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])))
        for child, p, q in zip(children, position, quat)]
    msg = T["tf2_msgs/msg/TFMessage"](transforms=transforms)
    ref = bytes(store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage"))
    assert cdr_frame.tf_message(STAMP_NS, "world", children, position, quat) == ref
