"""FlatEncoder against rclpy's serializer (the rosidl C typesupport), byte for byte, for the two flat
messages of the live path with values that exercise every alignment case (strings of every length mod 4,
NaN, infinities, negative zero, booleans), and against the generated classes' field lists."""
from __future__ import annotations

import math

import numpy as np
import pytest

rclpy_serialization = pytest.importorskip("rclpy.serialization")
euc_msgs = pytest.importorskip("euc_msgs.msg")

from euc_ros.core.io.cdr_flat import FlatEncoder  # noqa: E402
from euc_ros.ros.convert import flat_fields, ns_to_stamp  # noqa: E402


def _build(cls, stamp_ns, frame_id, fields, values):
    m = cls()
    m.header.stamp = ns_to_stamp(stamp_ns)
    m.header.frame_id = frame_id
    for (name, kind), v in zip(fields, values):
        obj = m
        *path, last = name.split(".")
        for p in path:
            obj = getattr(obj, p)
        setattr(obj, last, bool(v) if kind == "bool" else (float(v) if kind == "float64" else v))
    return m


def _values(fields, rng, text):
    out = []
    for _, kind in fields:
        if kind == "bool":
            out.append(bool(rng.integers(2)))
        elif kind == "float64":
            out.append(float(rng.choice([rng.normal() * 10.0 ** int(rng.integers(-9, 9)), math.nan, math.inf, -0.0])))
        else:
            out.append(text)
    return out


@pytest.mark.parametrize("cls_name", ["RiderState", "TorqueEstimate"])
def test_flat_encoder_writes_what_rclpy_serializes(cls_name):
    cls = getattr(euc_msgs, cls_name)
    fields = flat_fields(cls)
    enc = FlatEncoder(fields)
    rng = np.random.default_rng(5)
    for k, (frame_id, text) in enumerate([("world", "hinge"), ("w", ""), ("map", "3dof+ground_slope"),
                                           ("odom_x", "not yet (12.3 of 30.0 s of valid states)"),
                                           ("", "ok"), ("wörld", "eq3")]):
        stamp = int(rng.integers(0, 2**31 * 10**9)) if k else 0
        values = _values(fields, rng, text)
        got = enc.encode(stamp, frame_id, values)
        want = rclpy_serialization.serialize_message(_build(cls, stamp, frame_id, fields, values))
        # same length, same bytes except alignment padding (rclpy leaves it uninitialised; ours is 0)
        assert len(got) == len(want), (cls_name, frame_id, text)
        diff = [i for i in range(len(got)) if got[i] != want[i]]
        assert all(got[i] == 0 for i in diff), (cls_name, frame_id, text, diff)
        back = rclpy_serialization.deserialize_message(got, cls)
        assert (back.header.frame_id, back.header.stamp.sec, back.header.stamp.nanosec) == (
            frame_id, stamp // 10**9, stamp % 10**9)
        for (name, kind), v in zip(fields, values):
            obj = back
            for part in name.split("."):
                obj = getattr(obj, part)
            if kind == "float64":
                assert (math.isnan(v) and math.isnan(obj)) or (obj == v and math.copysign(1, obj) == math.copysign(1, v))  # noqa: E501
            else:
                assert obj == v, name


def test_field_lists_follow_the_message_definitions():
    names = [n for n, _ in flat_fields(euc_msgs.RiderState)]
    assert names[:2] == ["has_rider", "x"] and "c.x" in names and names[-1] == "filter_lag"
    assert names.index("g.z") == names.index("c.x") + 5
    with pytest.raises(ValueError):
        flat_fields(euc_msgs.MocapFrame)      # sequences are not flat
    with pytest.raises(ValueError):
        FlatEncoder([("a", "int32")])
    with pytest.raises(ValueError):
        FlatEncoder([("a", "float64")]).encode(0, "w", [])
