"""Which processes hold a file open, from Linux /proc (euc_ros.core.io.open_files)."""
from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from euc_ros.core.io import open_files
from euc_ros.core.io.open_files import processes_with_open

pytestmark = pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="needs Linux /proc")


def test_a_file_this_process_holds_open_is_seen_only_with_include_self(tmp_path):
    f = tmp_path / "bag.mcap"
    f.write_bytes(b"x")
    me = os.getpid()
    with open(f, "rb"):
        assert me in [pid for pid, _ in processes_with_open(f, include_self=True)]
        assert me not in [pid for pid, _ in processes_with_open(f)]
    assert me not in [pid for pid, _ in processes_with_open(f, include_self=True)]  # closed: gone


def test_a_file_inside_a_directory_counts_and_the_process_is_named(tmp_path):
    d = tmp_path / "bag"
    (d / "sub").mkdir(parents=True)
    f = d / "sub" / "bag_0.db3"
    f.write_bytes(b"x")
    other = tmp_path / "other.txt"
    other.write_bytes(b"y")
    code = "import sys, time; fh = open(sys.argv[1], 'ab'); print('ok', flush=True); time.sleep(30)"
    child = subprocess.Popen([sys.executable, "-c", code, str(f)], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "ok"
        found = dict(processes_with_open(d))
        assert child.pid in found
        with open(f"/proc/{child.pid}/comm") as comm:
            assert found[child.pid] == comm.read().strip()
        assert child.pid not in dict(processes_with_open(other))
    finally:
        child.kill()
        child.wait()
    deadline = time.monotonic() + 2
    while child.pid in dict(processes_with_open(d)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert child.pid not in dict(processes_with_open(d))


def test_without_proc_nothing_is_found(tmp_path, monkeypatch):
    monkeypatch.setattr(open_files, "PROC", tmp_path / "no_proc")
    f = tmp_path / "a"
    f.write_bytes(b"x")
    with open(f, "rb"):
        assert processes_with_open(f, include_self=True) == []
