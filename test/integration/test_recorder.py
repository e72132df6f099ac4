"""The recorder's drain loop (issue 15): every message of every topic, a topic that appears late,
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
from euc_ros.launch import Launcher, NodeSpec


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
