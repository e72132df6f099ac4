"""FoxgloveBridge (euc_ros.ros.foxglove_bridge) on a real graph, in-process: it bridges the viewed
topics it finds, with the publishers' type, skips the others (and says why when a viewed topic
cannot be bridged, or when publishers of another type join a bridged one), and forwards the CDR
bytes unchanged on a ros2msg/cdr channel. A foxglove-sdk MCAP sink on the bridge's context records
what the channels carry; mcap-ros2-support decodes it back from the schema the bridge wrote."""
from __future__ import annotations

import time

import pytest

pytest.importorskip("rclpy")
pytest.importorskip("foxglove")

import foxglove  # noqa: E402
import rclpy  # noqa: E402
from geometry_msgs.msg import PoseStamped  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from euc_ros.ros.foxglove_bridge import FoxgloveBridge  # noqa: E402

pytestmark = pytest.mark.ros


def spin_until(executor, condition, timeout_s: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() >= deadline:
            return False
        executor.spin_once(timeout_sec=0.01)
    return True


def test_viewed_topics_are_forwarded_as_ros2msg_cdr(ros_context, other_ros_context, tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.executors import SingleThreadedExecutor

    node = rclpy.create_node("bridge_test", context=ros_context)
    talker = rclpy.create_node("bridge_talker", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    context = foxglove.Context()
    lines = []
    writer = foxglove.open_mcap(tmp_path / "seen.mcap", context=context,
                                writer_options=foxglove.mcap.MCAPWriteOptions(compression=None))
    bridge = FoxgloveBridge(node, context, report=lines.append)
    try:
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        pose_pub = talker.create_publisher(PoseStamped, "mocap/Box/pose", qos)
        talker.create_publisher(String, "chatter", qos)                 # not a viewed topic
        talker.create_publisher(PoseStamped, "mocap/Two/pose", qos)     # two types on one topic
        other = rclpy.create_node("bridge_other", context=other_ros_context)
        other.create_publisher(String, "mocap/Two/pose", qos)
        graph = {"/mocap/Box/pose": 1, "/mocap/Two/pose": 2, "/chatter": 1}   # topic -> types

        def graph_complete() -> bool:
            seen = dict(node.get_topic_names_and_types())
            return all(len(seen.get(topic, ())) == n for topic, n in graph.items())

        assert spin_until(ex, graph_complete)
        assert bridge.discover() == ["/mocap/Box/pose"]
        assert bridge.discover() == []
        assert set(bridge.topics) == {"/mocap/Box/pose"}
        assert bridge.topics["/mocap/Box/pose"].type_name == "geometry_msgs/msg/PoseStamped"
        assert "disagree on the type" in bridge.skipped["/mocap/Two/pose"]
        assert "view: /mocap/Box/pose (geometry_msgs/msg/PoseStamped)" in lines
        assert sum("skipping /mocap/Two/pose" in line for line in lines) == 1     # said once
        assert spin_until(ex, lambda: pose_pub.get_subscription_count() >= 1)

        sent = []
        for i in range(5):
            msg = PoseStamped()
            msg.header.frame_id = "world"
            msg.header.stamp.sec = 100 + i
            msg.pose.position.x, msg.pose.orientation.w = 0.5 * i, 1.0
            pose_pub.publish(msg)
            sent.append(msg)
        assert spin_until(ex, lambda: bridge.topics["/mocap/Box/pose"].forwarded == 5)

        other.create_publisher(String, "mocap/Box/pose", qos)     # joins a bridged topic with another type
        graph["/mocap/Box/pose"] = 2
        assert spin_until(ex, graph_complete)
        assert bridge.discover() == [] and bridge.discover() == []
        assert "std_msgs/msg/String are not shown" in bridge.skipped["/mocap/Box/pose"]
        assert sum("view: /mocap/Box/pose: publishers of" in line for line in lines) == 1
    finally:
        bridge.close()
        writer.close()
        ex.shutdown()
        talker.destroy_node()
        node.destroy_node()
        if "other" in locals():
            other.destroy_node()

    with open(tmp_path / "seen.mcap", "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        channels = list(summary.channels.values())
        assert [c.topic for c in channels] == ["/mocap/Box/pose"] and channels[0].message_encoding == "cdr"
        schema = summary.schemas[channels[0].schema_id]
        assert (schema.name, schema.encoding) == ("geometry_msgs/msg/PoseStamped", "ros2msg")
        got = [m for _, _, _, m in reader.iter_decoded_messages()]
    assert [(m.header.stamp.sec, m.pose.position.x, m.header.frame_id) for m in got] == \
        [(s.header.stamp.sec, s.pose.position.x, "world") for s in sent]
