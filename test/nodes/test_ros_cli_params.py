"""Parameters as the ROS command line spells them: `-p world_up:=y` works.

rcl reads a bare `y` as the YAML 1.1 boolean true; the node maps it back to the choice it spelt
instead of exiting 2. A real node process, started the way a lab starts it.
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

pytestmark = [pytest.mark.ros, pytest.mark.integration]


@pytest.fixture(scope="module")
def csv(tmp_path_factory):
    from euc_ros.cli.main import main

    d = tmp_path_factory.mktemp("cli") / "ride"
    assert main(["simulate-ride", "--runs", "1", "--duration", "2", "--out", str(d), "--no-progress"]) == 0
    return d / "deceleration_01.csv"


def _run(csv, up, ros_domain):
    import os

    exe = Path(sys.executable).parent / "mocap_ingest"
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain))
    p = subprocess.Popen([str(exe), "--ros-args", "-p", "source:=csv", "-p", f"csv_path:={csv}", "-p",
                          f"world_up:={up}", "-p", "rate_factor:=5.0"], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, env=env)
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and p.poll() is None:
        time.sleep(0.1)
        if time.monotonic() > deadline - 17:   # ~3 s: long enough to have parsed every parameter
            break
    if p.poll() is None:
        p.terminate()
    out, _ = p.communicate(timeout=20)
    return p.returncode, out


@pytest.mark.parametrize("up", ["y", "z"])
def test_world_up_from_the_ros_command_line(csv, up, ros_domain):
    rc, out = _run(csv, up, ros_domain)
    assert rc != 2 and "replaying" in out, out


def test_a_value_outside_the_choices_is_refused_with_the_reason(csv, ros_domain):
    rc, out = _run(csv, "n", ros_domain)
    assert rc == 2 and "world_up" in out and "read as a boolean" in out, out
