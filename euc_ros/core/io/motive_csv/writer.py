"""Writing a Motive CSV export: :func:`write_motive_csv`.

The file is format 1.23, with quaternions, in metres, written atomically;
:func:`~euc_ros.core.io.motive_csv.reader.read_motive_csv` reads it back.
"""
from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.io.motive_csv.header import QUATERNION, check_world_up
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.rotations import (
    z_up_to_y_up_position,
    z_up_to_y_up_quat,
)


def _csv_line(cells: list[str]) -> str:
    for c in cells:
        if "\n" in c or "\r" in c:
            raise InputError(f"cannot write {c!r} in a CSV header: it contains a line break")
    out = []
    for c in cells:
        out.append('"' + c.replace('"', '""') + '"' if any(ch in c for ch in ',"') else c)
    return ",".join(out)


def write_motive_csv(series: MocapSeries, path: str | Path, *, world_up: str = "y", take_name: str | None = None,
                     decimals: int = 9) -> Path:
    """Write ``series`` as a Motive CSV export, format 1.23, quaternions, metres (atomically).

    Parameters
    ----------
    series : MocapSeries
        Poses in the Z-up world [m]; untracked samples (``tracked == False``) become blank cells.
    path : str or Path
        Output file. It is written to a temporary file in the same directory and renamed, so a failure
        leaves any existing file untouched and never a half-written one.
    world_up : {"y", "z"}
        Up axis of the file's world: ``"y"`` writes Motive's default Y-up axes (X, Y, Z) = (x, z, -y).
    take_name : str, optional
        ``Take Name`` value (default: ``series.name`` or the file stem).
    decimals : int
        Decimals of positions [m], quaternions and marker errors [m] (Motive writes 6).

    Returns
    -------
    Path
        The written file. ``read_motive_csv(path, world_up=world_up)`` returns ``series`` again to within
        ``0.5 * 10**-decimals``.

    Raises
    ------
    InputError
        Without a positive frame rate, or with body names that are empty or not unique.
    """
    world_up = check_world_up(world_up)
    path = Path(path)
    rate = float(series.rate_hz)
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"cannot write a Motive CSV without a positive frame rate (got {rate})", key="rate_hz")
    n, b = series.n_frames, len(series.bodies)
    for k, nm in enumerate(series.bodies):
        if not nm or nm in series.bodies[:k]:
            raise InputError(f"rigid-body names must be unique and non-empty to be written, got {nm!r}",
                             path=path, key="bodies")
    take = take_name if take_name is not None else (series.name or path.stem)
    start = str(series.meta.get("start_time") or "")
    meta = ["Format Version", "1.23", "Take Name", take, "Take Notes", "", "Capture Frame Rate", f"{rate:.6f}",
            "Export Frame Rate", f"{rate:.6f}", "Capture Start Time", start,
            "Capture Start Frame", str(int(series.frame[0]) if n else 0),
            "Total Frames in Take", str(n), "Total Exported Frames", str(n), "Rotation Type", QUATERNION,
            "Length Units", "Meters", "Coordinate Space", "Global"]
    per_body = 8
    types = ["", "Type"] + ["Rigid Body"] * (per_body * b)
    names = ["", "Name"] + [nm for nm in series.bodies for _ in range(per_body)]
    ids = ["", "ID"] + [str(k + 1) for k in range(b) for _ in range(per_body)]
    comps = ["", ""] + sum((["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"] for _ in range(b)), [])
    axes = ["Frame", "Time (Seconds)"] + ["X", "Y", "Z", "W", "X", "Y", "Z", ""] * b
    head = "\n".join([_csv_line(meta), "", _csv_line(types), _csv_line(names), _csv_line(ids), _csv_line(comps),
                      _csv_line(axes)]) + "\n"

    pos = np.asarray(series.position, float)
    quat = np.asarray(series.quat, float)
    if world_up == "y":
        pos, quat = z_up_to_y_up_position(pos), z_up_to_y_up_quat(quat)
    trk = np.asarray(series.tracked, bool)[..., None]
    block = np.concatenate([np.where(trk, quat, np.nan), np.where(trk, pos, np.nan),
                            np.where(trk[..., 0], series.mean_marker_error, np.nan)[..., None]], axis=2)  # (b, n, 8)
    matrix = np.empty((n, 2 + per_body * b))
    matrix[:, 0] = series.frame
    matrix[:, 1] = np.asarray(series.frame, float) / rate
    matrix[:, 2:] = np.moveaxis(block, 0, 1).reshape(n, per_body * b)
    fmt = ",".join(["%d", "%.6f"] + [f"%.{int(decimals)}f"] * (per_body * b))
    buf = io.StringIO()
    np.savetxt(buf, matrix, fmt=fmt, delimiter=",", newline="\n")
    body = buf.getvalue().replace("nan", "")

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write(head)
            fh.write(body)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path
