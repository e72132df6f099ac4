"""`euc-ros inspect FILE [--json OUT]`: what a recording holds.

For a Motive CSV export: bodies, frames, rates, duration, first/last frame, dropped and duplicate
frames, up axis (as configured, and as inferred from the data: Motive never writes it), rotation type,
length units and occlusion counts per body. For a rosbag2 bag (a directory with ``metadata.yaml``, or
an ``.mcap`` file): the summary of :func:`euc_ros.core.io.bags.inspect_bag` and the verdict of its
structural check :func:`euc_ros.core.io.bags.check_bag`.

Exit codes: 0 (read, and for bags the structural check passed), 1 (bag failed the structural check),
2 (the file cannot be read: the error names the file, line and column).
"""
from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import InputError
from euc_ros.core.session import load_session

HELP = "show what a Motive CSV or a bag holds (and check bags structurally)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``euc-ros inspect``."""
    parser.add_argument("file", metavar="FILE",
                        help="Motive CSV export, rosbag2 directory (with metadata.yaml) or .mcap file")
    parser.add_argument("--json", metavar="OUT", default=None,
                        help="also write the summary as JSON to OUT (written only if FILE could be read)")
    parser.add_argument("--world-up", choices=("y", "z"), default=None,
                        help="up axis of the Motive world of a CSV (default: the session's world_up, else y)")
    parser.add_argument("--session", metavar="YAML", default=None, help="session file giving world_up")


def is_bag(path: Path) -> bool:
    """True for a rosbag2 directory (has ``metadata.yaml``) or an ``.mcap`` file."""
    return (path.is_dir() and (path / "metadata.yaml").is_file()) or path.suffix.lower() == ".mcap"


def summarize_motive_csv(path: str | Path, *, world_up: str = "y", world_up_source: str = "default",
                         session=None) -> dict:
    """Return the inspect summary of a Motive CSV export (JSON-ready; NaN become None).

    Parameters
    ----------
    path : str or Path
        Motive CSV export.
    world_up : {"y", "z"}
        Up axis the file is read with.
    world_up_source : str
        Where ``world_up`` came from (``"--world-up"``, ``"session"`` or ``"default"``), reported as is.
    session : Session, optional
        Adds the wheel-centre and EUC-axis evidence to the inferred up axis
        (:func:`euc_ros.core.mocap.conventions.infer_up_axis`).
    """
    from euc_ros.core.io.motive_csv import UP_AXIS_NOTE, read_motive_csv

    s = read_motive_csv(path, world_up=world_up)
    m = s.meta
    n = s.n_frames
    return {
        "kind": "motive_csv",
        "path": str(path),
        "take_name": m.get("take_name"),
        "format_version": m.get("format_version"),
        "bodies": list(s.bodies),
        "n_bodies": len(s.bodies),
        "skipped": {k: len(v) for k, v in s.meta.get("skipped", {}).items()},
        "n_frames": n,
        "rate_hz": m["rate_hz"],
        "capture_rate_hz": m.get("capture_rate_hz"),
        "duration_s": float(s.t[-1] - s.t[0]) if n else 0.0,
        "first_frame": int(s.frame[0]) if n else None,
        "last_frame": int(s.frame[-1]) if n else None,
        "n_dropped": m["n_dropped"],
        "n_duplicates_dropped": m["n_duplicates_dropped"],
        "up_axis": {"configured": world_up, "source": world_up_source, **_up_axis(s, session), "note": UP_AXIS_NOTE},
        "rotation_type": m.get("rotation_type"),
        "length_units": m.get("length_units"),
        "coordinate_space": m.get("coordinate_space"),
        "start_time": m.get("start_time"),
        "occlusions": dict(m["occlusions"]),
        "n_partial_blank": dict(m["n_partial_blank"]),
        "warnings": list(m["warnings"]),
    }


def _up_axis(series, session) -> dict:
    """The inferred up axis: ``inferred``, ``reason``, ``conclusive`` (the per-test values stay in the core)."""
    from euc_ros.core.mocap.conventions import infer_up_axis

    info = infer_up_axis(series, session)
    return {k: info[k] for k in ("inferred", "reason", "conclusive")}


def summarize_bag(path: str | Path) -> dict:
    """Return the inspect summary of a bag: ``bags.inspect_bag`` plus ``check`` {ok, problems}.

    The problems are those of the structural check ``bags.check_bag`` (reported by ``inspect_bag``
    itself when it carries them, so the bag is scanned once).
    """
    try:
        bags = importlib.import_module("euc_ros.core.io.bags")
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.startswith("euc_ros"):
            raise InputError("bag support (euc_ros.core.io.bags) is not available in this build", path=path) from None
        raise
    info = dict(bags.inspect_bag(path))
    problems = list(info.pop("problems")) if "problems" in info else list(bags.check_bag(path))
    return {"kind": "rosbag2", "path": str(path), **info, "check": {"ok": not problems, "problems": problems}}


