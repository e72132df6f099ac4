"""The pipeline split across two hosts: two network namespaces joined by a veth pair (docs/distributed.md).

Host A (10.77.0.1) runs ``mocap_ingest``; host B (10.77.0.2) runs ``rider_state``,
``torque_estimator`` and ``recorder``. Discovery is confined to each host
(``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) and crosses only through the other host's address in
``ROS_STATIC_PEERS``, as it must where multicast does not reach the other machine. Fast DDS is
limited to UDPv4 (``FASTDDS_BUILTIN_TRANSPORTS``): its shared-memory transport would otherwise see
the other namespace through the common ``/dev/shm`` and bypass the network.

Needs root or CAP_NET_ADMIN (``ip netns add``); skipped with the reason otherwise.
"""
from __future__ import annotations

import io
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.ros.launcher import Launcher, NodeSpec
from euc_ros.testing import wait_for

pytestmark = [pytest.mark.ros, pytest.mark.integration, pytest.mark.slow]

ADDR_A, ADDR_B = "10.77.0.1", "10.77.0.2"
BIN = Path(sys.executable).parent


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run([IP, *args], capture_output=True, text=True, timeout=20, check=check)


IP = shutil.which("ip") or "/usr/sbin/ip"


@pytest.fixture
def two_hosts():
    """Two namespaces A and B joined by a veth pair (10.77.0.1/24 - 10.77.0.2/24); removed afterwards."""
    if not Path(IP).exists():
        pytest.skip("the 'ip' tool (iproute2) is not installed")
    tag = f"{os.getpid() % 100000}"
    ns = {"A": f"euc_a{tag}", "B": f"euc_b{tag}"}
    dev = {"A": f"euca{tag}", "B": f"eucb{tag}"}
    made = []
    try:
        for host in ("A", "B"):
            r = _ip("netns", "add", ns[host], check=False)
            if r.returncode != 0:
                pytest.skip(f"cannot create a network namespace ('ip netns add' needs root or CAP_NET_ADMIN): "
                            f"{r.stderr.strip()}")
            made.append(ns[host])
        _ip("link", "add", dev["A"], "type", "veth", "peer", "name", dev["B"])
        for host, addr in (("A", ADDR_A), ("B", ADDR_B)):
            _ip("link", "set", dev[host], "netns", ns[host])
            _ip("-n", ns[host], "addr", "add", f"{addr}/24", "dev", dev[host])
            _ip("-n", ns[host], "link", "set", dev[host], "up")
            _ip("-n", ns[host], "link", "set", "lo", "up")
        yield ns, dev
    finally:
        for name in made:
            _ip("netns", "del", name, check=False)   # also removes the veth pair


