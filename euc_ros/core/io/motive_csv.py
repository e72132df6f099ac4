"""OptiTrack Motive CSV exports: a fast, strict-where-broken, lenient-where-real reader and a writer.

The reader turns a Motive "Export Tracking Data" CSV (format 1.21, 1.22, 1.23;
docs/motive_csv.md) into a :class:`~euc_ros.core.mocap.series.MocapSeries` in the REP-103 Z-up world, SI units.
It is ROS-free and used by the mocap node and by every offline command.

Layout of a file (1.23; in 1.21/1.22 the label cells ``Type``, ``Name``, ``ID`` are empty)::

    line 1   Format Version,1.23,Take Name,...,Export Frame Rate,120.000000,...   key,value pairs
    line 2   (empty, or a row of commas)
    line 3   ,Type,Rigid Body,Rigid Body,...,Marker,...
    line 4   ,Name,E,E,...
    line 5   ,ID,1,1,...
    line 6   ,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error
    line 7   Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,
    line 8+  data rows (blank cells = untracked)

Conventions
-----------
* Columns are grouped by (Type, Name, ID) read from the header rows, never by position. Only
  ``Rigid Body`` groups are read. Skeleton bones, markers and unknown types are skipped and counted
  (``meta["skipped"]``, :func:`skipped_assets`), bones and unknown types with a warning naming them
  (markers beside rigid bodies are the usual export): euc_ros tracks the rider
  by rigid bodies at the pivots of the recording contract, and a bone's frame is not one of them. A
  file with no rigid body at all is refused by every command (:func:`require_rigid_bodies`), with
  what it holds instead and what to export.
* Time is ``t = Frame / Export Frame Rate`` [s] (docs/motive_csv.md): the ``Time (Seconds)`` column is
  rounded to whole milliseconds by some exporters and is not used.
* Y-up files (Motive's default, ``world_up="y"``): with REP-103 axes (x, y, z) the Motive axes are
  (X, Y, Z) = (x, z, -y), so a position (X, Y, Z) becomes (X, -Z, Y) and a quaternion
  (qx, qy, qz, qw) becomes (qx, -qz, qy, qw). ``world_up="z"`` leaves the axes as they are.
* Euler rotation types (``XYZ``, ``XZY``, ``YXZ``, ``YZX``, ``ZXY``, ``ZYX``; degrees) are Motive's
  *relative* (intrinsic) sequences: for ``XYZ`` the body is rotated about X, then about the new Y,
  then about the new Z, i.e. ``R = Rx(a_X) @ Ry(a_Y) @ Rz(a_Z)`` (NaturalPoint knowledge-base article
  "Changes in Motive's Reported Euler Angles", Motive >= 1.6; scipy's upper-case sequence names).
  The columns headed X, Y, Z hold the angles about X, Y and Z whatever the order. Angles are applied
  in the file's own (Motive) frame, then the axis swap above is applied to the quaternion.
* Quaternions are (x, y, z, w), body-to-world, normalised, with w >= 0.

Speed and memory: the data rows are read in chunks of about 1 MB, each converted by numpy's C float
parser (after a vectorized check of the row shapes where it fails) and turned into poses in place,
in arrays sized once by a first pass that counts the rows. The file is never held whole, nor the
matrix of all its cells: the peak memory is the result plus a few chunks. A per-cell scan only runs
on the chunk that holds an error, to name its line and column. See ``docs/motive_csv.md``.
"""
from __future__ import annotations

import csv
import io
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.rotations import (
    z_up_to_y_up_position,
    z_up_to_y_up_quat,
)

#: Length Units value (lower case, singular or plural) -> metres per unit.
LENGTH_UNITS_M: dict[str, tuple[str, float]] = {
    "meters": ("Meters", 1.0), "meter": ("Meters", 1.0), "metres": ("Meters", 1.0),
    "centimeters": ("Centimeters", 0.01), "centimeter": ("Centimeters", 0.01), "centimetres": ("Centimeters", 0.01),
    "millimeters": ("Millimeters", 0.001), "millimeter": ("Millimeters", 0.001), "millimetres": ("Millimeters", 0.001),
}
#: Euler rotation types Motive can export (relative / intrinsic sequences, degrees).
EULER_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")
#: Rotation type written when the header has none and each rigid body has 3 rotation columns.
DEFAULT_EULER_ORDER = "XYZ"
#: Header value of the quaternion rotation type.
QUATERNION = "Quaternion"
#: Component names of the per-body tracking-quality column (1.23 and 1.21/1.22 spelling).
ERROR_COMPONENTS = ("mean marker error", "error per marker")
#: The header is searched for the ``Frame`` row within this many lines.
MAX_HEADER_LINES = 64
#: Column types of markers: skipped without a warning (every export with rigid bodies has them).
MARKER_TYPES = ("marker", "rigid body marker")
#: Rows per chunk when an error has to be located.
_CHUNK_ROWS = 2048
#: |norm - 1| of a file quaternion above which a warning is added (Motive writes 6 decimals).
QUAT_NORM_TOLERANCE = 1e-3
#: Largest plausible pivot distance from the origin of a capture volume [m] (unit sanity check).
PLAUSIBLE_REACH_M = 50.0
#: Note printed wherever the up axis is reported.
UP_AXIS_NOTE = "Motive never writes the up axis in a CSV: it is configured (session world_up), not read"

_NUMBER = re.compile(rb"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)\s*", re.IGNORECASE)
_UTF8_BOM = b"\xef\xbb\xbf"


@dataclass
class _Column:
    """One data column as described by the five header rows."""

    type: str
    name: str
    id: str
    component: str
    axis: str

    @property
    def label(self) -> str:
        return " ".join(s for s in (self.name, self.component, self.axis) if s)


