"""Which processes hold a file open (Linux ``/proc``): a bag still being written is not damaged.

Examples
--------
>>> import os, tempfile
>>> with tempfile.NamedTemporaryFile() as f:
...     os.getpid() in [pid for pid, _ in processes_with_open(f.name, include_self=True)]
True
"""
from __future__ import annotations

import os
from pathlib import Path

PROC = Path("/proc")


def _targets(path: Path) -> set[str]:
    """The real paths of ``path`` and, for a directory, of every file in it."""
    p = Path(path)
    found = {os.path.realpath(p)}
    if p.is_dir():
        found |= {os.path.realpath(f) for f in p.rglob("*") if f.is_file()}
    return found


def processes_with_open(path: str | Path, *, include_self: bool = False) -> list[tuple[int, str]]:
    """``(pid, process name)`` of every process with ``path`` (or a file in it) open.

    Processes whose descriptors this user cannot read are not seen (other users' processes without
    privileges). Returns an empty list where ``/proc`` does not exist.

    Parameters
    ----------
    path : str or Path
        The file or directory.
    include_self : bool
        Include this process.

    Returns
    -------
    list of tuple of (int, str)
        ``(pid, process name)``.
    """
    if not PROC.is_dir():
        return []
    targets = _targets(Path(path))
    me = os.getpid()
    out = []
    for entry in PROC.iterdir():
        if not entry.name.isdigit() or (int(entry.name) == me and not include_self):
            continue
        try:
            fds = list((entry / "fd").iterdir())
        except OSError:
            continue
        for fd in fds:
            try:
                if os.readlink(fd) in targets:
                    name = (entry / "comm").read_text().strip()
                    out.append((int(entry.name), name))
                    break
            except OSError:
                continue
    return out
