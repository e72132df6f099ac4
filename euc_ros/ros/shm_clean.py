"""Stale Fast DDS shared-memory files: the ones no process maps, removed before a recorder starts.

Fast DDS 2.14 keeps each participant's receive port in ``/dev/shm/fastrtps_port<N>`` (with a semaphore
``sem.fastrtps_port<N>_mutex``) and each participant's segment in ``fastrtps_<hex>`` (with a lock file
``fastrtps_<hex>_el``). A process that is killed or crashes leaves its files behind, and a later
participant with the same port number **opens the old port file as it is**: the recorder's profile
asks for a 65536-descriptor port, but a stale 512-descriptor file keeps 512, and a burst of more than
5 ms at 100k msgs/s is then dropped. Measured here: with the stale ports a day of test runs had left,
the recorder benchmark lost messages at 86k msgs/s (reliable) and 104k msgs/s (best effort); with
them removed, none up to the publishers' limit.

A file is stale when it is ours (same owner), was last modified at least :data:`MIN_AGE_S` ago, and
**no process maps it** (``/proc/<pid>/maps``; for a port, neither the port nor its semaphore). The
directory is listed before the maps are read, so a participant starting meanwhile is not mistaken
for a dead one. Processes whose maps cannot be read are not counted: for our own files that is a
process of another user that could not open them for writing anyway (Fast DDS' shared memory does
not work across users), or a privileged one that is not a Fast DDS participant (PID 1 here). Processes in
another PID namespace that share ``/dev/shm`` (containers run with ``--ipc=host``) are invisible:
set ``EUC_ROS_SHM_CLEAN=0`` for a recorder in such a set-up. Removing a file unlinks its name only.
"""
from __future__ import annotations

import os
import re
import time
from pathlib import Path

#: Environment variable that turns the recorder's clean-up off (``0``).
SHM_CLEAN_ENV = "EUC_ROS_SHM_CLEAN"
#: A file modified more recently than this is never taken for stale [s].
MIN_AGE_S = 5.0
_PORT = re.compile(r"^fastrtps_port(\d+)$")
_SEGMENT = re.compile(r"^fastrtps_([0-9a-f]{16})$")


def mapped_shm_files(proc: Path = Path("/proc"), shm: Path = Path("/dev/shm")) -> set[str]:
    """Names of the files in ``shm`` that some process maps (processes whose maps are unreadable are skipped)."""
    prefix = str(shm).rstrip("/") + "/"
    names: set[str] = set()
    for entry in os.scandir(proc):
        if not entry.name.isdigit():
            continue
        try:
            with open(os.path.join(entry.path, "maps"), encoding="utf-8", errors="replace") as f:
                for line in f:
                    i = line.find(prefix)
                    if i >= 0:
                        names.add(line[i + len(prefix):].rstrip("\n").removesuffix(" (deleted)"))
        except (FileNotFoundError, ProcessLookupError, PermissionError):
            continue                          # ended meanwhile, or not ours to read (module docstring)
    return names


def stale_fastdds_files(shm: Path = Path("/dev/shm"), proc: Path = Path("/proc"), *,
                        min_age_s: float = MIN_AGE_S) -> list[Path]:
    """The Fast DDS port and segment files in ``shm`` that are ours, older than ``min_age_s`` and mapped by no process.

    The files come with their semaphores and lock files.
    """
    if not shm.is_dir():
        return []
    now, uid = time.time(), os.getuid()
    present: dict[str, float] = {}
    for entry in os.scandir(shm):
        try:
            st = entry.stat(follow_symlinks=False)
        except FileNotFoundError:
            continue
        if st.st_uid == uid:
            present[entry.name] = st.st_mtime
    mapped = mapped_shm_files(proc, shm)
    stale: list[Path] = []
    for name in sorted(present):
        if now - present[name] < min_age_s or name in mapped:
            continue
        if (m := _PORT.match(name)) is not None:
            sem = f"sem.fastrtps_port{m.group(1)}_mutex"
            if sem not in mapped:
                stale += [shm / name] + ([shm / sem] if sem in present else [])
        elif _SEGMENT.match(name) is not None:
            lock = name + "_el"
            stale += [shm / name] + ([shm / lock] if lock in present else [])
    return stale


def remove_stale_fastdds_files(shm: Path = Path("/dev/shm"), proc: Path = Path("/proc"), environ=None,
                               **kw) -> list[Path]:
    """Remove :func:`stale_fastdds_files` (nothing when ``EUC_ROS_SHM_CLEAN=0``); returns what was removed."""
    if (os.environ if environ is None else environ).get(SHM_CLEAN_ENV, "1").strip() == "0":
        return []
    removed = []
    for path in stale_fastdds_files(shm, proc, **kw):
        try:
            path.unlink()
        except (FileNotFoundError, PermissionError):   # another cleaner was first / not removable
            continue
        removed.append(path)
    return removed
