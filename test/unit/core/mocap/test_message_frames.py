"""Frames from NatNet packets and from named poses (mocap4r2_msgs/RigidBodies), by hand
(euc_ros.core.mocap.message_frames).

Tolerances: positions go through float32 where the message type is float32 (1e-6 of a ~1.5 m value is
17x its half-ulp 6e-8).

Named poses: expected values are written out for each case: body order from ``bodies``, not from the
message; a body absent, repeated, unknown, with a non-finite position or a non-unit quaternion; Y-up
worlds rotated by +90 deg about X (Motive's up (0, 1, 0) becomes REP-103's (0, 0, 1)).
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.io.natnet import FrameOfData, RigidBodyData
from euc_ros.core.mocap.message_frames import frame_from_named_poses, frame_from_natnet, natnet_capture_stamp

MS = 1_000_000
S = np.sqrt(0.5)


def test_natnet_capture_stamp():
    assert natnet_capture_stamp(1_000 * MS, 0.0045) == (1_000 * MS - 4_500_000, True)
    assert natnet_capture_stamp(1_000 * MS, float("nan")) == (1_000 * MS, False)
    assert natnet_capture_stamp(1_000 * MS, 2.0, max_latency_s=1.0) == (1_000 * MS, False)
    assert natnet_capture_stamp(1_000 * MS, -0.001) == (1_000 * MS, False)


def test_frame_from_natnet_maps_names_validity_and_y_up():
    s = np.sqrt(0.5)
    rbs = [RigidBodyData(7, np.float32([0.1, 1.5, -0.2]), np.float32([s, 0, 0, s]), 0.0003, True),
           RigidBodyData(2, np.float32([0.0, 0.0, 0.0]), np.float32([0, 0, 0, 0]), 0.0, False),
           RigidBodyData(99, np.float32([1, 1, 1]), np.float32([0, 0, 0, 1]), 0.0, True)]   # no name
    m = FrameOfData(frame_number=42, rigid_bodies=rbs)
    f = frame_from_natnet(m, {7: "E", 2: "H", 99: ""}, ["H", "E", "CHR"], 123, world_up="y")
    assert (f.stamp_ns, f.frame_number, f.bodies) == (123, 42, ["H", "E", "CHR"])
    assert f.tracked.tolist() == [False, True, False]
    # Motive Y-up (X, Y, Z) -> Z-up (X, -Z, Y); a rotation of +90 deg about Motive X is +90 deg about Z-up x
    np.testing.assert_allclose(f.position[1], [0.1, 0.2, 1.5], atol=1e-6)
    np.testing.assert_allclose(f.quat[1], [s, 0, 0, s], atol=1e-6)
    assert f.mean_marker_error[1] == pytest.approx(0.0003)
    assert np.isnan(f.position[[0, 2]]).all() and np.isnan(f.quat[[0, 2]]).all()
    g = frame_from_natnet(m, {7: "E"}, ["E"], 0, world_up="z")
    np.testing.assert_allclose(g.position[0], [0.1, 1.5, -0.2], atol=1e-6)


def test_bodies_in_the_requested_order_missing_ones_untracked_unknown_ones_named():
    names = ["PV", "E", "Cup"]                     # the message's order; "Cup" is not wanted; "TL" is absent
    pos = [[1.0, 2.0, 3.0], [0.1, 0.2, 0.3], [9.0, 9.0, 9.0]]
    quat = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, S, S], [0.0, 0.0, 0.0, 1.0]]
    frame, unknown = frame_from_named_poses(123, 7, names, pos, quat, ["E", "TL", "PV"], world_up="z")
    assert frame.stamp_ns == 123 and frame.frame_number == 7 and frame.bodies == ["E", "TL", "PV"]
    assert frame.tracked.tolist() == [True, False, True]
    np.testing.assert_array_equal(frame.position[0], [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(frame.position[2], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(frame.quat[0], [0.0, 0.0, S, S])
    assert np.isnan(frame.position[1]).all() and np.isnan(frame.quat[1]).all()    # a gap, never zeros
    assert unknown == ["Cup"]


def test_invalid_poses_are_gaps_and_a_repeated_name_keeps_its_first_pose():
    names = ["E", "E", "TL", "PV"]
    pos = [[1.0, 0.0, 0.0], [5.0, 5.0, 5.0], [np.nan, 0.0, 0.0], [0.0, 0.0, 1.0]]
    quat = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0]]
    frame, unknown = frame_from_named_poses(0, 1, names, pos, quat, ["E", "TL", "PV"])
    assert frame.tracked.tolist() == [True, False, False]
    np.testing.assert_array_equal(frame.position[0], [1.0, 0.0, 0.0])
    assert unknown == ["E"]                               # the repeat is reported, not averaged in


def test_a_quaternion_within_the_norm_tolerance_is_normalised():
    q = np.array([0.0, 0.0, 0.0, 1.0005])
    frame, _ = frame_from_named_poses(0, 1, ["E"], [[0.0, 0.0, 0.0]], [q], ["E"])
    assert frame.tracked[0] and np.linalg.norm(frame.quat[0]) == pytest.approx(1.0, abs=1e-15)


def test_y_up_world_is_rotated_to_z_up():
    # Motive Y-up: up is +Y, the body is 1 m up and 2 m along Motive's +Z (toward the viewer), and it is
    # yawed 90 deg about Motive's up axis (+Y): q = (0, sin 45, 0, cos 45).
    frame, _ = frame_from_named_poses(0, 1, ["E"], [[0.5, 1.0, 2.0]], [[0.0, S, 0.0, S]], ["E"], world_up="y")
    # REP-103: x stays, Motive +Z is -y, Motive +Y is +z; the yaw is about +z
    np.testing.assert_allclose(frame.position[0], [0.5, -2.0, 1.0], atol=0)
    np.testing.assert_allclose(frame.quat[0], [0.0, 0.0, S, S], atol=1e-16)
