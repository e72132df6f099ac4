"""The MOCAP4ROS2 driver's messages (mocap4r2_msgs/RigidBodies) as input.

A hand-built trajectory of three bodies (one hidden for 10 frames, a fourth body nobody asked for) is
written the way the driver publishes it: one RigidBodies per frame, bodies by name, frame numbers.
Recorded: a bag of it reads back exactly (float64 in, float64 out) and `euc-ros convert` writes the
same poses to CSV (9 decimals). Live: a publisher at 120 Hz feeds a mocap_ingest process
(``topic_type: rigid_bodies``) whose MocapFrame stream is checked frame by frame.
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mocap4r2_msgs", reason="mocap4r2_msgs is not built (./run setup builds extra_interfaces/)")

from euc_ros.core.io.bags import RIGID_BODIES, BagWriter, read_mocap_bag  # noqa: E402
from euc_ros.core.io.motive_csv import read_motive_csv  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.integration]
BODIES = ["E", "PV", "CHL"]
N = 240
RATE = 120.0
T0_NS = 1_732_000_000 * 10**9
HIDDEN = range(100, 110)          # PV is not in these messages (occluded: the driver leaves it out)


def trajectory():
    """Positions (b, n, 3) and unit quaternions (b, n, 4) of a smooth ride-like motion (Z-up)."""
    t = np.arange(N) / RATE
    pos = np.stack([np.stack([0.8 * t + 0.1 * j, 0.05 * np.sin(2 * t + j), 0.3 + 0.4 * j + 0.01 * np.cos(3 * t)],
                             axis=-1) for j in range(len(BODIES))])
    yaw = 0.2 * np.sin(t)[None, :] + 0.1 * np.arange(len(BODIES))[:, None]
    quat = np.stack([np.zeros_like(yaw), np.zeros_like(yaw), np.sin(yaw / 2), np.cos(yaw / 2)], axis=-1)
    return pos, quat


def messages(typestore):
    """RigidBodies per frame as the driver writes them (rosbags objects), with an extra body 'Cup'."""
    T = typestore.types
    pos, quat = trajectory()
    out = []
    for k in range(N):
        bodies = []
        for j, name in list(enumerate(BODIES)) + [(0, "Cup")]:
            if name == "PV" and k in HIDDEN:
                continue
            p, q = pos[j, k] + (np.array([5.0, 0.0, 0.0]) if name == "Cup" else 0.0), quat[j, k]
            pose = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
                                               orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2],
                                                                                              w=q[3]))
            bodies.append(T["mocap4r2_msgs/msg/RigidBody"](rigid_body_name=name, markers=[], pose=pose))
        stamp = T0_NS + int(round(k * 1e9 / RATE))
        header = T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=stamp // 10**9,
                                                                                 nanosec=stamp % 10**9),
                                          frame_id="map")
        out.append((stamp, T[RIGID_BODIES](header=header, frame_number=1000 + k, rigidbodies=bodies)))
    return out


@pytest.fixture(scope="module")
def driver_bag(tmp_path_factory):
    path = tmp_path_factory.mktemp("m4r2") / "driver_bag"
    w = BagWriter(path)
    for stamp, msg in messages(w.typestore):
        w.write("/rigid_bodies", RIGID_BODIES, msg, stamp)
    w.close()
    return path


def test_a_driver_bag_reads_back_exactly(driver_bag):
    series = read_mocap_bag(driver_bag)
    pos, quat = trajectory()
    assert series.bodies == BODIES + ["Cup"]
    assert series.frame.tolist() == list(range(1000, 1000 + N))
    np.testing.assert_array_equal(series.t, (np.round(np.arange(N) * 1e9 / RATE).astype(np.int64)) * 1e-9)
    sel = series.select(BODIES)
    hidden = np.zeros(N, bool)
    hidden[list(HIDDEN)] = True
    want_tracked = np.ones((3, N), bool)
    want_tracked[1] = ~hidden
    assert (sel.tracked == want_tracked).all()
    np.testing.assert_array_equal(sel.position[want_tracked], pos[want_tracked])       # float64 round trip
    # quaternions are renormalised on input: divided by a norm that is 1 to within 1 ulp
    np.testing.assert_allclose(sel.quat[want_tracked], quat[want_tracked], rtol=0, atol=2 * np.finfo(float).eps)
    assert np.isnan(sel.position[1, hidden]).all()                                     # gaps, never zeros
    assert series.meta["source"] == f"{RIGID_BODIES} /rigid_bodies"


def test_euc_ros_convert_writes_the_driver_bag_as_motive_csv(driver_bag, tmp_path):
    out = tmp_path / "ride.csv"
    r = subprocess.run([sys.executable, "-m", "euc_ros.cli.main", "convert", str(driver_bag), str(out),
                        "--world-up", "z", "--no-progress"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    csv = read_motive_csv(out, world_up="z").select(BODIES)
    pos, _ = trajectory()
    assert csv.n_frames == N and (csv.tracked[1] == ~np.isin(np.arange(N), list(HIDDEN))).all()
    ok = csv.tracked
    np.testing.assert_allclose(csv.position[ok], pos[ok], rtol=0, atol=0.5e-9 + 1e-15)   # 9 decimals


def test_live_rigid_bodies_into_a_mocap_ingest_process(ros_context, tmp_path):
    import rclpy
    from euc_msgs.msg import MocapFrame
    from mocap4r2_msgs.msg import RigidBodies, RigidBody
    from rclpy.executors import SingleThreadedExecutor

    from euc_ros.ros import interfaces as itf

    proc = subprocess.Popen([str(Path(sys.executable).parent / "mocap_ingest"), "--ros-args",
                             "-p", "source:=topics", "-p", "topic_type:=rigid_bodies", "-p", "world_up:=z",
                             "-p", f"bodies:={BODIES}", "-p", "publish_tf:=false"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    node = rclpy.create_node("mocap4r2_driver_stand_in", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    got: list[MocapFrame] = []
    pub = node.create_publisher(RigidBodies, "/rigid_bodies", 10)
    node.create_subscription(MocapFrame, itf.MOCAP_FRAME, got.append, itf.RELIABLE_QOS)
    pos, quat = trajectory()
    try:
        deadline = time.monotonic() + 30
        while not (pub.get_subscription_count() and node.count_publishers(itf.MOCAP_FRAME)) \
                and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
        assert pub.get_subscription_count(), "mocap_ingest did not subscribe /rigid_bodies"
        t_settle = time.monotonic() + 1.0             # discovery settles both ways (the notes' asymmetric match)
        while time.monotonic() < t_settle:
            ex.spin_once(timeout_sec=0.05)
        t_next = time.monotonic()
        for k in range(N):
            msg = RigidBodies()
            stamp = T0_NS + int(round(k * 1e9 / RATE))
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 10**9)
            msg.frame_number = 1000 + k
            for j, name in enumerate(BODIES):
                if name == "PV" and k in HIDDEN:
                    continue
                rb = RigidBody(rigid_body_name=name)
                rb.pose.position.x, rb.pose.position.y, rb.pose.position.z = (float(v) for v in pos[j, k])
                o = rb.pose.orientation
                o.x, o.y, o.z, o.w = (float(v) for v in quat[j, k])
                msg.rigidbodies.append(rb)
            pub.publish(msg)
            t_next += 1.0 / RATE
            while time.monotonic() < t_next:
                ex.spin_once(timeout_sec=max(t_next - time.monotonic(), 0.0))
        deadline = time.monotonic() + 10
        while len(got) < N and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
    finally:
        ex.shutdown()
        node.destroy_node()
        proc.send_signal(2)
        try:
            out = proc.communicate(timeout=10)[0]
        except subprocess.TimeoutExpired:
            proc.kill()
            out = proc.communicate()[0]
    assert proc.returncode == 0, out[-2000:]
    assert [m.frame_number for m in got] == list(range(1000, 1000 + N)), out[-2000:]   # every frame, in order
    for k, m in enumerate(got):
        assert list(m.body_names) == BODIES
        assert list(m.tracked) == [True, k not in HIDDEN, True]
        assert m.stamp_source == MocapFrame.STAMP_SOURCE_HEADER
        assert m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == T0_NS + int(round(k * 1e9 / RATE))
        for j in range(3):
            if m.tracked[j]:
                p = m.poses[j].position
                assert (p.x, p.y, p.z) == tuple(pos[j, k])
            else:
                assert np.isnan(m.poses[j].position.x)
