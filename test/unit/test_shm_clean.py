"""Stale Fast DDS shared-memory files (euc_ros.ros.shm_clean), on real files and the real /proc.

The files live in a temporary directory standing in for /dev/shm (the functions take it as ``shm``);
a child process maps one of them with mmap, as a Fast DDS participant maps its port, and /proc shows it.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time

from euc_ros.ros.shm_clean import SHM_CLEAN_ENV, remove_stale_fastdds_files, stale_fastdds_files

OLD = time.time() - 3600.0

HOLD = """
import mmap, sys, time
f = open(sys.argv[1], "r+b")
m = mmap.mmap(f.fileno(), 0)
print("mapped", flush=True)
time.sleep(60)
"""


def _make(path, size=64, mtime=OLD):
    path.write_bytes(b"\0" * size)
    os.utime(path, (mtime, mtime))
    return path


def test_unmapped_old_ports_and_segments_are_stale_mapped_or_young_ones_are_not(tmp_path):
    shm = tmp_path
    dead_port, dead_sem = _make(shm / "fastrtps_port7999"), _make(shm / "sem.fastrtps_port7999_mutex")
    live_port, live_sem = _make(shm / "fastrtps_port7998"), _make(shm / "sem.fastrtps_port7998_mutex")
    young_port = _make(shm / "fastrtps_port7997", mtime=time.time())
    dead_seg, dead_lock = _make(shm / "fastrtps_0123456789abcdef"), _make(shm / "fastrtps_0123456789abcdef_el")
    other = _make(shm / "not_fast_dds")
    child = subprocess.Popen([sys.executable, "-c", HOLD, str(live_port)], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "mapped"
        stale = set(stale_fastdds_files(shm))
        assert stale == {dead_port, dead_sem, dead_seg, dead_lock}
        assert remove_stale_fastdds_files(shm, environ={SHM_CLEAN_ENV: "0"}) == []     # switched off
        assert dead_port.exists()
        removed = set(remove_stale_fastdds_files(shm, environ={}))
        assert removed == stale
        assert not any(p.exists() for p in stale)
        assert all(p.exists() for p in (live_port, live_sem, young_port, other))
    finally:
        child.kill()
        child.wait()
    # the port is stale once its process has ended (and it is old)
    os.utime(live_port, (OLD, OLD))
    assert set(stale_fastdds_files(shm)) == {live_port, live_sem}


def test_a_mapped_semaphore_keeps_its_port(tmp_path):
    port, sem = _make(tmp_path / "fastrtps_port7000"), _make(tmp_path / "sem.fastrtps_port7000_mutex")
    child = subprocess.Popen([sys.executable, "-c", HOLD, str(sem)], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "mapped"
        assert stale_fastdds_files(tmp_path) == []
    finally:
        child.kill()
        child.wait()
    assert port.exists()


def test_a_missing_directory_has_nothing_stale(tmp_path):
    assert stale_fastdds_files(tmp_path / "absent") == []
