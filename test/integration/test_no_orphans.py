"""No node outlives ``euc-ros launch`` or ``euc-ros record``, however the parent ends.

A closed terminal (SIGHUP, with the launcher's output gone) stops the launch in order; SIGKILL gives
the launcher no chance to act, and the children's parent-death signal (SIGTERM) ends them. In both
cases no child may be left after 5 s, and the recorder must have closed its bag with its metadata
(a SIGTERM is a clean stop for every node).
"""
from __future__ import annotations

import io
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.ros.launcher import Launcher, NodeSpec

pytestmark = [pytest.mark.ros, pytest.mark.integration]
REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config"
EUC_ROS = str(Path(sys.executable).parent / "euc-ros")
NODE_NAMES = ("recorder", "mocap_ingest")
GONE_WITHIN_S = 5.0


def _nodes_of(pid: int) -> list[psutil.Process]:
    try:
        kids = psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []
    out = []
    for k in kids:
        try:
            if any(n in " ".join(k.cmdline()) for n in NODE_NAMES):
                out.append(k)
        except psutil.NoSuchProcess:
            pass
    return out


def _wait_for(cond, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


#: What the recorder says once its subscription has matched the frames' publisher: frames from then on
#: are recorded.
MATCHED = b"matched /mocap/frame: 1 publisher"


def _wait_for_output(proc: subprocess.Popen, needle: bytes, timeout_s: float) -> None:
    """Read the process' output (without a thread: the SIGHUP case closes it) until ``needle`` appears."""
    fd, seen, deadline = proc.stdout.fileno(), b"", time.monotonic() + timeout_s
    while needle not in seen:
        left = deadline - time.monotonic()
        if left <= 0 or proc.poll() is not None:
            raise AssertionError(f"{needle!r} not in the output:\n{seen.decode(errors='replace')[-3000:]}")
        if select.select([fd], [], [], min(left, 0.2))[0]:
            seen += os.read(fd, 1 << 16)


def _frames_in(bag: Path) -> int:
    return sum(1 for _ in read_bag(bag, topics=["/mocap/frame"]))


def _end_parent(proc: subprocess.Popen, how: str) -> None:
    if how == "SIGHUP":        # a closed terminal: the output goes nowhere, then the hang-up
        proc.stdout.close()
        proc.send_signal(signal.SIGHUP)
    else:
        proc.kill()
    proc.wait(timeout=30)


def _assert_no_orphans_and_bag_reads(kids: list[psutil.Process], bag: Path) -> None:
    _, alive = psutil.wait_procs(kids, timeout=GONE_WITHIN_S)
    names = [p.pid for p in alive]
    for p in alive:          # do not leak them into the rest of the suite
        p.kill()
    assert not alive, f"children still alive {GONE_WITHIN_S} s after the parent ended: {names}"
    assert check_bag(bag) == [], "the bag was not closed with its metadata"
    assert _frames_in(bag) > 0


def _end_while_recording(cmd: list[str], n_nodes: int, bag: Path, how: str) -> None:
    """Start ``cmd`` (a parent of ``n_nodes`` node processes, one a recorder of ``bag``), end it ``how`` once
    frames are being recorded, and check that no node outlives it and the bag reads."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        _wait_for(lambda: len(_nodes_of(proc.pid)) >= n_nodes and bag.exists(), 30, "the nodes to start")
        kids = _nodes_of(proc.pid)
        _wait_for_output(proc, MATCHED, 60)
        time.sleep(1.0)    # frames flow into the bag
        _end_parent(proc, how)
    finally:
        if proc.poll() is None:
            proc.kill()
    _assert_no_orphans_and_bag_reads(kids, bag)


@pytest.mark.parametrize("how", ["SIGHUP", "SIGKILL"])
def test_launch_leaves_no_orphans(ros_domain, looping_launch, how):
    launch_file, bag = looping_launch
    _end_while_recording([EUC_ROS, "launch", str(launch_file)], 2, bag, how)


@pytest.mark.parametrize("how", ["SIGHUP", "SIGKILL"])
def test_record_leaves_no_orphans(ros_domain, short_ride, tmp_path, how):
    ride_dir, _ = short_ride
    bag = tmp_path / "bag"
    ingest = NodeSpec("mocap_ingest", params_file=str(CONFIG / "mocap_ingest.yaml"),
                      parameters={"csv_path": str(ride_dir / "deceleration_01.csv"), "loop": True,
                                  "start_delay": 0.5, "wait_subscribers": 1})
    with Launcher([ingest], stream=io.StringIO()):
        _end_while_recording([EUC_ROS, "record", str(bag), "mocap/frame"], 1, bag, how)