@dataclass
class _BodyColumns:
    """0-based column indices of one rigid body's group."""

    name: str
    id: str
    first: int
    rotation: dict[str, int] = field(default_factory=dict)
    position: dict[str, int] = field(default_factory=dict)
    error: int | None = None


@dataclass
class _Header:
    path: str
    meta: dict[str, str]            # key as written -> value (stripped)
    meta_col: dict[str, int]        # lower-case key -> 1-based column of its value on line 1
    axis_line: int                  # 1-based line number of the "Frame,Time..." row
    data_offset: int                # byte offset of the first data row
    width: int                      # number of columns declared by the header rows
    columns: list[_Column]
    bodies: list[_BodyColumns]
    row_lines: dict[str, int]       # "type"/"name"/"id"/"component" -> 1-based line number
    crlf: bool
    skipped: dict[str, list[str]] = field(default_factory=dict)   # column type -> asset names, file order

    def get(self, key: str) -> tuple[str | None, int | None]:
        """Value and 1-based column of metadata ``key`` (case-insensitive), or (None, None)."""
        for k, v in self.meta.items():
            if k.lower() == key.lower():
                return v, self.meta_col[k.lower()]
        return None, None


# ----------------------------------------------------------------------------------------- header
def _decode(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _split_cells(text: str, path: str, line: int) -> list[str]:
    try:
        rows = list(csv.reader([text], skipinitialspace=False))
    except csv.Error as exc:
        raise InputError(f"cannot split the line into cells ({exc})", path=path, line=line) from None
    return rows[0] if rows else []


def _header_lines(raw: bytes, path: str) -> tuple[list[list[str]], list[int], bool]:
    """Split the first lines of ``raw`` into cells, up to and including the ``Frame`` row.

    Returns the rows, the byte offset just past each row, and whether lines end in CRLF.
    """
    rows: list[list[str]] = []
    ends: list[int] = []
    pos = len(_UTF8_BOM) if raw.startswith(_UTF8_BOM) else 0
    crlf = False
    while len(rows) < MAX_HEADER_LINES and pos < len(raw):
        nl = raw.find(b"\n", pos)
        end = len(raw) if nl < 0 else nl + 1
        line = raw[pos:end].rstrip(b"\n")
        if line.endswith(b"\r"):
            line = line[:-1]
            crlf = crlf or not rows
        cells = _split_cells(_decode(line), path, len(rows) + 1)
        rows.append(cells)
        ends.append(end)
        pos = end
        if len(rows) == 1:
            _parse_metadata(cells, path)  # fail early on files that are not Motive exports at all
        if len(rows) > 1 and cells and cells[0].strip().lower() == "frame":
            return rows, ends, crlf
    if not rows:
        raise InputError("empty file: not a Motive CSV export", path=path, line=1)
    raise InputError("missing header rows: no 'Frame,Time (Seconds),...' row found in the first "
                     f"{len(rows)} lines (a Motive export has key/value, Type, Name, ID, component and "
                     "axis rows above the data)", path=path, line=len(rows), column=1)


def _parse_metadata(cells: list[str], path: str) -> tuple[dict[str, str], dict[str, int]]:
    if not cells or cells[0].strip().lower() != "format version":
        first = cells[0] if cells else ""
        raise InputError(f"not a Motive CSV export: line 1 must start with 'Format Version', found {first[:40]!r}",
                         path=path, line=1, column=1)
    meta: dict[str, str] = {}
    cols: dict[str, int] = {}
    for i in range(0, len(cells), 2):  # key,value pairs; keys are looked up by name afterwards
        key = cells[i].strip()
        if not key:
            continue
        value = cells[i + 1].strip() if i + 1 < len(cells) else ""
        if key.lower() not in cols:
            meta[key] = value
            cols[key.lower()] = i + 2
    return meta, cols


def _is_blank(cells: list[str]) -> bool:
    return all(not c.strip() for c in cells)


def _locate_rows(rows: list[list[str]], path: str) -> dict[str, int]:
    """Return 0-based indices of the Type, Name, ID and component rows (axis row is last)."""
    a = len(rows) - 1
    wanted = ("type", "name", "id")
    labels = {i: (rows[i][1].strip().lower() if len(rows[i]) > 1 else "") for i in range(1, a)}
    labelled = any(lbl in wanted for lbl in labels.values())
    expected = {"type": a - 4, "name": a - 3, "id": a - 2, "component": a - 1}
    if labelled:
        at = {lbl: next((i for i, v in labels.items() if v == lbl), None) for lbl in wanted}
        for k, lbl in enumerate(wanted):
            if at[lbl] is None:  # where it should be: after the row before it, else before the row after it
                prev = at[wanted[k - 1]] if k else None
                nxt = next((at[w] for w in wanted[k + 1:] if at[w] is not None), None)
                line = prev + 2 if prev is not None else (nxt + 1 if nxt is not None else a + 1)
                raise InputError(f"missing header row '{lbl.capitalize()}' (rows Type, Name, ID and component "
                                 f"must precede the 'Frame' row at line {a + 1})", path=path, line=line, column=2)
        for lbl in wanted:
            found = [i for i, v in labels.items() if v == lbl]
            if found[0] != expected[lbl]:
                raise InputError(f"header row '{lbl.capitalize()}' is at line {found[0] + 1} but must be at line "
                                 f"{expected[lbl] + 1} (order: Type, Name, ID, component, Frame): missing header rows",
                                 path=path, line=found[0] + 1, column=2)
    elif a < 5:
        raise InputError(f"missing header rows: expected Type, Name, ID and component rows between line 1 and "
                         f"the 'Frame' row at line {a + 1}", path=path, line=a + 1, column=1)
    for i in range(1, expected["type"]):
        if not _is_blank(rows[i]):
            raise InputError("unexpected header line: only an empty line (or a row of commas) may follow line 1",
                             path=path, line=i + 1, column=1)
    if expected["type"] < 1:
        raise InputError("missing header rows above the 'Frame' row", path=path, line=a + 1, column=1)
    return expected


def _parse_header(raw: bytes, path: str) -> _Header:
    rows, ends, crlf = _header_lines(raw, path)
    meta, meta_col = _parse_metadata(rows[0], path)
    idx = _locate_rows(rows, path)
    a = len(rows) - 1
    axis = rows[a]
    hdr = {k: rows[i] for k, i in idx.items()}
    width = 2
    for r in (*hdr.values(), axis):
        stripped = len(r)
        while stripped and not r[stripped - 1].strip():
            stripped -= 1
        width = max(width, stripped)
    if len(axis) < 2 or not axis[1].strip().lower().startswith("time"):
        raise InputError("the second column must be the time column ('Time (Seconds)' or 'Time')",
                         path=path, line=a + 1, column=2)

    def cell(r: list[str], j: int) -> str:
        return r[j].strip() if j < len(r) else ""

    columns = [_Column("", "", "", "", cell(axis, 0)), _Column("", "", "", "", cell(axis, 1))]
    for j in range(2, width):
        columns.append(_Column(cell(hdr["type"], j), cell(hdr["name"], j), cell(hdr["id"], j),
                               cell(hdr["component"], j), cell(axis, j)))
    if width > 2:  # data columns exist: the rows that describe them must not be empty
        for key in ("type", "name", "component"):
            if all(not cell(hdr[key], j) for j in range(2, width)):
                raise InputError(f"missing header rows: the {key} row is empty although there are "
                                 f"{width - 2} data columns", path=path, line=idx[key] + 1, column=3)
    bodies = _group_bodies(columns, path, {k: i + 1 for k, i in idx.items()}, a + 1)
    skipped: dict[str, list[str]] = {}
    for c in columns[2:]:
        if c.type and c.type.lower() != "rigid body":
            names = skipped.setdefault(c.type, [])
            name = c.name or c.id
            if name not in names:
                names.append(name)
    return _Header(path=path, meta=meta, meta_col=meta_col, axis_line=a + 1, data_offset=ends[-1], width=width,
                   columns=columns, bodies=bodies, row_lines={k: i + 1 for k, i in idx.items()}, crlf=crlf,
                   skipped=skipped)


def _skipped_text(skipped: dict[str, list[str]]) -> str:
    """``{"Bone": [...13], "Marker": [...4]}`` -> ``13 Bone (Skeleton:Hip, ...), 4 Marker (...)``."""
    parts = []
    for kind, names in skipped.items():
        shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
        parts.append(f"{len(names)} {kind} ({shown})")
    return "; ".join(parts)


def skipped_assets(series_or_header: dict) -> dict[str, list[str]]:
    """The asset names a read skipped, by Motive column type (``meta`` of a series or a header summary)."""
    return dict(series_or_header.get("skipped") or {})


def require_rigid_bodies(series, path=None) -> None:
    """Refuse a Motive CSV with no rigid body: say what it holds and what to export instead.

    Raises
    ------
    InputError
        No rigid body in the file (markers only, skeleton bones only, or no asset at all).
    """
    if series.bodies:
        return
    skipped = skipped_assets(series.meta)
    held = _skipped_text(skipped) if skipped else "no asset columns at all"
    fix = ("in Motive, define a rigid body for the EUC and for each rider segment (the recording contract's "
           "bodies: docs/motive_csv.md) and export with 'Rigid Bodies' enabled")
    if any(k.lower().startswith("bone") for k in skipped):
        fix += ("; skeleton bones are not read: their frames are not the contract's pivots, so track the "
                "segments as rigid bodies (a skeleton may stay in the take beside them)")
    raise InputError(f"no rigid bodies in the file: it holds {held}; {fix}",
                     path=path if path is not None else series.meta.get("path"))


def _group_bodies(columns: list[_Column], path: str, lines: dict[str, int], axis_line: int) -> list[_BodyColumns]:
    groups: dict[tuple[str, str], _BodyColumns] = {}
    by_name: dict[str, _BodyColumns] = {}
    for j, c in enumerate(columns[2:], start=2):
        if c.type.lower() != "rigid body":
            continue
        key = (c.name, c.id)
        g = groups.get(key)
        if g is None:
            name = c.name or c.id
            if not name:
                raise InputError("rigid body column has neither a name nor an ID", path=path,
                                 line=lines["name"], column=j + 1)
            other = by_name.get(name)
            if other is not None:
                raise InputError(f"two rigid bodies are named {name!r} (IDs {other.id!r} at column {other.first + 1} "
                                 f"and {c.id!r})", path=path, line=lines["name"], column=j + 1)
            g = groups[key] = by_name[name] = _BodyColumns(name=name, id=c.id, first=j)
        comp, ax = c.component.lower(), c.axis.upper()
        if comp in ("rotation", "position") and ax in ("X", "Y", "Z", "W"):
            target = g.rotation if comp == "rotation" else g.position
            if ax == "W" and comp == "position":
                continue  # unknown component: skipped
            if ax in target:
                raise InputError(f"duplicate column {c.label!r} (also column {target[ax] + 1})",
                                 path=path, line=axis_line, column=j + 1)
            target[ax] = j
        elif comp in ERROR_COMPONENTS:
            if g.error is not None:
                raise InputError(f"duplicate column {c.label!r} (also column {g.error + 1})",
                                 path=path, line=lines["component"], column=j + 1)
            g.error = j
    for g in groups.values():
        for ax in "XYZ":
            if ax not in g.position:
                raise InputError(f"rigid body {g.name!r} has no 'Position {ax}' column", path=path,
                                 line=axis_line, column=g.first + 1)
            if ax not in g.rotation:
                raise InputError(f"rigid body {g.name!r} has no 'Rotation {ax}' column", path=path,
                                 line=axis_line, column=g.first + 1)
    return list(groups.values())


#: Plausible frame rates [Hz] (Motive exports 1 Hz to a few kHz); outside them times overflow or vanish.
MIN_RATE_HZ, MAX_RATE_HZ = 1e-3, 1e6


def _float_meta(hdr: _Header, key: str) -> float | None:
    value, col = hdr.get(key)
    if value is None or value == "":
        return None
    try:
        x = float(value)
    except ValueError:
        x = float("nan")
    if not np.isfinite(x) or x <= 0:
        raise InputError(f"{key} must be a positive number, got {value!r}", path=hdr.path, line=1, column=col, key=key)
    if key.endswith("Frame Rate") and not MIN_RATE_HZ <= x <= MAX_RATE_HZ:
        raise InputError(f"{key} must be between {MIN_RATE_HZ:g} and {MAX_RATE_HZ:g} Hz, got {value!r}",
                         path=hdr.path, line=1, column=col, key=key)
    return x


def _units(hdr: _Header, warnings: list[str]) -> tuple[str, float]:
    value, col = hdr.get("Length Units")
    if not value:
        warnings.append("no 'Length Units' in the header: assumed Meters")
        return "Meters", 1.0
    try:
        return LENGTH_UNITS_M[value.lower()]
    except KeyError:
        raise InputError(f"unknown Length Units {value!r} (expected Meters, Centimeters or Millimeters)",
                         path=hdr.path, line=1, column=col, key="Length Units") from None


def _rotation_type(hdr: _Header, warnings: list[str]) -> str | None:
    value, col = hdr.get("Rotation Type")
    n_rot = {len(b.rotation) for b in hdr.bodies}
    if value:
        v = value.strip()
        if v.lower().startswith("euler"):
            v = v[5:].strip(" :-_")
        if v.lower() == "quaternion":
            rot = QUATERNION
        elif v.upper() in EULER_ORDERS:
            rot = v.upper()
        else:
            raise InputError(f"unknown Rotation Type {value!r} (expected Quaternion or one of "
                             f"{', '.join(EULER_ORDERS)})", path=hdr.path, line=1, column=col, key="Rotation Type")
    elif not hdr.bodies:
        return None
    elif n_rot == {4}:
        warnings.append("no 'Rotation Type' in the header: 4 rotation columns, read as Quaternion")
        rot = QUATERNION
    elif n_rot == {3}:
        warnings.append(f"no 'Rotation Type' in the header: 3 rotation columns, assumed Euler {DEFAULT_EULER_ORDER} "
                        "(degrees)")
        rot = DEFAULT_EULER_ORDER
    else:
        raise InputError("no 'Rotation Type' in the header and rigid bodies have both 3 and 4 rotation columns",
                         path=hdr.path, line=1)
    for b in hdr.bodies:
        has_w = "W" in b.rotation
        if (rot == QUATERNION) != has_w:
            need = "X, Y, Z, W" if rot == QUATERNION else "X, Y, Z (no W)"
            raise InputError(f"Rotation Type {rot} needs rotation columns {need}, but rigid body {b.name!r} has "
                             f"{', '.join(sorted(b.rotation))}", path=hdr.path, line=hdr.axis_line,
                             column=b.first + 1)
    return rot


# -------------------------------------------------------------------------------------- data block
#: Bytes of data rows read and converted at a time, at most. The reader's working memory is a few times
#: the chunk (the chunk's text, its nan-filled copy, its float matrix and per-body temporaries) on top of
#: the arrays it returns; a file of under ``_CHUNK_BYTES * _CHUNKS_AT_LEAST`` bytes is read in that many
#: smaller chunks (not under ``_CHUNK_BYTES_MIN``), so the working memory stays a small part of its arrays.
_CHUNK_BYTES = 1 << 20
_CHUNKS_AT_LEAST = 32
_CHUNK_BYTES_MIN = 1 << 16
#: Data rows of at least this many bytes are read by the compiled parser first
#: (:mod:`~euc_ros.core.io.csv_compiled`: numpy's values bit for bit, 5-10x faster); smaller files (a live
#: replay's, a test's) by numpy alone, without loading the compiler.
_COMPILED_MIN_BYTES = 16 << 20


class _Realign(Exception):
    """A chunk needs the exact scan but is not made of whole 2048-row blocks: read again, aligned."""


def _lf(rows: bytes) -> bytes:
    """``rows`` with LF line ends."""
    return rows.replace(b"\r\n", b"\n") if b"\r" in rows else rows


class _Block:
    """The data rows of an open file, read in chunks of whole rows, with line numbering for messages.

    The rows run from the end of the header to the last byte that is not a line end (trailing line
    ends and blank lines are not rows). A first pass counts the rows (to size the result once) and
    looks for quotes; :meth:`matrices` then reads and converts the rows chunk by chunk.
    """

    def __init__(self, f, hdr: _Header) -> None:
        self.f = f
        self.hdr = hdr
        self.aligned = False  # chunks of whole 2048-row blocks (set when the exact scan needs them)
        self.first_line = hdr.axis_line + 1
        size = f.seek(0, os.SEEK_END)
        start, end = min(hdr.data_offset, size), size
        self.chunk_bytes = min(_CHUNK_BYTES, max(_CHUNK_BYTES_MIN, (end - start) // _CHUNKS_AT_LEAST))
        while end > start:  # trailing line ends and blank lines
            lo = max(start, end - 65536)
            f.seek(lo)
            kept = f.read(end - lo).rstrip(b"\r\n")
            end = lo + len(kept)
            if kept:
                break
        self.start, self.end = start, end
        self.terminated = end < size
        self.compiled = end - start >= _COMPILED_MIN_BYTES
        self._piece_lf: list[int] = []     # line ends per piece read (the second pass reads the same pieces)
        self.has_quote = False
        for piece in self._pieces():
            self._piece_lf.append(piece.count(b"\n"))
            self.has_quote = self.has_quote or b'"' in piece
        self.n_rows = sum(self._piece_lf) + 1 if end > start else 0

    def _pieces(self):
        self.f.seek(self.start)
        left = self.end - self.start
        while left > 0:
            piece = self.f.read(min(self.chunk_bytes, left))
            if not piece:
                raise InputError("the file changed while it was read", path=self.hdr.path)
            left -= len(piece)
            yield piece

    def _chunks(self):
        """``(i0, k, rows)``: rows i0 to i0 + k - 1, LF or CRLF separated, without their last line end.

        When ``self.aligned``, every chunk but the last holds a multiple of ``_CHUNK_ROWS`` rows.
        """
        i, rest, rest_lf = 0, b"", 0
        for piece, n_lf in zip(self._pieces(), self._piece_lf):
            buf = rest + piece if rest else piece
            lf = rest_lf + n_lf
            k = lf - lf % _CHUNK_ROWS if self.aligned else lf
            if not k:  # the row (or the block of rows) goes on
                rest, rest_lf = buf, lf
                continue
            if k == lf:
                cut = buf.rfind(b"\n")
            else:  # the k-th line end (the exact path only: rare)
                cut = int(np.flatnonzero(np.frombuffer(buf, dtype=np.uint8) == 10)[k - 1])
            rows, rest = buf[:cut - 1 if cut and buf[cut - 1] == 13 else cut], buf[cut + 1:]  # without its CRLF
            rest_lf = lf - k
            yield i, k, rows
            i += k
        if self.n_rows:
            yield i, rest_lf + 1, rest  # the last rows (they end on a byte that is not a line end)

    def error(self, i: int, j: int, what: str, cell: bytes | None = None) -> InputError:
        col = self.hdr.columns[j].label if j < len(self.hdr.columns) else ""
        head = f" ({col!r})" if col else ""
        shown = "" if cell is None else f": {_decode(cell)[:40]!r}"
        return InputError(f"{what}{head}{shown}", path=self.hdr.path, line=self.first_line + i, column=j + 1)

    def matrices(self):
        """``(i0, rows, m)`` per chunk: the (k, width) float matrix of rows i0.. (NaN for blank cells).

        Errors are those of one pass over the whole block: a row with too few cells (or a blank line)
        is reported first wherever it is, unless the rows hold quotes; otherwise the first bad cell.
        The exact scan works on blocks of ``_CHUNK_ROWS`` rows counted from the first row (a block
        the fast path rejects is scanned whole); a chunk that needs it but does not start and end on
        such blocks raises ``_Realign``: the caller starts again with ``aligned`` set.
        """
        width = self.hdr.width
        chunks = self._chunks()
        for i0, k, rows in chunks:
            m = None
            # The common case (every cell numeric, every row full): the compiled parser (large files), else
            # numpy's C reader, straight on the file's bytes. Both read LF and CRLF alike and give up on quoted
            # cells and rows of another width (numpy also on blank cells), and a blank line changes the row
            # count, so anything odd ends in the checked path below.
            if rows[:1] not in (b"\r", b"\n", b""):  # (a chunk of blank lines only would make numpy warn)
                m = _compiled_rows(rows, k, width) if self.compiled else None
                if m is None:
                    m = _loadtxt(rows, k, width)
            if m is None:
                data = _lf(rows)
                if self.has_quote:  # quoted cells (never written by Motive in the data rows): exact path
                    m = self._chunked(data.split(b"\n"), i0)
                else:
                    n_cells = self._check_short(data, i0)
                    try:
                        if np.any(n_cells > width):  # trailing empty cells beyond the header: exact path
                            m = self._chunked(data.split(b"\n"), i0)
                        else:
                            m = _fast(data, k, width)
                            if m is None:
                                m = self._chunked(data.split(b"\n"), i0)
                    except InputError:
                        for j0, _, later in chunks:  # a short row further on is reported first
                            self._check_short(_lf(later), j0)
                        raise
            yield i0, rows, m

    def _check_short(self, data: bytes, i0: int) -> np.ndarray:
        """Cells per row of LF-separated ``data``; InputError at the first row with too few (or a blank line)."""
        buf = np.frombuffer(data, dtype=np.uint8)
        nl = np.flatnonzero(buf == 10)
        ends = np.append(nl, len(data))
        starts = np.concatenate(([0], nl + 1))
        commas = np.flatnonzero(buf == 44)
        n_cells = np.diff(np.concatenate(([0], np.searchsorted(commas, ends)))) + 1
        short = np.flatnonzero((n_cells < self.hdr.width) | (ends == starts))
        if short.size:  # locate and report the first malformed row exactly
            i = int(short[0])
            self._scan_rows([data[starts[i]:ends[i]]], i0 + i)
            raise self.error(i0 + i, 0, "malformed row")  # not reached: the scan names the problem
        return n_cells

    def _scan_rows(self, rows: list[bytes], start: int) -> np.ndarray:
        """Slow, exact path: check every cell of ``rows`` and convert them; InputError at the first bad cell."""
        width = self.hdr.width
        out = np.full((len(rows), width), np.nan)
        for r, row in enumerate(rows):
            i = start + r
            if b'"' in row:
                cells = [c.encode("latin-1", "replace") for c in _split_cells(row.decode("latin-1"), self.hdr.path,
                                                                               self.first_line + i)]
            else:
                cells = row.split(b",")
            if not row.strip():
                raise InputError("blank line inside the data rows", path=self.hdr.path, line=self.first_line + i,
                                 column=1)
            if len(cells) < width:
                last = i == self.n_rows - 1
                what = ("truncated last line" if last else "truncated line") + \
                    f": {len(cells)} of {width} cells, missing from this column"
                raise self.error(i, len(cells), what)
            for j in range(width, len(cells)):
                if cells[j].strip():
                    raise InputError(f"cell beyond the {width} columns of the header: {_decode(cells[j])[:40]!r}",
                                     path=self.hdr.path, line=self.first_line + i, column=j + 1)
            for j in range(width):
                c = cells[j]
                if not c.strip():
                    continue
                if _NUMBER.fullmatch(c) is None:
                    raise self.error(i, j, "non-numeric cell", c)
                out[r, j] = float(c)
        return out

    def _chunked(self, rows: list[bytes], start: int) -> np.ndarray:
        """Convert row chunks quickly, scanning cell by cell only the chunks the fast path rejects."""
        if start % _CHUNK_ROWS or (len(rows) % _CHUNK_ROWS and start + len(rows) != self.n_rows):
            raise _Realign
        width = self.hdr.width
        out = np.empty((len(rows), width))
        for a in range(0, len(rows), _CHUNK_ROWS):
            chunk = rows[a:a + _CHUNK_ROWS]
            m = None
            if not any(b'"' in r for r in chunk) and all(r.count(b",") == width - 1 for r in chunk):
                m = _fast(b"\n".join(chunk), len(chunk), width)
            out[a:a + len(chunk)] = m if m is not None else self._scan_rows(chunk, start + a)
        return out


def _fill_blanks(data: bytes) -> bytes:
    """Write ``nan`` into every blank cell of LF-separated rows (vectorized insertion)."""
    buf = np.frombuffer(data, dtype=np.uint8)
    delim = (buf == 44) | (buf == 10)
    before = np.ones(buf.size + 1, bool)   # a cell starts at the data start or after a delimiter...
    before[1:] = delim
    after = np.ones(buf.size + 1, bool)    # ...and is blank if a delimiter (or the end) follows at once
    after[:-1] = delim
    at = np.flatnonzero(before & after)
    if at.size == 0:
        return data
    nan = np.frombuffer(b"nan", dtype=np.uint8)
    return np.insert(buf, np.repeat(at, 3), np.tile(nan, at.size)).tobytes()


def _fast(rows_bytes: bytes, n_rows: int, width: int) -> np.ndarray | None:
    """Convert uniform rows (``width`` cells each, LF separated) in one C pass; None if anything is odd.

    Blank cells are filled with ``nan`` first, then numpy's C text reader (``np.loadtxt`` on an
    in-memory buffer, no comments, no quotes) converts the block.
    """
    return _loadtxt(_fill_blanks(rows_bytes), n_rows, width)


def _fold_last(op, a: np.ndarray) -> np.ndarray:
    """``op`` folded over a short last axis, one call per component: ``op.reduce(a, axis=-1)`` for
    ``np.logical_and`` / ``np.logical_or`` / ``np.maximum`` (the same values, NaN propagating alike), where
    numpy's reduction over a three- or four-long axis costs several times more."""
    out = a[..., 0].copy()
    for i in range(1, a.shape[-1]):
        op(out, a[..., i], out=out)
    return out


def _compiled_rows(data: bytes, n_rows: int, width: int) -> np.ndarray | None:
    """:func:`~euc_ros.core.io.csv_compiled.parse_rows` (numba, imported on first use)."""
    from euc_ros.core.io.csv_compiled import parse_rows

    return parse_rows(data, n_rows, width)


def _loadtxt(data: bytes, n_rows: int, width: int) -> np.ndarray | None:
    """numpy's C text reader on an in-memory block; None unless it gives exactly (n_rows, width)."""
    try:
        values = np.loadtxt(io.BytesIO(data), dtype=float, delimiter=",", comments=None, ndmin=2)
    except ValueError:
        return None
    if values.shape != (n_rows, width):
        return None
    return values


class _SeriesArrays:
    """The arrays of a :class:`MocapSeries`, sized once for every data row and filled chunk by chunk.

    Each chunk's float matrix is turned into poses in place (frame check, duplicate frames dropped,
    units, gaps, quaternion normalisation or Euler conversion, axis swap) and then freed, so the
    reader never holds the whole file, nor the whole matrix of its cells.
    """

    def __init__(self, n: int, selected: list[_BodyColumns], rot_type: str | None, scale: float, world_up: str,
                 check_reach: bool) -> None:
        b = len(selected)
        self.selected, self.rot_type, self.scale, self.world_up = selected, rot_type, scale, world_up
        self.check_reach = check_reach
        self.pos_cols = np.array([[g.position[a] for a in "XYZ"] for g in selected], dtype=np.intp).reshape(b, 3)
        rot_axes = "XYZW" if rot_type == QUATERNION else "XYZ"
        self.rot_cols = np.array([[g.rotation[a] for a in rot_axes] for g in selected],
                                 dtype=np.intp).reshape(b, len(rot_axes))
        self.frame = np.empty(n, np.int64)
        self.time = np.empty(n)                 # the file's Time column [s] (checked against frame / rate)
        self.position = np.empty((b, n, 3))
        self.quat = np.empty((b, n, 4))
        self.tracked = np.empty((b, n), bool)
        self.error = np.empty((b, n))
        self.n = 0                              # rows kept so far
        self.n_rows = 0                         # rows read so far
        self.last = np.iinfo(np.int64).min      # largest frame number so far
        self.bad_frame: tuple[int, bytes] | None = None
        self.norm_error = 0.0
        self.partial = np.zeros(b, np.int64)
        self.reach = -np.inf

    def add(self, i0: int, rows: bytes, m: np.ndarray) -> None:
        """Append the rows ``i0..`` whose cells are ``m`` (text ``rows``, to quote a bad Frame cell)."""
        self.n_rows += m.shape[0]
        f = m[:, 0]
        bad = ~np.isfinite(f) | (f != np.round(f)) | (np.abs(f) > 2.0 ** 53)
        if bad.any() and self.bad_frame is None:
            i = int(np.flatnonzero(bad)[0])
            self.bad_frame = (i0 + i, _lf(rows).split(b"\n", i + 1)[i].split(b",", 1)[0])
        if self.bad_frame is not None:
            return  # the file is rejected after its last row is read (a bad cell further on is reported first)

        # Frame column: integers, duplicates / out-of-order dropped (first kept).
        frames = f.astype(np.int64)
        seen = np.maximum.accumulate(frames)
        prev_max = np.empty_like(frames)
        prev_max[0] = self.last
        np.maximum(seen[:-1], self.last, out=prev_max[1:])
        keep = frames > prev_max
        self.last = max(self.last, int(seen[-1]))
        if not keep.all():
            m, frames = m[keep], frames[keep]
        k, o = frames.size, self.n
        span = slice(o, o + k)
        self.n += k
        self.frame[span] = frames
        self.time[span] = m[:, 1]

        pos = self.position[:, span]                                   # (b, k, 3) views of the result
        pos[...] = np.moveaxis(m[:, self.pos_cols], 0, 1)             # file frame
        if self.scale != 1.0:
            pos *= self.scale                                          # -> metres
        rot = np.ascontiguousarray(np.moveaxis(m[:, self.rot_cols], 0, 1))  # (b, k, 4 or 3)
        fin_pos, fin_rot = np.isfinite(pos), np.isfinite(rot)
        finite = _fold_last(np.logical_and, fin_pos) & _fold_last(np.logical_and, fin_rot)
        some = _fold_last(np.logical_or, fin_pos) | _fold_last(np.logical_or, fin_rot)
        self.partial += (some & ~finite).sum(axis=1)
        quat = self.quat[:, span]
        if self.rot_type == QUATERNION:
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                big = _fold_last(np.maximum, np.abs(rot))[..., None]  # scale first: no overflow
                unit = rot / big
                norm = big[..., 0] * np.sqrt(np.einsum("bni,bni->bn", unit, unit))
                tracked = finite & (norm > 1e-9) & np.isfinite(norm)
                np.divide(unit, (norm / big[..., 0])[..., None], out=quat)
            if tracked.any():
                self.norm_error = max(self.norm_error, float(np.max(np.abs(norm[tracked] - 1.0))))
        else:
            tracked = finite
            quat[...] = np.nan
            if tracked.any():
                order = self.rot_type  # columns hold the angles about X, Y, Z; scipy wants them in sequence order
                angles = rot[tracked][:, ["XYZ".index(a) for a in order]]
                quat[tracked] = Rotation.from_euler(order, angles, degrees=True).as_quat()
        # overflowing nonsense is a gap too
        tracked &= _fold_last(np.logical_and, np.isfinite(quat)) & _fold_last(np.logical_and, np.isfinite(pos))
        if not tracked.all():
            pos[~tracked] = np.nan
            quat[~tracked] = np.nan
        if self.world_up == "y":  # in place: (X, Y, Z) -> (X, -Z, Y), (qx, qy, qz) -> (qx, -qz, qy)
            pos[..., 1], pos[..., 2] = -pos[..., 2], pos[..., 1].copy()
            quat[..., 1], quat[..., 2] = -quat[..., 2], quat[..., 1].copy()
        quat[quat[..., 3] < 0] *= -1.0  # canonical sign: w >= 0
        err = self.error[:, span]
        err[...] = np.nan
        for j, g in enumerate(self.selected):
            if g.error is not None:
                err[j] = m[:, g.error] * self.scale
        err[~tracked] = np.nan
        self.tracked[:, span] = tracked
        if self.check_reach and tracked.any():
            self.reach = max(self.reach, float(np.max(np.abs(pos[tracked]))))

    def trim(self) -> None:
        """Drop the rows left unused by duplicate frames, in place (no second copy of the result)."""
        n = self.n
        if n == self.frame.size:
            return
        self.frame, self.time = self.frame[:n], self.time[:n]
        for name in ("position", "quat", "tracked", "error"):
            setattr(self, name, _shrink_axis1(getattr(self, name), n))


def _shrink_axis1(a: np.ndarray, n: int) -> np.ndarray:
    """``a[:, :n]`` as a C-contiguous array in ``a``'s own memory (rows moved down body by body)."""
    b = a.shape[0]
    per = int(np.prod(a.shape[2:], dtype=np.int64)) * n
    rows = a.reshape(b, -1)
    flat = a.reshape(-1)
    for k in range(1, b):   # body k moves from k * N * ... to k * n * ...: down, so earlier bodies are safe
        flat[k * per:(k + 1) * per] = rows[k, :per]
    return flat[:b * per].reshape((b, n) + a.shape[2:])


# ------------------------------------------------------------------------------------------ reader
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


def _head_bytes(fh) -> bytes:
    """The first lines of an open file, up to the ``Frame`` row (as :func:`_header_lines` finds it).

    Reading stops at that row, after :data:`MAX_HEADER_LINES` lines, or at a line the header parser
    rejects (it reports it); the file is left positioned after the returned bytes.
    """
    lines: list[bytes] = []
    while len(lines) < MAX_HEADER_LINES:
        line = fh.readline()
        if not line:
            break
        lines.append(line)
        text = line.rstrip(b"\n")
        if text.endswith(b"\r"):
            text = text[:-1]
        if len(lines) == 1 and text.startswith(_UTF8_BOM):
            text = text[len(_UTF8_BOM):]
        try:
            cells = _split_cells(_decode(text), "", len(lines))
            if len(lines) == 1:
                _parse_metadata(cells, "")
        except InputError:
            break
        if len(lines) > 1 and cells and cells[0].strip().lower() == "frame":
            break
    return b"".join(lines)


def _check_world_up(world_up: str) -> str:
    if world_up not in ("y", "z"):
        raise ConfigError(f"must be 'y' or 'z', got {world_up!r}", key="world_up")
    return world_up


def _header_summary(hdr: _Header, warnings: list[str]) -> dict:
    units, _ = _units(hdr, warnings)
    rot = _rotation_type(hdr, warnings)
    rate = _float_meta(hdr, "Export Frame Rate")
    capture = _float_meta(hdr, "Capture Frame Rate")
    return {
        "path": hdr.path,
        "take_name": hdr.get("Take Name")[0],
        "format_version": hdr.get("Format Version")[0],
        "rate_hz": rate,
        "capture_rate_hz": capture,
        "start_time": hdr.get("Capture Start Time")[0],
        "rotation_type": rot,
        "length_units": units,
        "coordinate_space": hdr.get("Coordinate Space")[0],
        "header": dict(hdr.meta),
    }


def read_motive_header(path: str | Path) -> dict:
    """Read only the header of a Motive CSV export (cheap: the data rows are not read).

    Parameters
    ----------
    path : str or Path
        Motive CSV export.

    Returns
    -------
    dict
        ``path``, ``take_name``, ``format_version``, ``rate_hz`` (export) [Hz], ``capture_rate_hz`` [Hz],
        ``start_time`` (as written), ``rotation_type``, ``length_units``, ``coordinate_space``,
        ``header`` (all key/value pairs of line 1), ``bodies`` (rigid-body names in file order),
        ``n_columns``, ``warnings`` (assumptions made). Values missing from the file are None.

    Raises
    ------
    InputError
        Malformed header, naming the file, line and column.
    """
    p = Path(path)
    chunks: list[bytes] = []
    try:
        with open(p, "rb") as f:
            for _ in range(MAX_HEADER_LINES):
                line = f.readline()
                if not line:
                    break
                chunks.append(line)
                if line.lstrip(_UTF8_BOM).split(b",", 1)[0].strip().strip(b'"').lower() == b"frame" and len(chunks) > 1:
                    break
    except FileNotFoundError:
        raise InputError("no such file", path=p) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a Motive CSV file", path=p) from None
    hdr = _parse_header(b"".join(chunks), str(p))
    warnings: list[str] = []
    out = _header_summary(hdr, warnings)
    out["bodies"] = [b.name for b in hdr.bodies]
    out["skipped"] = {k: list(v) for k, v in hdr.skipped.items()}
    out["n_columns"] = hdr.width
    out["warnings"] = warnings
    return out


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
    Euler types are Motive's relative (intrinsic) sequences in degrees, see the module docstring.
    """
    world_up = _check_world_up(world_up)
    spath = str(path)
    try:
        with _open(path) as fh:
            hdr = _parse_header(_head_bytes(fh), spath)
            warnings: list[str] = []
            info = _header_summary(hdr, warnings)
            units, scale = LENGTH_UNITS_M[info["length_units"].lower()]
            rot_type = info["rotation_type"]

            selected = hdr.bodies
            if bodies is not None:
                by_name = {b.name: b for b in hdr.bodies}
                missing = [b for b in bodies if b not in by_name]
                if missing:
                    raise InputError(f"rigid body {missing[0]!r} not in the file (has: "
                                     f"{', '.join(by_name) or 'no rigid bodies'})", path=spath)
                selected = [by_name[b] for b in bodies]

            # The data rows, chunk by chunk, into arrays sized once (docs/motive_csv.md, "Memory").
            block = _Block(fh, hdr)
            check_reach = bool(info["header"]) and hdr.get("Length Units")[0] in (None, "")
            while True:
                out = _SeriesArrays(block.n_rows, selected, rot_type, scale, world_up, check_reach)
                try:
                    for i0, rows, m in block.matrices():
                        out.add(i0, rows, m)
                        del rows, m
                    break
                except _Realign:  # again, in whole 2048-row blocks (files with a bad or quoted cell: rare)
                    out = None
                    block.aligned = True
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
    t = frame / rate
    time_dev = float(np.nanmax(np.abs(time_col - t))) if frame.size and np.isfinite(time_col).any() else None
    del time_col
    out.time = None

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
        warnings.append(f"not read (euc_ros reads rigid bodies): {_skipped_text(unread)}")
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


# ------------------------------------------------------------------------------------------ writer
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
    """
    world_up = _check_world_up(world_up)
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
