"""Reading a Motive CSV export: :func:`read_motive_csv`.

The header is parsed (:mod:`.header`), the data rows read chunk by chunk (:mod:`.block`), then come the
checks and the metadata of the series.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.io.motive_csv.block import read_rows
from euc_ros.core.io.motive_csv.header import (
    EULER_ORDERS,
    LENGTH_UNITS_M,
    MARKER_TYPES,
    check_world_up,
    head_bytes,
    header_summary,
    parse_header,
    skipped_text,
)
from euc_ros.core.mocap.series import MocapSeries

#: |norm - 1| of a file quaternion above which a warning is added (Motive writes 6 decimals).
QUAT_NORM_TOLERANCE = 1e-3
#: Largest plausible pivot distance from the origin of a capture volume [m] (unit sanity check).
PLAUSIBLE_REACH_M = 50.0


def _open(path: str | Path):
    """The file opened for binary reading (seekable); InputError naming it if it cannot be."""
    p = Path(path)
    try:
        f = open(p, "rb")
        if not f.seekable():  # a pipe: read whole (the reader reads the data rows twice)
            with f:
                return io.BytesIO(f.read())
        return f
    except FileNotFoundError:
        raise InputError("no such file", path=p) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a Motive CSV file", path=p) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=p) from None


def _select_bodies(hdr, bodies: list[str] | None, spath: str) -> list:
    """The header's rigid bodies named in ``bodies``, in that order (all, in file order, when None)."""
    if bodies is None:
        return hdr.bodies
    by_name = {b.name: b for b in hdr.bodies}
    missing = [b for b in bodies if b not in by_name]
    if missing:
        raise InputError(f"rigid body {missing[0]!r} not in the file (has: "
                         f"{', '.join(by_name) or 'no rigid bodies'})", path=spath)
    return [by_name[b] for b in bodies]


def _frame_rate(info: dict, frame: np.ndarray, time_col: np.ndarray, spath: str, warnings: list) -> tuple[float, str]:
    """The export's frame rate and where it came from.

    The header's export rate, else its capture rate, else the Frame and Time columns (said in ``warnings``).
    """
    rate = info["rate_hz"]
    rate_source = "Export Frame Rate"
    if rate is None:
        rate, rate_source = info["capture_rate_hz"], "Capture Frame Rate"
        if rate is None:
            ok = np.isfinite(time_col)
            if ok.sum() >= 2 and np.ptp(time_col[ok]) > 0:
                rate = float(np.ptp(frame[ok]) / np.ptp(time_col[ok]))
                rate_source = "Frame and Time columns"
            else:
                raise InputError("no 'Export Frame Rate' (nor 'Capture Frame Rate') in the header, and the Time "
                                 "column cannot give the rate", path=spath, line=1, key="Export Frame Rate")
        warnings.append(f"no 'Export Frame Rate' in the header: rate {rate:g} Hz taken from the {rate_source}")
    return rate, rate_source


def _content_warnings(hdr, block, out, check_reach: bool, warnings: list) -> None:
    """Append to ``warnings`` what the rows read say about the file.

    Quaternions not unit, positions beyond a plausible reach in metres, a row count other than the header's,
    columns not read.
    """
    norm_error = out.norm_error
    if norm_error > QUAT_NORM_TOLERANCE:
        warnings.append(f"quaternions are not unit (largest |norm - 1| = {norm_error:.3g}): normalised")
    if check_reach and out.reach > PLAUSIBLE_REACH_M:
        warnings.append(f"positions reach {out.reach:.4g} (assumed m): without a 'Length Units' key the file may be "
                        "in centimetres or millimetres")
    total, _ = hdr.get("Total Exported Frames")
    if total and total.isdigit() and int(total) != block.n_rows:
        warnings.append(f"header says Total Exported Frames {total} but the file has {block.n_rows} data rows")
    unread = {k: v for k, v in hdr.skipped.items() if k.lower() not in MARKER_TYPES}
    if unread:   # markers beside rigid bodies are the usual export; anything else is worth a word
        warnings.append(f"not read (euc_ros reads rigid bodies): {skipped_text(unread)}")


