"""Lab recording replayed into the live pipeline: CSV -> convert -> bag -> play -> mocap_ingest (topics) -> recorder.

Separate processes over DDS. The recorded MocapFrames must equal the Motive CSV: every frame, the
capture stamps (start + frame / rate), the poses bit for bit (float64 all the way) and the gaps.

Tolerances: float64 all the way, so the quaternions compare to 1e-15 (an exact copy).
"""
from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.core.mocap.capture_time import capture_start_ns
from euc_ros.ros.launcher import Launcher, NodeSpec

pytestmark = [pytest.mark.ros, pytest.mark.integration, pytest.mark.slow]
CONFIG = Path(__file__).resolve().parents[2] / "config"


def test_csv_bag_play_ingest_record(ros_domain, short_ride, tmp_path):
    ride_dir, _ = short_ride
    csv = ride_dir / "deceleration_01.csv"
    series = read_motive_csv(csv, world_up="y")
    lab_bag, out_bag = tmp_path / "lab_bag", tmp_path / "pipeline_bag"
    assert main(["convert", str(csv), str(lab_bag)]) == 0

    log = io.StringIO()
    specs = [
        NodeSpec("recorder", params_file=str(CONFIG / "recorder.yaml"),
                 parameters={"output": str(out_bag), "topics": ["/mocap/frame"]}, required=False),
        NodeSpec("mocap_ingest", params_file=str(CONFIG / "mocap_ingest.yaml"),
                 # sync_timeout: a loaded CI host can stall the player by ~0.3 s
                 # reliable input (the player publishes reliable): no pose may be lost, however loaded the host
                 parameters={"source": "topics", "bodies": list(series.bodies), "sync_timeout": 1.0,
                             "input_reliability": "reliable"}),
    ]
    with Launcher(specs, stream=log) as launcher:
        # the recorder's subscription must have matched mocap_ingest's publisher before the first pose
        assert launcher.wait(timeout=30, until=lambda: "matched /mocap/frame: 1 publisher" in log.getvalue()), \
            log.getvalue()
        exe = Path(sys.executable).parent / "euc-ros"
        played = subprocess.run([str(exe), "play", str(lab_bag), "--wait-timeout", "20", "--realtime"],
                                capture_output=True, text=True, timeout=60)
        assert played.returncode == 0, played.stdout + played.stderr
        launcher.wait(timeout=4.0)                      # the last partial frames leave after sync_timeout
    assert launcher.exit_codes["recorder"] == 0, log.getvalue()
    assert check_bag(out_bag) == []

    frames = [m for _, _, _, m in read_bag(out_bag, topics=["/mocap/frame"])]
    keep = series.tracked.any(axis=0)                   # frames with no tracked body leave no PoseStamped
    n = int(keep.sum())
    print(f"{len(frames)} of {n} frames of {len(series.bodies)} bodies recorded; {played.stdout.strip()}")
    assert len(frames) == n, log.getvalue()
    start = capture_start_ns(series.meta["start_time"])
    stamps = np.array([f.header.stamp.sec * 10**9 + f.header.stamp.nanosec for f in frames])
    np.testing.assert_array_equal(stamps, start + np.round(series.t[keep] * 1e9).astype(np.int64))
    assert {f.stamp_source for f in frames} == {3} and list(frames[0].body_names) == series.bodies
    tracked = np.array([f.tracked for f in frames]).T
    np.testing.assert_array_equal(tracked, series.tracked[:, keep])   # no pose lost on the way
    pos = np.array([[[p.position.x, p.position.y, p.position.z] for p in f.poses] for f in frames])
    quat = np.array([[[p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w] for p in f.poses]
                     for f in frames])
    np.testing.assert_allclose(pos.transpose(1, 0, 2), series.position[:, keep], atol=0, equal_nan=True)
    np.testing.assert_allclose(quat.transpose(1, 0, 2), series.quat[:, keep], atol=1e-15, equal_nan=True)
