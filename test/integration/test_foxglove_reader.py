"""A bag the recorder node wrote, read by Foxglove's own TypeScript libraries.

tools/foxglove_reader/read_bag.mjs opens the .mcap with @mcap/core's indexed reader and decodes every
message with @foxglove/rosmsg2-serialization from the schema embedded in the file, as Foxglove Studio
and Lichtblick do. Checked: every message decodes; the schema accounts for every byte but CDR's end
padding (< 4 bytes); per-topic counts equal the MCAP summary and metadata.yaml; decoded torques and
states equal what rosbags decodes from the same bytes (doubles travel as shortest round-trip decimal in
JSON: equal, not close).

Needs node and npm (Node 20): skipped with the reason where they are absent or the npm registry
cannot be reached. The npm packages are pinned (package-lock.json) and installed with ``npm ci`` into
a cache outside the repository, keyed by the lock file's hash.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from euc_ros.core.io.bags import read_bag

pytestmark = [pytest.mark.ros, pytest.mark.integration, pytest.mark.slow]
REPO = Path(__file__).resolve().parents[2]
TOOL = REPO / "tools" / "foxglove_reader"


@pytest.fixture(scope="module")
def reader_dir(npm_tool):
    return npm_tool(TOOL, "@mcap/core", "read_bag.mjs", "Foxglove's TypeScript MCAP reader")


@pytest.fixture(scope="module")
def recorded_bag(tmp_path_factory, ros_domain_module):
    """The live pipeline (four nodes and the recorder, each its own process) on a 6 s ride."""
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    out = tmp_path_factory.mktemp("fox")
    write_ride(simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=11, duration_s=6.0)), out / "ride")
    bag = out / "bag"
    r = subprocess.run([sys.executable, "-m", "euc_ros.cli.main", "launch", "pipeline.launch.xml",
                        f"session:={out / 'ride' / 'session.yaml'}", "h:=0.61", "source:=csv",
                        f"csv_path:={out / 'ride' / 'deceleration_01.csv'}", "exit_when_done:=true", f"bag:={bag}"],
                       capture_output=True, text=True, timeout=180)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return bag


@pytest.fixture(scope="module")
def ros_domain_module():
    from domain_coordinator import domain_id

    from euc_ros.bench.common import environ

    with domain_id() as did, environ({"ROS_DOMAIN_ID": did, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}):
        yield did


def same(a, b) -> bool:
    """Equal doubles; NaN (JSON null from JavaScript) equals NaN."""
    if a is None:
        return isinstance(b, float) and math.isnan(b)
    return a == b


def test_every_message_decodes_with_foxgloves_reader(reader_dir, recorded_bag):
    mcap = next(recorded_bag.glob("*.mcap"))
    r = subprocess.run(["node", str(reader_dir / "read_bag.mjs"), str(mcap), "/euc/torque", "/rider/state"],
                       cwd=reader_dir, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout)
    assert out["failures"] == 0 and out["problems"] == [], out["problems"]
    assert all(left < 4 for left in out["trailing"].values()), out["trailing"]   # only CDR end padding
    meta = yaml.safe_load((recorded_bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    want = {t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]}
    assert {"/mocap/frame", "/rider/state", "/euc/torque", "/diagnostics", "/tf"} <= set(out["counts"])
    assert out["counts"] == {k: v for k, v in want.items() if v}
    assert {k: int(v) for k, v in out["statistics"]["channelMessageCounts"].items()} == out["counts"]
    assert int(out["statistics"]["messageCount"]) == meta["message_count"]

    ours = {"/euc/torque": [], "/rider/state": []}
    for topic, _, _, msg in read_bag(recorded_bag, topics=list(ours)):
        ours[topic].append(msg)
    fields = {"/euc/torque": ("valid", "m_d1", "m_d2", "residual", "rmse_window", "h", "h_online", "model",
                              "h_online_status"),
              "/rider/state": ("x_dot", "gamma", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "phi_definition")}
    for topic, names in fields.items():
        theirs = out["messages"][topic]
        assert len(theirs) == len(ours[topic]) > 0
        for a, b in zip(theirs, ours[topic]):
            assert (a["header"]["stamp"]["sec"], a["header"]["stamp"]["nanosec"]) == (b.header.stamp.sec,
                                                                                      b.header.stamp.nanosec)
            for name in names:
                assert same(a[name], getattr(b, name)), (topic, name, a[name], getattr(b, name))
