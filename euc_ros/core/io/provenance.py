r"""Where a result came from: the session and recordings an analysis read, by path and content hash.

``identify`` and ``residual`` write :func:`inputs_record` into their JSON (``inputs``; the recording
format's section 5). Whatever applies a result to data (``identify --from-residual``, the live
``torque_estimator``'s ``model``, the Python API) compares it with the data it is given through
:func:`check_inputs`, which refuses a mismatch with one line naming the file.

A recording's hash is its content's, not its name's: a CSV is hashed whole; a bag directory by its
storage files (``*.mcap``, ``*.db3``) in name order, each with its name, so that a bag whose
``metadata.yaml`` was rebuilt (``euc-ros recover``) is the same recording, and a CSV converted to a
bag is another one.

Examples
--------
>>> import tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> _ = (folder / "session.yaml").write_text("rider: {}\n")
>>> _ = (folder / "take.csv").write_text("Format Version,1.23\n")
>>> record = inputs_record(folder / "session.yaml", [folder / "take.csv"])
>>> check_inputs(record, session=folder / "session.yaml", recordings=[folder / "take.csv"], source="r.json")
[]
>>> _ = (folder / "other.csv").write_text("Format Version,1.24\n")
>>> check_inputs(record, recordings=[folder / "other.csv"], source="r.json")  # doctest: +ELLIPSIS
Traceback (most recent call last):
    ...
euc_ros.core.io.provenance.InputMismatch: r.json: .../other.csv is not among the recordings it was made from...
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Sequence

from euc_ros.core.errors import ConfigError, InputError

#: Storage files of a rosbag2 directory that make its content (``metadata.yaml`` is an index of them).
BAG_STORAGE_SUFFIXES = (".mcap", ".db3")
_CHUNK = 1 << 22


class InputMismatch(ConfigError):
    """A result applied to data it was not made from (another session or other recordings).

    Parameters
    ----------
    message : str
        What differs and how to proceed.
    path : str or Path, optional
        File the error is in.
    line : int, optional
        1-based line number.
    column : int or str, optional
        1-based column number or column name.
    key : str, optional
        Dotted key for structured files.
    """


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of a file's bytes, as 64 hex digits.

    Parameters
    ----------
    path : str or Path
        A regular file.

    Returns
    -------
    str
        The hex digest.

    Raises
    ------
    InputError
        The file cannot be read, naming it.
    """
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(_CHUNK), b""):
                digest.update(chunk)
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path) from None
    return digest.hexdigest()


def recording_sha256(path: str | Path) -> str:
    """The content hash of a recording: a CSV or ``.mcap`` file whole, a bag directory by its storage files.

    Parameters
    ----------
    path : str or Path
        A Motive CSV export, an ``.mcap`` file or a rosbag2 directory.

    Returns
    -------
    str
        64 hex digits. A directory's is the SHA-256 of the names and hashes of its storage files
        (:data:`BAG_STORAGE_SUFFIXES`), in name order.

    Raises
    ------
    InputError
        A directory without storage files, or a file that cannot be read.
    """
    p = Path(path)
    if not p.is_dir():
        return file_sha256(p)
    parts = sorted(q for q in p.iterdir() if q.is_file() and q.suffix.lower() in BAG_STORAGE_SUFFIXES)
    if not parts:
        raise InputError("bag directory without a storage file (.mcap or .db3)", path=p)
    digest = hashlib.sha256()
    for q in parts:
        digest.update(f"{q.name}\0{file_sha256(q)}\n".encode())
    return digest.hexdigest()


def inputs_record(session: str | Path, recordings: Sequence[str | Path]) -> dict:
    """The ``inputs`` block of an analysis JSON: the session and every recording, path and hash.

    Parameters
    ----------
    session : str or Path
        Session file as given (the path is written as given, relative or absolute).
    recordings : sequence of str or Path
        Recordings as given.

    Returns
    -------
    dict
        ``{"session": {"path", "sha256"}, "recordings": [{"path", "sha256"}, ...]}``.
    """
    return {"session": {"path": str(session), "sha256": file_sha256(session)},
            "recordings": [{"path": str(r), "sha256": recording_sha256(r)} for r in recordings]}


def _recorded(record: dict, source: str | Path, force_option: str) -> tuple[dict, list[dict]]:
    """The session and recording entries of an ``inputs`` block; InputMismatch naming ``source`` when absent."""
    session = record.get("session") if isinstance(record, dict) else None
    recs = record.get("recordings") if isinstance(record, dict) else None
    if not isinstance(session, dict) or "sha256" not in session or not isinstance(recs, list):
        raise InputMismatch("records no inputs (session and recordings with their sha256), so it cannot be checked "
                            f"against this data: write it again with this euc-ros, or pass {force_option} to apply "
                            "it unchecked", path=source, key="inputs")
    return session, [r for r in recs if isinstance(r, dict) and "sha256" in r]


def check_inputs(record: dict | None, *, session: str | Path | None = None,
                 recordings: Sequence[str | Path] | None = None, source: str | Path = "the result",
                 force: bool = False, force_option: str = "--force") -> list[str]:
    """Refuse to apply a result to a session or recordings it was not made from.

    Parameters
    ----------
    record : dict or None
        The result's ``inputs`` block (:func:`inputs_record`); None when the result has none.
    session : str or Path, optional
        The session file the result is applied with (not checked when None).
    recordings : sequence of str or Path, optional
        The recordings it is applied to (not checked when None): each must be one the result was
        made from (by content; a subset is fine).
    source : str or Path
        The result's file, named in the message.
    force : bool
        Apply anyway: the mismatches are returned as warnings instead of raised.
    force_option : str
        How the user says ``force`` (named in the messages): ``--force``, or a node's parameter.

    Returns
    -------
    list of str
        With ``force``, one line per mismatch; otherwise empty.

    Raises
    ------
    InputMismatch
        The first mismatch, naming the result's file, the file given and the one recorded, and
        ``--force``.
    """
    problems: list[str] = []
    try:
        recorded_session, recorded = _recorded(record or {}, source, force_option)
    except InputMismatch as exc:
        if force:
            return [f"{source}: {exc.detail.split(':')[0]} (applied unchecked: {force_option})"]
        raise
    if session is not None and file_sha256(session) != recorded_session["sha256"]:
        problems.append(f"it was made with the session {recorded_session.get('path', '?')}, and {session} differs "
                        "from it (another rider, EUC or marker set: its h and effects do not belong to this session)")
    if recordings is not None:
        known = {r["sha256"] for r in recorded}
        names = ", ".join(os.path.basename(str(r.get("path", "?"))) for r in recorded) or "none"
        for rec in recordings:
            if recording_sha256(rec) not in known:
                problems.append(f"{rec} is not among the recordings it was made from ({names}): a result of other "
                                "data is not evidence about this one")
    if problems and not force:
        raise InputMismatch(problems[0] + f"; run the analysis on this data, or pass {force_option} to apply it "
                            "anyway", path=source)
    return [f"{source}: {p} (applied anyway: {force_option})" for p in problems]
