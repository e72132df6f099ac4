"""What `euc-ros play` says when the subscribers it waits for do not all come: plain counts, no
"subscription(s)"."""
from __future__ import annotations

import threading
from types import SimpleNamespace

import pytest

from euc_ros.cli.play import Player, missing_subscribers


@pytest.mark.parametrize("have, wanted, said", [
    ({"/mocap/frame": 0}, 1, "/mocap/frame has no subscriber"),
    ({"/mocap/frame": 0, "/clock": 1}, 1, "/mocap/frame has no subscriber"),
    ({"/a": 0, "/b": 0}, 1, "/a has no subscriber, /b has no subscriber"),
    ({"/a": 1, "/b": 2}, 2, "/a has 1 of 2 subscribers"),
    ({"/a": 1, "/b": 0}, 2, "/a has 1 of 2 subscribers, /b has 0 of 2"),
    ({"/a": 3}, 3, ""),
])
def test_missing_subscribers_are_said_with_their_counts(have, wanted, said):
    assert missing_subscribers(have, wanted) == said


class _Log:
    def __init__(self):
        self.lines = []

    def info(self, text):
        self.lines.append(text)

    warning = info


class _Node:
    """Stands in for the rclpy node: publishers whose subscription counts the test sets."""

    def __init__(self, counts):
        self.counts, self.log = counts, _Log()

    def get_logger(self):
        return self.log

    def create_publisher(self, cls, topic, qos):
        return SimpleNamespace(get_subscription_count=lambda: self.counts[topic])


def test_the_player_says_who_is_missing_when_it_stops_waiting():
    pytest.importorskip("rclpy")
    pytest.importorskip("std_msgs.msg")
    node = _Node({"/mocap/frame": 0, "/chatter": 1})
    source = SimpleNamespace(types={"/mocap/frame": "std_msgs/msg/String", "/chatter": "std_msgs/msg/String"},
                             path="bag")
    player = Player(node, source, rate=1.0, clock_hz=None, stop=threading.Event())
    player.wait_for_subscribers(2, timeout_s=0.0, settle_s=0.0, first_bag_ns=0)
    assert node.log.lines == ["after 0 s, /mocap/frame has 0 of 2 subscribers, /chatter has 1 of 2: playing anyway"]
