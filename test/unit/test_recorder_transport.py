"""The recorder's Fast DDS profile: when the recorder applies it, and that Fast DDS reads it.

A shared-memory push that finds the receiver's port full is dropped; a publisher whose segment has
no free buffer reuses the oldest one not being read. The profiles size both for a receive thread that
waits for a core: at the target 100k msgs/s, 100 ms of waiting are 10 000 messages.
"""
from __future__ import annotations

import ast
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

from euc_ros.ros.fastdds import FAST_PUBLISHER_PROFILE, RECORDER_PROFILE, TRANSPORT_CHOICES, transport_env

NS = {"d": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
#: Messages that arrive while a receive thread waits 100 ms for a core at the target rate.
BACKLOG = int(100_000 * 0.1)


def _transports(path) -> tuple[dict, ET.Element]:
    root = ET.parse(path).getroot()
    descs = {d.findtext("d:transport_id", namespaces=NS): d for d in root.iterfind(".//d:transport_descriptor", NS)}
    part = root.find(".//d:participant[@is_default_profile='true']", NS)
    assert part is not None, f"{path}: no default participant profile"
    used = [t.text for t in part.iterfind("d:rtps/d:userTransports/d:transport_id", NS)]
    assert part.findtext("d:rtps/d:useBuiltinTransports", namespaces=NS) == "false"   # else both SHM transports
    return {descs[u].findtext("d:type", namespaces=NS): descs[u] for u in used}, part


def test_the_recorder_profile_queues_a_100_ms_backlog_at_the_target_and_keeps_udp():
    by_type, _ = _transports(RECORDER_PROFILE)
    assert set(by_type) == {"SHM", "UDPv4"}                 # publishers on other hosts are still recorded
    assert int(by_type["SHM"].findtext("d:port_queue_capacity", namespaces=NS)) >= BACKLOG


def test_the_fast_publisher_profile_lets_a_100_ms_backlog_wait_for_receivers():
    by_type, _ = _transports(FAST_PUBLISHER_PROFILE)
    assert set(by_type) == {"SHM", "UDPv4"}
    # Fast DDS 2.14 gives a segment one buffer per KiB (512 KiB / 512 by default)
    assert int(by_type["SHM"].findtext("d:segment_size", namespaces=NS)) // 1024 >= BACKLOG


def test_the_recorder_applies_its_profile_only_when_no_transport_was_chosen(tmp_path):
    assert transport_env({}, cwd=tmp_path) == {"FASTRTPS_DEFAULT_PROFILES_FILE": str(RECORDER_PROFILE)}
    assert transport_env({"RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}, cwd=tmp_path) != {}
    for key in TRANSPORT_CHOICES:
        assert transport_env({key: "UDPv4"}, cwd=tmp_path) == {}, key
    assert transport_env({"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}, cwd=tmp_path) == {}
    (tmp_path / "DEFAULT_FASTRTPS_PROFILES.xml").write_text("<dds/>")
    assert transport_env({}, cwd=tmp_path) == {}
    with pytest.raises(FileNotFoundError, match="absent.xml"):
        transport_env({}, cwd=tmp_path / "x", profile=tmp_path / "absent.xml")


_SHM_FILES = """
import os, rclpy
rclpy.init()
node = rclpy.create_node("profile_probe")
files = {line.split()[-1] for line in open("/proc/self/maps") if "/dev/shm/fastrtps_" in line}
print({os.path.basename(f): os.path.getsize(f) for f in files if not f.endswith(("_el", "_sl", "_mutex"))})
node.destroy_node()
rclpy.shutdown()
"""


def _shm_files(env: dict) -> dict[str, int]:
    """The Fast DDS shared-memory files a fresh rclpy node maps, with their sizes [bytes]."""
    full = {k: v for k, v in os.environ.items() if k not in TRANSPORT_CHOICES} | env
    r = subprocess.run([sys.executable, "-c", _SHM_FILES], env=full, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return ast.literal_eval(r.stdout.strip().splitlines()[-1])     # the dict the probe printed


@pytest.mark.ros
def test_fast_dds_reads_both_profiles():
    """Fast DDS 2.14 reads FASTRTPS_DEFAULT_PROFILES_FILE (not FASTDDS_...): the port the node listens on and
    its own segment are as large as the profiles ask, compared with a node on Fast DDS' defaults.

    Each probe runs on a domain of its own: Fast DDS sizes a port only when it creates it, and in a full
    test run the session's domain has ports that earlier participants' peers still hold open (with the
    default 512 descriptors), which a new participant with the same id reuses."""
    from domain_coordinator import domain_id

    def probe(env: dict) -> tuple[dict[str, int], set[str]]:
        """The files the probe maps, and which of its ports existed before it ran (Fast DDS reuses an existing
        port file, e.g. one a killed process left in /dev/shm, without resizing it)."""
        before = set(os.listdir("/dev/shm")) if os.path.isdir("/dev/shm") else set()
        with domain_id() as did:
            files = _shm_files({"ROS_DOMAIN_ID": str(did), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", **env})
        return files, {k for k in files if k.startswith("fastrtps_port") and k in before}

    default, _ = probe({})
    rec, rec_reused = probe({"FASTRTPS_DEFAULT_PROFILES_FILE": str(RECORDER_PROFILE)})
    pub, _ = probe({"FASTRTPS_DEFAULT_PROFILES_FILE": str(FAST_PUBLISHER_PROFILE)})

    def largest(files: dict, port: bool) -> int:
        return max(v for k, v in files.items() if k.startswith("fastrtps_port") == port)

    by_type, _ = _transports(RECORDER_PROFILE)
    extra = int(by_type["SHM"].findtext("d:port_queue_capacity", namespaces=NS)) - 512
    # the recorder profile is read: its own segment is the profile's, larger than the default one
    assert largest(rec, port=False) >= int(by_type["SHM"].findtext("d:segment_size", namespaces=NS)) > \
        largest(default, port=False), (default, rec)
    # every descriptor slot of a port holds at least a 16-byte segment id (only a port the probe created)
    fresh = {k: v for k, v in rec.items() if k.startswith("fastrtps_port") and k not in rec_reused}
    if fresh:
        assert max(fresh.values()) - largest(default, port=True) >= 16 * extra, (default, rec, rec_reused)
    by_type, _ = _transports(FAST_PUBLISHER_PROFILE)
    assert largest(pub, port=False) >= int(by_type["SHM"].findtext("d:segment_size", namespaces=NS)) > \
        largest(default, port=False), (default, pub)
