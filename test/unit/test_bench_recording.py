"""The recording benchmark's loss report: which frames of which topic a lossy step lost."""
from __future__ import annotations

import numpy as np

from euc_ros.bench.recording import lost_frames
from euc_ros.core.io.bags import BagWriter, posestamped_cdr


def test_lost_frames_names_the_missing_runs_of_each_topic(tmp_path):
    n = 50
    stamps = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 2_000_000      # a frame every 2 ms
    pos, quat = np.zeros((n, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
    raws = posestamped_cdr(stamps, pos, quat)
    keep = {"/a": np.ones(n, bool), "/b": np.ones(n, bool), "/c": np.ones(n, bool)}
    keep["/b"][[3, 4, 5, 20]] = False          # two runs on /b
    keep["/c"][0] = False                      # the first frame on /c: seen on /a (same publisher)
    with BagWriter(tmp_path / "bag") as w:
        for topic, k in keep.items():
            w.write_raw_many(topic, "geometry_msgs/msg/PoseStamped", [r for r, ok in zip(raws, k) if ok],
                             [int(s) for s, ok in zip(stamps, k) if ok])
    where = lost_frames(tmp_path / "bag", [["/a", "/b", "/c"]])
    assert set(where) == {"/b", "/c"}
    assert where["/b"]["runs"] == [[3, 5, 3], [20, 20, 1]] and where["/b"]["first_ms"] == 6.0
    assert where["/c"]["runs"] == [[0, 0, 1]] and where["/c"]["first_ms"] == 0.0
    assert where["/b"]["frames_seen"] == n
