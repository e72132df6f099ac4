"""The recorder's drain loop: every message of every topic, a topic that appears late,
a clean close on SIGINT. Real processes: the ``recorder`` console script and ``relay blast``
publishers (pre-serialized CDR, the pipeline's reliable QoS). Speed is the benchmark's business.
"""
from __future__ import annotations

import io
import json
import os
import re
import signal
import sys

import pytest
import yaml

from euc_ros.bench.recording import blast_topics
from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.ros.launcher import Launcher, NodeSpec


def _blast(part: str, result, frame_rate: float = 300.0, duration_s: float = 1.5) -> NodeSpec:
    return NodeSpec(sys.executable, name=f"blast{part[0]}", ros_args=False,
                    args=["-m", "euc_ros.bench.relay", "blast", "--frame-rate", str(frame_rate), "--duration",
                          str(duration_s), "--start-delay", "0.3", "--linger", "0.5", "--part", part,
                          "--result", str(result)])


@pytest.mark.ros
@pytest.mark.integration
def test_recorder_records_every_message_and_discovers_a_late_topic(ros_domain, tmp_path):
    bag = tmp_path / "bag"
    log = io.StringIO()
    recorder = NodeSpec("recorder", parameters={"output": str(bag), "topics": blast_topics(),
                                                "discovery_period": 0.05}, required=False)
    # the mix in two halves: /tf and the odd topics only appear once the first half is recorded
    first, second = tmp_path / "first.json", tmp_path / "second.json"
    with Launcher([recorder, _blast("0/2", first)], stream=log) as launcher:
        assert launcher.wait(timeout=60, until=lambda: launcher.procs["blast0"].poll() is not None), log.getvalue()
        assert launcher.procs["blast0"].returncode == 0, log.getvalue()
        assert "subscribed /tf" not in log.getvalue()
        with Launcher([_blast("1/2", second)], stream=log) as late:
            assert late.wait(timeout=60) and late.exit_codes["blast1"] == 0, log.getvalue()
        assert "subscribed /tf" in log.getvalue()
        os.killpg(launcher.procs["recorder"].pid, signal.SIGINT)
        assert launcher.procs["recorder"].wait(timeout=15) == 0, log.getvalue()

    assert check_bag(bag) == []          # closed: summary, metadata.yaml, counts agree; every message decodes
    sent = {}
    for result in (first, second):
        sent.update({"/" + t.lstrip("/"): n for t, n in json.loads(result.read_text())["sent"].items()})
    assert set(sent) == set(blast_topics())
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
    assert counts == sent                # nothing lost, nothing doubled
    closed = re.search(r"\[recorder\] closed \S+: (\d+) messages", log.getvalue())
    assert closed and int(closed.group(1)) == sum(sent.values())
    # receive times: non-decreasing per topic, and the late half after the first
    stamps = {}
    for topic, _, stamp, _ in read_bag(bag, topics=["/mocap/frame", "/tf"]):
        stamps.setdefault(topic, []).append(stamp)
    assert all(a == sorted(a) for a in stamps.values())
    assert min(stamps["/tf"]) > max(stamps["/mocap/frame"])


def _expected_mix(n_bodies: int = 14) -> dict:
    """The blast mix as rclpy messages, by topic (stamps set per frame)."""
    from euc_ros.bench.relay import blast_mix

    return {"/" + topic.lstrip("/"): msg for topic, _, msg in blast_mix(n_bodies)}   # absolute, as in the bag


