"""Bags as rosbag2 Jazzy writes them.

The fixture ``data/rosbag2_jazzy/metadata.yaml`` is the metadata.yaml of a ``ros2 bag record -s mcap``
bag on Jazzy, written here from the format's definition (rosbag2 jazzy branch:
``rosbag2_storage/yaml.hpp`` encodes the fields in this order, ``qos.cpp`` writes version-9 QoS as
policy words, ``bag_metadata.hpp`` sets version 9; ``ros_distro`` is the ROS_DISTRO the recorder ran
on). Our bags must have the same fields, nesting and value kinds; our check (the Jazzy decoder's rules)
must accept the fixture and refuse what the decoder refuses.
"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from euc_ros.core.io.bags import BagWriter, check_bag
from euc_ros.core.io.bags.check import _check_metadata

FIXTURE = Path(__file__).parent / "data" / "rosbag2_jazzy"


def shape(node):
    """The structure of a YAML document: mappings by key, lists by their first element, scalars by kind."""
    if isinstance(node, dict):
        return {k: shape(v) for k, v in node.items()}
    if isinstance(node, list):
        return [shape(node[0])] if node else []
    if node is None:
        return "null"
    return "bool" if isinstance(node, bool) else "int" if isinstance(node, int) else "str"


def assert_like_rosbag2_jazzy(meta_file: Path) -> None:
    """``meta_file`` has the fields, nesting and value kinds of the rosbag2 Jazzy fixture."""
    ours = yaml.safe_load(meta_file.read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
    ref = yaml.safe_load((FIXTURE / "metadata.yaml").read_text(encoding="utf-8"))["rosbag2_bagfile_information"]
    assert ours["version"] == ref["version"] == 9
    assert ours["ros_distro"] == ref["ros_distro"] == "jazzy"
    assert ours["storage_identifier"] == "mcap"
    assert set(ours) == set(ref), set(ours) ^ set(ref)
    s_ours, s_ref = shape(ours), shape(ref)
    assert s_ours["custom_data"] in ("null", {}) or all(v == "str" for v in s_ours["custom_data"].values())
    for key in set(ref) - {"custom_data", "topics_with_message_count"}:
        assert s_ours[key] == s_ref[key], key
    topic_ref = s_ref["topics_with_message_count"][0]
    for entry in ours["topics_with_message_count"]:
        tm = shape(entry["topic_metadata"])
        assert set(entry) == {"topic_metadata", "message_count"}
        assert set(tm) == set(topic_ref["topic_metadata"]), entry["topic_metadata"]["name"]
        for profile in entry["topic_metadata"]["offered_qos_profiles"]:
            assert shape(profile) == topic_ref["topic_metadata"]["offered_qos_profiles"][0]
    assert check_bag(meta_file.parent) == []


def test_our_check_accepts_what_rosbag2_jazzy_writes():
    problems: list[str] = []
    info = _check_metadata(FIXTURE, problems)
    assert problems == [] and info["ros_distro"] == "jazzy"


@pytest.mark.parametrize("edit, message", [
    (lambda q: q.update(reliability="sometimes"), "reliability' is 'sometimes'"),
    (lambda q: q.update(depth="10"), "depth' must be an integer"),
    (lambda q: q.update(deadline={"sec": -1, "nsec": 0}), "deadline' must be {sec, nsec}"),
    (lambda q: q.update(avoid_ros_namespace_conventions="no"), "must be true or false"),
    (lambda q: q.pop("lifespan"), "lacks lifespan"),
])
def test_our_check_refuses_qos_the_jazzy_decoder_cannot_read(tmp_path, edit, message):
    doc = yaml.safe_load((FIXTURE / "metadata.yaml").read_text(encoding="utf-8"))
    edit(doc["rosbag2_bagfile_information"]["topics_with_message_count"][1]["topic_metadata"]
         ["offered_qos_profiles"][0])
    (tmp_path / "metadata.yaml").write_text(yaml.safe_dump(doc), encoding="utf-8")
    problems: list[str] = []
    _check_metadata(tmp_path, problems)
    assert any(message in p for p in problems), problems


def test_bag_writer_writes_what_rosbag2_jazzy_writes(tmp_path):
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    inf = QosTime(9223372036, 854775807)
    qos = Qos(QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, inf, inf,
              QosLiveliness.AUTOMATIC, inf, False)
    w = BagWriter(tmp_path / "bag")
    w.connection("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", offered_qos_profiles=[qos])
    msg = w.typestore.types["diagnostic_msgs/msg/DiagnosticArray"](
        header=w.typestore.types["std_msgs/msg/Header"](
            stamp=w.typestore.types["builtin_interfaces/msg/Time"](sec=1, nanosec=2), frame_id=""),
        status=[])
    w.write("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", msg, 1_000_000_002)
    w.close()
    assert_like_rosbag2_jazzy(tmp_path / "bag" / "metadata.yaml")
    profile = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"][
        "topics_with_message_count"][0]["topic_metadata"]["offered_qos_profiles"][0]
    assert profile["durability"] == "transient_local" and profile["deadline"] == {"sec": 9223372036,
                                                                                  "nsec": 854775807}