def _plain(x: Any) -> Any:
    """JSON-ready copy: NaN/inf -> None, numpy scalars/arrays -> Python, paths -> str."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if hasattr(x, "tolist") and not isinstance(x, (str, bytes)):
        return _plain(x.tolist())
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, (str, int, bool)) or x is None:
        return x
    return str(x)


def format_summary(summary: dict) -> str:
    """Human-readable text of a summary from :func:`summarize_motive_csv` or :func:`summarize_bag`."""
    s = _plain(summary)
    if s.get("kind") != "motive_csv":
        return _format_generic(s)

    def num(x, fmt):
        return "?" if x is None else format(x, fmt)

    up = s["up_axis"]
    lines = [
        f"Motive CSV     {s['path']}",
        f"take           {s['take_name']}  (format {s['format_version']}, started {s['start_time'] or '?'})",
        f"bodies         {s['n_bodies']}: {', '.join(s['bodies']) if s['bodies'] else '(no rigid bodies)'}",
        *([f"not read       {_skipped_line(s['skipped'])}"] if s.get("skipped") else []),
        f"frames         {s['n_frames']} (first {s['first_frame']}, last {s['last_frame']}), "
        f"{s['n_dropped']} dropped, {s['n_duplicates_dropped']} duplicate/out-of-order dropped",
        f"rate           {num(s['rate_hz'], 'g')} Hz export, {num(s['capture_rate_hz'], 'g')} Hz capture; "
        f"duration {num(s['duration_s'], '.3f')} s",
        f"up axis        {up['configured']} (configured: {up['source']}); data suggest {up['inferred']}: "
        f"{up['reason']}",
        f"               note: {up['note']}",
        f"rotation type  {s['rotation_type']}",
        f"length units   {s['length_units']}, coordinate space {s['coordinate_space']}",
    ]
    if s["bodies"]:
        lines.append("occlusions     untracked frames per body:")
        width = max(len(b) for b in s["bodies"])
        for b in s["bodies"]:
            occ = s["occlusions"][b]
            frac = 100.0 * occ / s["n_frames"] if s["n_frames"] else 0.0
            part = s["n_partial_blank"].get(b, 0)
            extra = f", {part} partly blank" if part else ""
            lines.append(f"  {b:<{width}}  {occ:>7} ({frac:.1f} %{extra})")
    for w in s["warnings"]:
        lines.append(f"warning        {w}")
    return "\n".join(lines)


def _format_generic(s: dict) -> str:
    """Bag summary: scalars as ``key: value``, topics and files as tables, other lists/dicts as JSON."""
    lines = [f"rosbag2 bag    {s.get('path')}"] if s.get("kind") == "rosbag2" else []
    for k, v in s.items():
        if k in ("check", "kind") or (k == "path" and lines):
            continue
        if k == "topics" and isinstance(v, list) and all(isinstance(t, dict) for t in v):
            lines.append(f"topics ({len(v)}):")
            width = max((len(str(t.get("name", ""))) for t in v), default=0)
            for t in v:
                rate = t.get("rate_hz")
                rate_s = f"{rate:9.2f} Hz" if isinstance(rate, (int, float)) else f"{'?':>9} Hz"
                lines.append(f"  {str(t.get('name', '?')):<{width}}  {t.get('count', '?'):>8} msgs  {rate_s}  "
                             f"{t.get('type', '?')}")
        elif k == "files" and isinstance(v, list) and all(isinstance(f, dict) for f in v):
            lines.append("files: " + ", ".join(f"{f.get('name', '?')} ({f.get('bytes', '?')} bytes)" for f in v))
        elif isinstance(v, (dict, list)):
            lines.append(f"{k}:")
            lines.extend(f"  {line}" for line in json.dumps(v, indent=2).splitlines())
        else:
            lines.append(f"{k}: {v}")
    check = s.get("check")
    if check is not None:
        if check["ok"]:
            lines.append("structural check: OK")
        else:
            lines.append(f"structural check: FAILED ({len(check['problems'])} problem(s))")
            lines.extend(f"  - {p}" for p in check["problems"])
    return "\n".join(lines)


def write_json(summary: dict, out: str | Path) -> Path:
    """Write ``summary`` as JSON atomically (temporary file in the same directory, then rename)."""
    out = Path(out)
    if not out.parent.is_dir():
        raise InputError("directory does not exist", path=out.parent)
    text = json.dumps(_plain(summary), indent=2, allow_nan=False) + "\n"
    fd, tmp = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out


def main(args: argparse.Namespace) -> int:
    """Run ``euc-ros inspect``; returns the exit code (InputError propagates to the dispatcher: 2)."""
    path = Path(args.file)
    if not path.exists():
        raise InputError("no such file or directory", path=path)
    check_outputs([Output("--json", args.json)], [path, getattr(args, "session", None)])
    rc = 0
    if is_bag(path):
        summary = summarize_bag(path)
        rc = 0 if summary["check"]["ok"] else 1
    elif path.is_dir():
        raise InputError("directory is not a rosbag2 bag (no metadata.yaml)", path=path)
    else:
        session = None
        if args.session is not None:
            session = load_session(args.session)
        if args.world_up is not None:
            world_up, source = args.world_up, "--world-up"
        elif session is not None:
            world_up, source = session.world_up, f"session {args.session}"
        else:
            world_up, source = "y", "default (Motive's Y-up)"
        summary = summarize_motive_csv(path, world_up=world_up, world_up_source=source, session=session)
    print(format_summary(summary))
    if args.json:
        write_json(summary, args.json)
    return rc


def _skipped_line(skipped: dict) -> str:
    """``{"Bone": 13, "Marker": 4}`` -> ``13 Bone, 4 Marker (euc_ros reads rigid bodies only)``."""
    return ", ".join(f"{n} {kind}" for kind, n in skipped.items()) + " (euc_ros reads rigid bodies only)"