def read_motive_csv(path: str | Path, *, world_up: str = "y", bodies: list[str] | None = None) -> MocapSeries:
    """Read a Motive CSV export into a :class:`MocapSeries` (Z-up world, metres, unit quaternions).

    Parameters
    ----------
    path : str or Path
        Motive "Export Tracking Data" CSV, format 1.21 to 1.23 (docs/motive_csv.md).
    world_up : {"y", "z"}
        Up axis of the Motive world the file was exported in (the file never says; the session file
        does). ``"y"`` (Motive's default): positions (X, Y, Z) -> (X, -Z, Y) and quaternions
        (qx, qy, qz, qw) -> (qx, -qz, qy, qw). ``"z"``: no swap.
    bodies : list of str, optional
        Rigid bodies to return, in this order (default: all, in file order).

    Returns
    -------
    MocapSeries
        ``t = frame / Export Frame Rate`` [s]; ``frame`` as in the file (duplicate or out-of-order frames
        dropped, first kept); positions [m]; quaternions (x, y, z, w) with w >= 0; ``tracked`` False and
        NaN where the body's group is blank (or partly blank) in a row; ``mean_marker_error`` [m] (NaN
        without the column). ``meta`` holds path, take_name, format_version, rate_hz, capture_rate_hz,
        start_time, rotation_type, length_units, coordinate_space, world_up, n_dropped (gaps in the frame
        numbering), n_duplicates_dropped, occlusions {body: untracked frames}, n_partial_blank
        {body: rows with a partly blank group}, warnings (assumptions: default units, rotation type...),
        header (the raw key/value pairs).

    Raises
    ------
    InputError
        Missing header rows, non-numeric cells, a truncated line, an unknown rotation type or length
        unit, a Frame cell that is not an integer, an unknown body in ``bodies``: the message names the
        file, the 1-based line and column and the column's header (e.g. ``'E Position Y'``).
    ConfigError
        ``world_up`` not ``"y"`` or ``"z"``.

    Notes
    -----
    Euler types are Motive's relative (intrinsic) sequences in degrees, see the docstring of
    :mod:`euc_ros.core.io.motive_csv`.
    """
    world_up = check_world_up(world_up)
    spath = str(path)
    try:
        with _open(path) as fh:
            hdr = parse_header(head_bytes(fh), spath)
            warnings: list[str] = []
            info = header_summary(hdr, warnings)
            units, scale = LENGTH_UNITS_M[info["length_units"].lower()]
            rot_type = info["rotation_type"]

            selected = _select_bodies(hdr, bodies, spath)

            # The data rows, chunk by chunk, into arrays sized once (docs/motive_csv.md, "Memory").
            check_reach = bool(info["header"]) and hdr.get("Length Units")[0] in (None, "")
            block, out = read_rows(fh, hdr, selected, rot_type, scale, world_up, check_reach)
    except OSError as exc:  # a read error after the file was opened
        raise InputError(f"cannot read: {exc.strerror}", path=Path(path)) from None
    if not block.terminated and block.n_rows:
        warnings.append("the last line has no line end: the file may have been cut short")
    if out.bad_frame is not None:
        i, cell = out.bad_frame
        raise block.error(i, 0, "Frame column is not an integer", cell)
    out.trim()
    frame, time_col, pos, quat, tracked, err = out.frame, out.time, out.position, out.quat, out.tracked, out.error
    n_dup = block.n_rows - frame.size
    n_dropped = int(np.sum(np.diff(frame) - 1)) if frame.size > 1 else 0

    rate, rate_source = _frame_rate(info, frame, time_col, spath, warnings)
    t = frame / rate
    time_dev = float(np.nanmax(np.abs(time_col - t))) if frame.size and np.isfinite(time_col).any() else None
    del time_col
    out.time = None

    norm_error = out.norm_error
    _content_warnings(hdr, block, out, check_reach, warnings)
    meta = {
        **{k: v for k, v in info.items() if k != "header"},
        "skipped": {k: list(v) for k, v in hdr.skipped.items()},
        "rate_hz": float(rate),
        "rate_source": rate_source,
        "world_up": world_up,
        "n_rows": int(block.n_rows),
        "n_dropped": n_dropped,
        "n_duplicates_dropped": n_dup,
        "occlusions": {g.name: int((~tracked[k]).sum()) for k, g in enumerate(selected)},
        "n_partial_blank": {g.name: int(out.partial[k]) for k, g in enumerate(selected)},
        "time_column_max_dev_s": time_dev,
        "max_quat_norm_error": norm_error,
        "warnings": warnings,
        "header": info["header"],
    }
    if rot_type in EULER_ORDERS:
        meta["euler_convention"] = (f"intrinsic (relative) {rot_type}, degrees: R = " +
                                    " @ ".join(f"R{a.lower()}" for a in rot_type))
    name = info["take_name"] or Path(spath).stem
    return MocapSeries(t=t, frame=frame, bodies=[g.name for g in selected], position=pos, quat=quat,
                       tracked=tracked, mean_marker_error=err, name=name, meta=meta)
