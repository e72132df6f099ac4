"""The packaged launch files run for real through `euc-ros launch`.

pipeline.launch.xml (CSV source, recorder on) records a ride; replay.launch.xml plays that bag's mocap
frames back through rider_state and torque_estimator into a second bag; unicycle.launch.xml runs the
closed loop. Separate processes over DDS, real bags.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.core.io.motive_csv import read_motive_csv

pytestmark = [pytest.mark.ros, pytest.mark.integration, pytest.mark.slow]
REPO = Path(__file__).resolve().parents[2]
LAUNCH = REPO / "launch"


def _metadata_check():
    import importlib.util

    path = REPO / "test" / "unit" / "core" / "io" / "test_rosbag2_metadata.py"
    spec = importlib.util.spec_from_file_location("rosbag2_metadata_check", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.assert_like_rosbag2_jazzy


def euc_ros(*args, timeout=150):
    return subprocess.run([sys.executable, "-m", "euc_ros.cli.main", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


def topic_counts(bag: Path) -> dict[str, int]:
    counts: dict[str, int] = {}
    first: dict[str, float] = {}
    last: dict[str, float] = {}
    for topic, _, _, msg in read_bag(bag):
        counts[topic] = counts.get(topic, 0) + 1
        if hasattr(msg, "header"):
            t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            first.setdefault(topic, t)
            last[topic] = t
    counts["_span"] = {k: (round(first[k] - first["/mocap/frame"], 3), round(last[k] - first["/mocap/frame"], 3))
                       for k in first if "/mocap/frame" in first}
    return counts


@pytest.fixture(scope="module")
def ride(tmp_path_factory):
    """An 8 s deceleration ride: long enough for the state and torque filters' windows (1.2 s each)."""
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    out = tmp_path_factory.mktemp("ride")
    write_ride(simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=5, duration_s=8.0)), out)
    return out


def test_pipeline_then_replay_launch_files(ros_domain, ride, tmp_path):
    ride_dir = ride
    csv = ride_dir / "deceleration_01.csv"
    session = ride_dir / "session.yaml"
    first = tmp_path / "first"
    # start_delay 6 s: the five processes discover each other before the first frame even on a host whose
    # other core runs the rest of the suite
    r = euc_ros("launch", LAUNCH / "pipeline.launch.xml", f"session:={session}", "h:=0.61", "source:=csv",
                f"csv_path:={csv}", "exit_when_done:=true", f"bag:={first}", "start_delay:=6.0")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert check_bag(first) == []
    _metadata_check()(first / "metadata.yaml")      # the recorder node's bag is laid out as rosbag2's
    meta = yaml.safe_load((first / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    offered = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
               for t in meta["topics_with_message_count"]}
    assert offered["/mocap/frame"] and all(q["reliability"] == "reliable" for q in offered["/mocap/frame"])
    # diagnostics as diagnostic_updater publishes them: "<node>: <check>", a hardware_id, key/values
    seen = set()
    for topic, _, _, msg in read_bag(first):
        for st in msg.status if topic == "/diagnostics" else ():
            node, sep, check = st.name.partition(": ")
            assert sep and node in {"mocap_ingest", "rider_state", "torque_estimator", "monitor"} and check, st.name
            assert st.hardware_id and st.values, (st.name, st.hardware_id)
            seen.add(node)
    assert seen == {"mocap_ingest", "rider_state", "torque_estimator", "monitor"}
    counts = topic_counts(first)
    frames = counts.get("/mocap/frame", 0)
    assert frames == len(read_motive_csv(csv).t), counts
    # States lose one 1.2 s filter window (144 frames), torques up to two; the ingest waits start_delay
    # so that the five processes have discovered each other before the first frame.
    # 2: the last ones may race the shutdown; 12 (0.1 s): the first states rider_state publishes (volatile) can
    # precede the recorder's match of its writer on a loaded host (a clean-clone run lost 6 at the start)
    assert counts["/rider/state"] >= frames - 144 - 12, counts["_span"]
    assert counts["/euc/torque"] >= frames - 288 - 4, counts

    second = tmp_path / "second"
    r = euc_ros("launch", "replay.launch.xml", f"in_bag:={first}", f"session:={session}", "h:=0.61",
                f"bag:={second}")     # a bare name: the package's launch directory
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert check_bag(second) == []
    again = topic_counts(second)
    assert again["/mocap/frame"] == frames, r.stdout[-4000:]   # every replayed frame recomputed
    assert again["/euc/torque"] >= frames - 288 - 4, (again["/euc/torque"], again["_span"])

    def torques(bag):
        return {(m.header.stamp.sec, m.header.stamp.nanosec): m.m_d1 for t, _, _, m in read_bag(bag)
                if t == "/euc/torque" and m.valid}

    a, b = torques(first), torques(second)
    common = sorted(set(a) & set(b))
    assert len(common) >= frames - 288 - 4
    # the same frames through the same estimator: the same torques (float64 arithmetic, same order)
    np.testing.assert_allclose([a[k] for k in common], [b[k] for k in common], rtol=0, atol=1e-9)


def test_unicycle_launch_file_records_the_closed_loop(ros_domain, tmp_path):
    bag = tmp_path / "loop"
    r = euc_ros("launch", "euc_ros", "unicycle.launch.xml", "maneuver:=turn", "duration:=2", f"bag:={bag}")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert check_bag(bag) == []
    counts = topic_counts(bag)
    assert counts["/unicycle/state"] >= 200 and counts["/unicycle/command"] >= 200, counts