@pytest.mark.ros
@pytest.mark.integration
def test_recorder_keeps_every_message_of_a_36k_messages_per_second_burst(ros_domain, tmp_path):
    """One publisher process sends 10 000 frames of the mix (180 000 messages) at 2000 frames/s, 36k
    msgs/s asked: above ~28k msgs/s, where a recorder that takes one message per callback loses (13-26 % at 45-50k). (At
    3000 frames/s the test lost a few messages of the publisher's own segment in one run at load ~4 with
    other ROS processes on the machine; the recorder's capacity itself is `euc-ros bench --only recording`'s.)
    The rate reached is printed, not asserted (a starved publisher falls behind, as fast as it can;
    unpaced, it took a whole core from the recorder on a machine at load 6). Every message is in the
    bag once, in order, with
    its content: each recorded message equals the rclpy serialization of the expected message with the
    stamp it carries (both through rosbags' CDR codec), and every topic carries the same 10 000 frame
    stamps."""
    from rclpy.serialization import serialize_message

    from euc_ros.bench.recording import fast_publisher_env
    from euc_ros.core.io.msgdefs import make_typestore

    n_frames, frame_rate = 10_000, 2000.0
    bag, result = tmp_path / "bag", tmp_path / "blast.json"
    log = io.StringIO()
    recorder = NodeSpec("recorder", parameters={"output": str(bag), "topics": blast_topics(),
                                                "discovery_period": 0.05}, required=False)
    blast = NodeSpec(sys.executable, name="blast", ros_args=False, env=fast_publisher_env(),
                     args=["-m", "euc_ros.bench.relay", "blast", "--frame-rate", str(frame_rate), "--duration",
                           str(n_frames / frame_rate), "--start-delay", "0.5", "--linger", "1.0",
                           "--result", str(result)])
    with Launcher([recorder, blast], stream=log) as launcher:
        assert launcher.wait(timeout=120, until=lambda: launcher.procs["blast"].poll() is not None), log.getvalue()
        assert launcher.procs["blast"].returncode == 0, log.getvalue()
        os.killpg(launcher.procs["recorder"].pid, signal.SIGINT)
        assert launcher.procs["recorder"].wait(timeout=30) == 0, log.getvalue()
    assert "[recorder] Fast DDS profile" in log.getvalue()     # the console script chose its transport
    sent = json.loads(result.read_text())
    print(f"burst: {sent['messages']} messages at {sent['achieved_msgs_per_s']:.0f} msgs/s")
    assert sent["frames"] == n_frames and sent["messages"] == 18 * n_frames
    assert check_bag(bag) == []

    store = make_typestore()
    # the expected messages as rosbags objects (rclpy's serialization read back once per topic); each is
    # compared, with the received stamp set, through rosbags' serializer: CDR padding bytes are
    # unspecified (rclpy leaves garbage)
    mix = _expected_mix()
    expected: dict = {}
    stamps: dict[str, list[int]] = {t: [] for t in mix}
    received: dict[str, list[int]] = {t: [] for t in mix}
    for topic, msgtype, t_recv, raw in read_bag(bag, raw=True):
        msg = store.deserialize_cdr(raw, msgtype)
        heads = [t.header for t in msg.transforms] if topic == "/tf" else [msg.header]
        sec, nsec = heads[0].stamp.sec, heads[0].stamp.nanosec
        assert all((h.stamp.sec, h.stamp.nanosec) == (sec, nsec) for h in heads), topic
        if topic not in expected:
            expected[topic] = store.deserialize_cdr(serialize_message(mix[topic]), msgtype)
        want = expected[topic]
        for h in ([t.header for t in want.transforms] if topic == "/tf" else [want.header]):
            h.stamp.sec, h.stamp.nanosec = sec, nsec
        assert store.serialize_cdr(msg, msgtype) == store.serialize_cdr(want, msgtype), \
            f"{topic}: message {len(stamps[topic])} differs"
        stamps[topic].append(sec * 1_000_000_000 + nsec)
        received[topic].append(t_recv)
    every = sorted(set().union(*stamps.values()))          # the frames seen on any topic
    missing = {t: [every.index(x) for x in sorted(set(every) - set(got))] for t, got in stamps.items()}
    assert len(every) == n_frames and not any(missing.values()), \
        f"{len(every)} frames seen; missing frames (index) per topic: {({t: m for t, m in missing.items() if m})}"
    for topic, got in stamps.items():
        assert got == every, f"{topic}: frames doubled or out of order"   # each frame once, in order
        assert received[topic] == sorted(received[topic]), topic            # receive stamps in order per topic


@pytest.mark.ros
@pytest.mark.integration
def test_a_publisher_that_appears_long_after_the_subscribers_gives_its_qos_to_the_bag(ros_context, tmp_path):
    """A topic the recorder sees through a subscriber only is subscribed after PUBLISHER_WAIT_S; the
    publisher that comes later (a slow node at launch) still gives its offered QoS to metadata.yaml."""
    import time

    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import String

    from euc_ros.nodes.recorder import PUBLISHER_WAIT_S

    bag = tmp_path / "bag"
    log = io.StringIO()
    node = Node("late_pub_test", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    node.create_subscription(String, "/late_topic", lambda m: None, 10)
    recorder = NodeSpec("recorder", parameters={"output": str(bag), "topics": ["/late_topic"],
                                                "discovery_period": 0.05}, required=False)
    with Launcher([recorder], stream=log) as launcher:
        deadline = time.monotonic() + 30
        while "subscribed /late_topic" not in log.getvalue() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert "subscribed /late_topic" in log.getvalue(), log.getvalue()
        time.sleep(PUBLISHER_WAIT_S)
        pub = node.create_publisher(String, "/late_topic", 10)
        deadline = time.monotonic() + 30
        while pub.get_subscription_count() < 2 and time.monotonic() < deadline:   # ours and the recorder's
            executor.spin_once(timeout_sec=0.05)
        for k in range(5):
            pub.publish(String(data=str(k)))
            executor.spin_once(timeout_sec=0.05)
        time.sleep(1.0)
        os.killpg(launcher.procs["recorder"].pid, signal.SIGINT)
        assert launcher.procs["recorder"].wait(timeout=15) == 0, log.getvalue()
    executor.shutdown()
    node.destroy_node()

    assert check_bag(bag) == []
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    (entry,) = meta["topics_with_message_count"]
    assert entry["message_count"] == 5
    offered = entry["topic_metadata"]["offered_qos_profiles"]
    assert offered and all(q["reliability"] == "reliable" for q in offered), offered
