"""Output paths checked before any work: nothing the user recorded is ever overwritten.

Every command that writes calls :func:`check_outputs` first, with its inputs (session, recordings,
bags) and its outputs (``--json``, ``--plots``, ``--report``, ``--out``...). A bad output is a
one-line :class:`~euc_ros.core.errors.ConfigError` naming the option and the path, raised before the
analysis runs, so a typo costs nothing and never costs a recording:

* an output is never an input (same file, or a file inside an input bag directory), and never a
  folder that holds an input it would write over;
* a file output is never an existing directory; a folder output is never an existing file;
* the nearest existing ancestor of an output must be a writable directory (missing folders are
  created by the commands);
* two outputs are never the same path;
* ``-`` as a file output is standard output (:data:`STDOUT`); the command's own messages then go to
  standard error, so that the output can be piped.
"""
from __future__ import annotations

import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from euc_ros.core.errors import ConfigError


@dataclass(frozen=True)
class Output:
    """One output of a command.

    Attributes
    ----------
    option : str
        The option or argument that names it (``--json``), for messages.
    path : str or Path or None
        The path (None: option not given, nothing to check).
    kind : {"file", "dir"}
        A file written, or a folder written into.
    """

    option: str
    path: str | Path | None
    kind: str = "file"


#: The path that means standard output.
STDOUT = "-"
#: Where a ``-`` output goes: the dispatcher points it at the real standard output while the command's
#: messages are redirected to standard error.
stdout_stream = None


def is_stdout(path) -> bool:
    """Whether ``path`` is ``-`` (standard output)."""
    return path is not None and str(path) == STDOUT


def write_output(path, text: str, option: str = "--json") -> None:
    """Write ``text`` to ``path`` atomically (a ``.part`` file renamed), or to standard output for ``-``.

    Raises
    ------
    ConfigError
        The file cannot be written, naming the option, the path and the reason (the analysis is done:
        the message says so, so that only the output needs another path).
    """
    if is_stdout(path):
        stream = stdout_stream or sys.stdout
        stream.write(text)
        stream.flush()
        return
    p = Path(path)
    tmp = p.with_name(p.name + ".part")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(p)
    except OSError as exc:
        tmp.unlink(missing_ok=True) if tmp.parent.is_dir() else None
        raise ConfigError(f"cannot be written ({exc.strerror or exc}); nothing else was affected: run again "
                          "with another path", key=option, path=str(p)) from None


def _probe_writable(anchor: Path) -> str | None:
    """Create and remove a file in ``anchor``: the reason it fails, or None.

    This finds a read-only or virtual file system, where permission bits and ``os.access`` say yes.
    """
    try:
        with tempfile.NamedTemporaryFile(dir=anchor, prefix=".euc_ros_probe_"):
            return None
    except OSError as exc:
        return exc.strerror or str(exc)


def _real(p: Path) -> Path:
    return Path(os.path.realpath(p))


def _inside(child: Path, parent: Path) -> bool:
    try:
        child.relative_to(parent)
    except ValueError:
        return False
    return True


def _nearest_existing(p: Path) -> Path:
    q = p
    while not q.exists() and q != q.parent:
        q = q.parent
    return q


def check_outputs(outputs: Iterable[Output], inputs: Iterable[str | Path] = ()) -> None:
    """Check every output against the inputs and the file system (see the module docstring).

    Raises
    ------
    ConfigError
        Naming the option (``key``) and the path, with what to do.
    """
    ins = [_real(Path(p)) for p in inputs if p is not None]
    seen: dict[Path, str] = {}
    for out in outputs:
        if out.path is None or str(out.path) == "":
            continue
        path = Path(out.path)
        where = dict(key=out.option, path=str(path))
        if is_stdout(path):
            if out.kind != "file":
                raise ConfigError("'-' (standard output) is for file outputs such as --json; give a folder",
                                  **where)
            if STDOUT in seen.values():
                raise ConfigError(f"is also given to {seen[Path(STDOUT)]}: only one output can go to "
                                  "standard output", **where)
            seen[Path(STDOUT)] = out.option
            continue
        real = _real(path)
        for src in ins:
            if real == src:
                raise ConfigError("is an input of this command: writing it would destroy the input; "
                                  "choose another path", **where)
            if src.is_dir() and _inside(real, src):
                raise ConfigError(f"is inside the input bag {src}: choose a path outside it", **where)
        if real in seen:
            raise ConfigError(f"is also the output of {seen[real]}: give them different paths", **where)
        seen[real] = out.option
        if out.kind == "file" and path.is_dir():
            raise ConfigError("is an existing directory: give a file name", **where)
        if out.kind == "dir" and path.exists() and not path.is_dir():
            raise ConfigError("is an existing file, not a folder: give a folder", **where)
        anchor = _nearest_existing(path.parent if out.kind == "file" else path)
        if not anchor.is_dir():
            raise ConfigError(f"cannot be created: {anchor} is a file, not a folder", **where)
        if not os.access(anchor, os.W_OK | os.X_OK):
            raise ConfigError(f"cannot be written: no write permission in {anchor}", **where)
        reason = _probe_writable(anchor)
        if reason is not None:
            raise ConfigError(f"cannot be written: {anchor} does not take new files ({reason})", **where)
