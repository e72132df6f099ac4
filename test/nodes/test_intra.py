"""LocalFanout (euc_ros.ros.intra) with a real rclpy publisher and subscriber: in-process handlers run
first (with the richer local form when given), then the middleware gets the message, also when a
handler fails; the subscription count includes the in-process subscribers."""
from __future__ import annotations

import time

import pytest

pytest.importorskip("rclpy")

import rclpy  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from euc_ros.ros.intra import LocalFanout  # noqa: E402

pytestmark = pytest.mark.ros


def test_handlers_first_then_the_middleware_even_when_a_handler_fails(ros_context):
    from rclpy.executors import SingleThreadedExecutor

    node = rclpy.create_node("fanout_test", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    try:
        qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        got, calls = [], []
        node.create_subscription(String, "fanout", lambda m: got.append(m.data), qos)
        pub = node.create_publisher(String, "fanout", qos)
        deadline = time.monotonic() + 10
        while pub.get_subscription_count() < 1 and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.01)

        def first(arg):
            calls.append(("first", arg, list(got)))

        def failing(arg):
            raise RuntimeError("handler failed")

        fan = LocalFanout(pub, [first])
        assert fan.get_subscription_count() == 2 and fan.topic_name == pub.topic_name
        fan.publish(String(data="a"), local="rich a")
        deadline = time.monotonic() + 10
        while not got and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.01)
        fan.handlers.append(failing)
        with pytest.raises(RuntimeError, match="handler failed"):
            fan.publish(String(data="b"))
        deadline = time.monotonic() + 10
        while len(got) < 2 and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.01)
        assert got == ["a", "b"]                         # both reached the middleware
        assert [c[0] for c in calls] == ["first", "first"]
        assert calls[0][1] == "rich a" and calls[1][1].data == "b"
        assert calls[0][2] == [] and calls[1][2] == ["a"]  # neither was out when its handler ran
    finally:
        ex.shutdown()
        node.destroy_node()
