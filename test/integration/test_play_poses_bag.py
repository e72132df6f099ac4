"""A bag of per-body poses (the simulator's, vrpn_mocap's) replays as mocap frames: `euc-ros play --topics
mocap/frame` assembles each frame from the poses of one capture stamp, recorded back identical."""
from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.io.bags import check_bag, read_mocap_bag
from euc_ros.ros.launcher import Launcher, NodeSpec

pytestmark = [pytest.mark.ros, pytest.mark.integration]
CONFIG = Path(__file__).resolve().parents[2] / "config"
EUC_ROS = str(Path(sys.executable).parent / "euc-ros")


def test_a_poses_only_bag_replays_as_frames(ros_domain, tmp_path):
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    write_ride(simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=6, duration_s=2.0)), tmp_path / "sim",
               bag=True)
    src = tmp_path / "sim" / "deceleration_01_bag"
    out = tmp_path / "frames"
    recorder = NodeSpec("recorder", params_file=str(CONFIG / "recorder.yaml"),
                        parameters={"output": str(out), "topics": ["mocap/frame"]}, required=False)
    log = io.StringIO()
    with Launcher([recorder], stream=log):
        play = subprocess.run([EUC_ROS, "play", str(src), "--topics", "mocap/frame", "--wait-subscribers", "1",
                               "--delay", "0.5", "--rate", "4"], capture_output=True, text=True, timeout=60)
    assert play.returncode == 0, play.stdout + play.stderr
    assert "frames assembled from its 14 per-body pose topics" in play.stdout
    assert check_bag(out) == [], log.getvalue()
    want, got = read_mocap_bag(src), read_mocap_bag(out)
    assert got.n_frames == want.n_frames and got.bodies == want.bodies
    np.testing.assert_array_equal(got.t, want.t)
    np.testing.assert_array_equal(got.position, want.position)
    np.testing.assert_array_equal(got.quat, want.quat)
