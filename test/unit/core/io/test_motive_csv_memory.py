"""Peak memory of ``read_motive_csv``: the result plus a bounded working set, never a
multiple of the file.

The reader runs in a fresh interpreter on a generated export (10 000 frames x 14 bodies, 10 % of the
body-frames occluded, about 10 MB: the slower path that fills blank cells). Its peak RSS increase
over the interpreter's (:func:`euc_ros.bench.common.peak_rss_increase`) must stay within

    1.5 x (bytes of the returned arrays) + CHUNKS x the reader's chunk size + SLACK_MB

* 1.5 x the result: the target is 1.5x numpy's loader, and numpy's loader itself needs
  about 1.15x its array (it grows the array as it reads);
* CHUNKS chunks (a file of under 32 MB is read in 32 chunks, so a chunk is ~0.3 MB here): the working
  set of one chunk is its text (the piece read, the piece joined to the
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

from euc_ros.core.errors import InputError
from euc_ros.core.io import motive_csv
from euc_ros.core.io.motive_csv import block as motive_block
from euc_ros.core.io.motive_csv import write_motive_csv
from euc_ros.core.mocap.series import MocapSeries

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
    chunk = min(motive_block._CHUNK_BYTES, max(motive_block._CHUNK_BYTES_MIN,
                                               path.stat().st_size // motive_block._CHUNKS_AT_LEAST))
    assert chunk < motive_block._CHUNK_BYTES      # a file of this size is read in smaller chunks
    bound = 1.5 * out["result_mb"] + CHUNKS * chunk / 2**20 + SLACK_MB
    assert increase <= bound, (f"read_motive_csv raised the RSS by {increase:.1f} MB on a {file_mb:.1f} MB file "
                               f"(result {out['result_mb']:.1f} MB); bound {bound:.1f} MB; {out['rss']}")


def _small_export(tmp_path, n=300):
    g = np.random.default_rng(3)
    q = g.normal(size=(3, n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    s = MocapSeries(t=np.arange(n) / 120.0, frame=np.arange(n), bodies=["E", "H", "T L"],
                    position=g.normal(size=(3, n, 3)), quat=q, tracked=g.random((3, n)) > 0.2,
                    mean_marker_error=g.random((3, n)) * 1e-3, name="chunks", meta={})
    data = write_motive_csv(s, tmp_path / "src.csv", decimals=6).read_bytes()
    head, rows = data.split(b"\nFrame,", 1)
    head += b"\nFrame," + rows.split(b"\n", 1)[0] + b"\n"
    return head, rows.split(b"\n", 1)[1].rstrip(b"\n").split(b"\n")


def _read_with_chunks(path, chunk_bytes, monkeypatch):
    monkeypatch.setattr(motive_block, "_CHUNK_BYTES", chunk_bytes)
    monkeypatch.setattr(motive_block, "_CHUNKS_AT_LEAST", 1)   # chunks of exactly chunk_bytes
    try:
        return motive_csv.read_motive_csv(path)
    except InputError as exc:
        return str(exc)


@pytest.mark.parametrize("edit", ["clean_crlf_duplicates", "bad_cells", "short_row_after_bad_cell", "quoted_cell"])
def test_result_and_errors_do_not_depend_on_the_chunk_size(tmp_path, monkeypatch, edit):
    head, rows = _small_export(tmp_path)
    sep = b"\n"
    if edit == "clean_crlf_duplicates":
        rows = rows[:100] + rows[90:]
        sep = b"\r\n"
    elif edit == "bad_cells":  # numpy's parser takes '\x1c1' for 1, the exact scan does not: a block-wide choice
        rows[40] = rows[40].replace(b",", b",\x1c", 1)
        rows[250] = rows[250].replace(b",", b",abc", 1)
    elif edit == "short_row_after_bad_cell":  # a short row is reported first wherever it is
        rows[20] = rows[20].replace(b",", b",abc", 1)
        rows[280] = rows[280].rsplit(b",", 3)[0]
    else:
        rows[150] = rows[150].replace(b",", b',"1",', 1)
    path = tmp_path / "take.csv"
    path.write_bytes(head.replace(b"\n", sep) + sep.join(rows) + sep)
    reference = _read_with_chunks(path, 1 << 30, monkeypatch)  # the whole block in one chunk
    for chunk_bytes in (1, 97, 4096, 20_000):
        got = _read_with_chunks(path, chunk_bytes, monkeypatch)
        if isinstance(reference, str):
            assert got == reference
        else:
            for f in ("t", "frame", "position", "quat", "tracked", "mean_marker_error"):
                np.testing.assert_array_equal(getattr(got, f), getattr(reference, f))
            assert got.meta == reference.meta
    if edit == "bad_cells":
        assert "line" in reference and "non-numeric cell" in reference