def _host_env(ros_domain: int, peer: str | None) -> dict:
    env = {"ROS_DOMAIN_ID": str(ros_domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}
    env["ROS_STATIC_PEERS"] = peer or ""
    return env


def _on(ns: str, executable: str, env: dict, **kwargs) -> NodeSpec:
    """A node run inside namespace ``ns`` (``ip netns exec NS /venv/bin/NODE --ros-args ...``)."""
    return NodeSpec(IP, name=kwargs.pop("name", executable), args=["netns", "exec", ns, str(BIN / executable)],
                    env=env, **kwargs)


def _tx_bytes(ns: str, dev: str) -> int:
    info = json.loads(_ip("-n", ns, "-s", "-j", "link", "show", "dev", dev).stdout)
    return int(info[0]["stats64"]["tx"]["bytes"])


def test_pipeline_across_two_hosts_with_static_peers(ros_domain, two_hosts, short_ride, tmp_path):
    ns, dev = two_hosts
    ride_dir, _ = short_ride
    csv, session = ride_dir / "deceleration_01.csv", ride_dir / "session.yaml"
    bag = tmp_path / "bag"
    env_a, env_b = _host_env(ros_domain, ADDR_B), _host_env(ros_domain, ADDR_A)
    tx0 = _tx_bytes(ns["A"], dev["A"])
    specs = [
        _on(ns["B"], "recorder", env_b, parameters={"output": str(bag)}, required=False),
        _on(ns["B"], "torque_estimator", env_b, parameters={"session_file": str(session)}, required=False),
        _on(ns["B"], "rider_state", env_b, parameters={"session_file": str(session)}, required=False),
        _on(ns["A"], "mocap_ingest", env_a,
            parameters={"csv_path": str(csv), "exit_when_done": True, "rate_factor": 1.0, "wait_subscribers": 2,
                        "start_delay": 4.0, "linger": 2.0}),  # torque_estimator (not awaited) must be up too
    ]
    log = io.StringIO()
    with Launcher(specs, stream=log) as launcher:
        assert launcher.wait(timeout=50), "the replay did not finish in 50 s:\n" + log.getvalue()
    assert launcher.exit_codes["mocap_ingest"] == 0, log.getvalue()
    assert all(code == 0 for code in launcher.exit_codes.values()), (launcher.exit_codes, log.getvalue())

    assert check_bag(bag) == []
    series = read_motive_csv(csv, world_up="y")
    counts: dict[str, int] = {}
    numbers, torques = [], []
    for topic, _, _, msg in read_bag(bag, topics=["/mocap/frame", "/rider/state", "/euc/torque"]):
        counts[topic] = counts.get(topic, 0) + 1
        if topic == "/mocap/frame":
            numbers.append(msg.frame_number)
        elif topic == "/euc/torque":
            torques.append(msg.m_d1)
    # every frame crossed from host A to the recorder on host B, in order
    np.testing.assert_array_equal(numbers, series.frame)
    # the estimators on B ran on the frames from A: one state per frame past the filter warm-up, one torque each
    assert counts.get("/rider/state", 0) > series.n_frames // 3, counts
    assert counts.get("/euc/torque", 0) == counts["/rider/state"], counts
    assert np.all(np.isfinite(torques))
    # the frames went over the veth link (at least their CDR size), not through shared memory
    frame_bytes = len(numbers) * 14 * 7 * 8   # the poses alone: 14 bodies x 7 float64 per frame
    assert _tx_bytes(ns["A"], dev["A"]) - tx0 > frame_bytes


def test_without_static_peers_the_hosts_do_not_discover_each_other(ros_domain, two_hosts, short_ride, tmp_path):
    """The control: the same set-up without ROS_STATIC_PEERS never matches (so the peers did the work above)."""
    ns, _ = two_hosts
    ride_dir, _ = short_ride
    log = io.StringIO()
    recorder = _on(ns["B"], "recorder", _host_env(ros_domain, None), parameters={"output": str(tmp_path / "bag")},
                   required=False)
    ingest = _on(ns["A"], "mocap_ingest", _host_env(ros_domain, None),
                 parameters={"csv_path": str(ride_dir / "deceleration_01.csv"), "exit_when_done": True,
                             "wait_subscribers": 1, "start_delay": 0.2})
    with Launcher([recorder], stream=log) as rec_launcher:
        assert wait_for(lambda: "recording to" in log.getvalue(), 30.0), log.getvalue()
        with Launcher([ingest], stream=log) as ingest_launcher:
            assert wait_for(lambda: "waiting for mocap/frame subscriptions 0/1" in log.getvalue(), 30.0), log.getvalue()
            # a static-peer match takes well under a second once both run; give it 6 s
            matched = ingest_launcher.wait(timeout=6.0, until=lambda: "replay finished" in log.getvalue())
            assert not matched and "mocap_ingest" not in ingest_launcher.exit_codes, log.getvalue()
    assert rec_launcher.exit_codes["recorder"] == 0
    assert sum(1 for _ in read_bag(tmp_path / "bag", topics=["/mocap/frame"])) == 0
