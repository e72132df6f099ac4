"""The numpy MocapFrame codec against rclpy's own serializer (the reference implementation of CDR)."""
# covers: euc_ros/core/mocap/frame.py
from __future__ import annotations

import numpy as np
import pytest

rclpy_serialization = pytest.importorskip("rclpy.serialization", reason="rclpy is not installed")
euc_msgs = pytest.importorskip("euc_msgs.msg", reason="the euc_msgs interfaces are not built (./run setup)")

from euc_ros.core.io import cdr_frame  # noqa: E402
from euc_ros.core.mocap.frame import Frame  # noqa: E402
from euc_ros.ros import convert  # noqa: E402

MocapFrame = euc_msgs.MocapFrame


def _random_frame(rng, n: int, name_len: int) -> Frame:
    names = ["".join(rng.choice(list("ABCDEFGHxyz_0123"), size=rng.integers(1, name_len + 1))) + str(i)
             for i in range(n)]
    pos = rng.normal(size=(n, 3))
    quat = rng.normal(size=(n, 4))
    tracked = rng.random(n) > 0.3
    pos[~tracked] = np.nan
    quat[~tracked] = np.nan
    err = rng.random(n).astype(np.float32).astype(float) * 1e-3
    stamp = int(rng.integers(0, 2**31 - 1)) * 1_000_000_000 + int(rng.integers(0, 10**9))
    return Frame(stamp, int(rng.integers(-1, 2**40)), names, pos, quat, tracked, err)


@pytest.mark.parametrize("n", [0, 1, 2, 3, 14, 56])
@pytest.mark.parametrize("frame_id", ["world", "w", "mocap_world_frame"])
def test_encoded_bytes_deserialize_to_the_same_message(n, frame_id):
    rng = np.random.default_rng(n * 31 + len(frame_id))
    fr = _random_frame(rng, n, name_len=7)
    raw = convert.frame_to_raw(fr, frame_id, MocapFrame.STAMP_CAPTURE_TIME)
    ref = convert.frame_to_msg(fr, frame_id, MocapFrame.STAMP_CAPTURE_TIME)
    got = rclpy_serialization.deserialize_message(raw, MocapFrame)
    assert got == ref or _same(got, ref)
    # same length as rclpy's serialization (padding bytes may differ: rmw leaves them uninitialised)
    assert len(raw) == len(rclpy_serialization.serialize_message(ref))


def _same(a, b) -> bool:
    """Messages equal with NaN == NaN (message __eq__ compares floats with ==)."""
    def poses(m):
        return np.array([[p.position.x, p.position.y, p.position.z, p.orientation.x, p.orientation.y,
                          p.orientation.z, p.orientation.w] for p in m.poses]).reshape(-1, 7)
    return (a.header == b.header and a.stamp_source == b.stamp_source and a.frame_number == b.frame_number
            and list(a.body_names) == list(b.body_names) and list(a.tracked) == list(b.tracked)
            and np.array_equal(poses(a), poses(b), equal_nan=True)
            and np.array_equal(np.asarray(a.mean_marker_error), np.asarray(b.mean_marker_error), equal_nan=True))


@pytest.mark.parametrize("n", [0, 1, 5, 14, 56])
def test_decoding_rclpy_bytes_equals_the_message_path(n):
    rng = np.random.default_rng(100 + n)
    for _ in range(5):
        fr = _random_frame(rng, n, name_len=9)
        msg = convert.frame_to_msg(fr, "world", MocapFrame.STAMP_FILE_TIME)
        raw = rclpy_serialization.serialize_message(msg)
        got, frame_id = convert.raw_to_frame(raw)
        ref = convert.msg_to_frame(msg)
        assert frame_id == "world"
        assert (got.stamp_ns, got.frame_number, got.bodies) == (ref.stamp_ns, ref.frame_number, ref.bodies)
        for k in ("position", "quat", "tracked", "mean_marker_error"):
            np.testing.assert_array_equal(getattr(got, k), getattr(ref, k))


def test_a_message_with_mismatched_sequences_reads_as_the_message_path_does():
    msg = convert.frame_to_msg(_random_frame(np.random.default_rng(3), 4, 5), "world", 1)
    msg.tracked = [True, False]          # a publisher that filled the flags wrongly
    msg.mean_marker_error = []
    raw = rclpy_serialization.serialize_message(msg)
    got, _ = convert.raw_to_frame(raw)
    ref = convert.msg_to_frame(msg)
    np.testing.assert_array_equal(got.tracked, ref.tracked)
    np.testing.assert_array_equal(got.position, ref.position)
    assert np.isnan(got.mean_marker_error).all()


def test_truncated_or_big_endian_bytes_are_refused_and_the_fallback_reads_valid_ones():
    fr = _random_frame(np.random.default_rng(4), 3, 4)
    raw = convert.frame_to_raw(fr, "world", 1)
    for cut in (3, 10, len(raw) // 2, len(raw) - 1):
        with pytest.raises(cdr_frame.CdrError):
            cdr_frame.decode(raw[:cut])
    with pytest.raises(cdr_frame.CdrError, match="little-endian"):
        cdr_frame.decode(b"\x00\x00" + raw[2:])
    # a count larger than the message is refused, not allocated
    bad = bytearray(raw)
    bad[4 + 32:4 + 36] = (10**9).to_bytes(4, "little")
    with pytest.raises(cdr_frame.CdrError):
        cdr_frame.decode(bytes(bad))


@pytest.mark.parametrize("frame_id", ["world", "w", "map_frame_x"])
def test_pose_stamped_and_tf_bytes_deserialize_to_the_message_classes(frame_id):
    from geometry_msgs.msg import PoseStamped
    from tf2_msgs.msg import TFMessage

    rng = np.random.default_rng(len(frame_id))
    stamp = 1_700_000_000_123_456_789
    pos, quat = rng.normal(size=(5, 3)), rng.normal(size=(5, 4))
    ps = rclpy_serialization.deserialize_message(cdr_frame.pose_stamped(stamp, frame_id, pos[0], quat[0]), PoseStamped)
    ref = convert.pose_stamped(stamp, frame_id, pos[0], quat[0])
    assert ps == ref
    children = ["E", "CHR", "a_longer_child_name", "H", "x"]
    tf = rclpy_serialization.deserialize_message(cdr_frame.tf_message(stamp, frame_id, children, pos, quat), TFMessage)
    ref_tf = TFMessage(transforms=[convert.transform_stamped(stamp, frame_id, c, pos[i], quat[i])
                                   for i, c in enumerate(children)])
    assert tf == ref_tf
    empty = rclpy_serialization.deserialize_message(cdr_frame.tf_message(stamp, frame_id, [], pos[:0], quat[:0]),
                                                    TFMessage)
    assert list(empty.transforms) == []
