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
* two outputs are never the same path.
"""
from __future__ import annotations

import os
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
        real = _real(path)
        where = dict(key=out.option, path=str(path))
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
