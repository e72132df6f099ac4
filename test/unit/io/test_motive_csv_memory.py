"""Peak memory of ``read_motive_csv`` (issue 15): the result plus a bounded working set, never a
multiple of the file.

The reader runs in a fresh interpreter on a generated export (10 000 frames x 14 bodies, 10 % of the
body-frames occluded, about 10 MB: the slower path that fills blank cells). Its peak RSS increase
over the interpreter's (:func:`euc_ros.bench.common.peak_rss_increase`) must stay within

    1.5 x (bytes of the returned arrays) + CHUNKS x the reader's chunk size + SLACK_MB

* 1.5 x the result: the target of issue 15 is 1.5x numpy's loader, and numpy's loader itself needs
  about 1.15x its array (it grows the array as it reads);
* CHUNKS chunks: the working set of one chunk is its text (the piece read, the piece joined to the
  previous row's tail, the rows cut out of it), numpy's reader's own copy of it (4 bytes a
  character), the blank-filling masks and the nan-filled copy, the chunk's float matrix and its
  per-body temporaries: 10 to 12 chunk sizes measured, 16 allowed;
* SLACK_MB: allocator slack (freed chunks kept by malloc, page granularity, numpy's first-call
  caches), 8 MB.

Measured (2 shared cores, numpy 2.4): the reader 19-21 MB for an 8.8 MB result, bound 37 MB; the
previous reader, which held the whole file, its nan-filled copy and the matrix of all cells, 94 MB
(10x the 9.3 MB file). No timing is asserted.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from euc_ros.core.io import motive_csv
from euc_ros.core.io.motive_csv import write_motive_csv
from euc_ros.core.mocap import MocapSeries

CHUNKS = 16
SLACK_MB = 8.0
N_FRAMES, N_BODIES = 10_000, 14

_MEASURE = """
import json, sys
from euc_ros.bench.common import peak_rss_increase
from euc_ros.core.io.motive_csv import read_motive_csv
with peak_rss_increase() as rss:
    s = read_motive_csv(sys.argv[1], world_up="y")
arrays = (s.t, s.frame, s.position, s.quat, s.tracked, s.mean_marker_error)
print(json.dumps({"rss": rss, "result_mb": sum(a.nbytes for a in arrays) / 2**20, "frames": s.n_frames}))
"""


def _occluded_export(path):
    g = np.random.default_rng(15)
    n, b = N_FRAMES, N_BODIES
    q = g.normal(size=(b, n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    s = MocapSeries(t=np.arange(n) / 120.0, frame=np.arange(n), bodies=[f"B{k}" for k in range(b)],
                    position=g.normal(size=(b, n, 3)), quat=q, tracked=g.random((b, n)) > 0.1,
                    mean_marker_error=g.random((b, n)) * 1e-3, name="memory", meta={})
    return write_motive_csv(s, path, decimals=6)


@pytest.mark.skipif(not os.path.exists("/proc/self/status"), reason="needs /proc/<pid>/status (Linux)")
def test_peak_memory_is_the_result_plus_a_bounded_working_set(tmp_path):
    path = _occluded_export(tmp_path / "take.csv")
    file_mb = path.stat().st_size / 2**20
    proc = subprocess.run([sys.executable, "-c", _MEASURE, str(path)], capture_output=True, text=True, timeout=170)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["frames"] == N_FRAMES
    increase = out["rss"]["increase_mb"]
    if increase is None:
        pytest.skip("no VmRSS/VmHWM in /proc/self/status")
    bound = 1.5 * out["result_mb"] + CHUNKS * motive_csv._CHUNK_BYTES / 2**20 + SLACK_MB
    assert increase <= bound, (f"read_motive_csv raised the RSS by {increase:.1f} MB on a {file_mb:.1f} MB file "
                               f"(result {out['result_mb']:.1f} MB); bound {bound:.1f} MB; {out['rss']}")
