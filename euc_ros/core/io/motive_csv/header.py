"""The header of a Motive CSV export: parsing, summary, :func:`read_motive_header` and checks.

Its key/value line and the Type, Name, ID, component and axis rows are parsed into columns grouped by
rigid body (:class:`Header`); then come its summary (rate, units, rotation type...),
:func:`read_motive_header`, and the checks of what a file holds (:func:`require_rigid_bodies`).

Also the format's constants and the ``world_up`` check that the reader and the writer share.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from euc_ros.core.errors import ConfigError, InputError

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
#: Note printed wherever the up axis is reported.
UP_AXIS_NOTE = "Motive never writes the up axis in a CSV: it is configured (session world_up), not read"

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
class BodyColumns:
    """0-based column indices of one rigid body's group.

    Parameters
    ----------
    name : str
        Rigid-body name.
    id : str
        Its ID as written.
    first : int
        Its first column.
    rotation : dict of str to int
        Rotation component (X, Y, Z, W) -> column.
    position : dict of str to int
        Position component (X, Y, Z) -> column.
    error : int, optional
        Column of the mean marker error.
    """

    name: str
    id: str
    first: int
    rotation: dict[str, int] = field(default_factory=dict)
    position: dict[str, int] = field(default_factory=dict)
    error: int | None = None


@dataclass
class Header:
    """The parsed header of a Motive CSV export (:func:`parse_header`).

    Parameters
    ----------
    path : str
        File the header was read from (for error messages).
    meta : dict of str to str
        Key/value pairs of line 1, key as written -> value (stripped).
    meta_col : dict of str to int
        Lower-case key -> 1-based column of its value on line 1.
    axis_line : int
        1-based line number of the "Frame,Time..." row.
    data_offset : int
        Byte offset of the first data row.
    width : int
        Number of columns declared by the header rows.
    columns : list of _Column
        Every column, Frame and Time first.
    bodies : list of BodyColumns
        Column groups of the rigid bodies, in file order.
    row_lines : dict of str to int
        "type"/"name"/"id"/"component" -> 1-based line number.
    crlf : bool
        Whether lines end in CRLF.
    skipped : dict of str to list of str
        Column type -> asset names not read (not rigid bodies), in file order.
    """

    path: str
    meta: dict[str, str]            # key as written -> value (stripped)
    meta_col: dict[str, int]        # lower-case key -> 1-based column of its value on line 1
    axis_line: int                  # 1-based line number of the "Frame,Time..." row
    data_offset: int                # byte offset of the first data row
    width: int                      # number of columns declared by the header rows
    columns: list[_Column]
    bodies: list[BodyColumns]
    row_lines: dict[str, int]       # "type"/"name"/"id"/"component" -> 1-based line number
    crlf: bool
    skipped: dict[str, list[str]] = field(default_factory=dict)   # column type -> asset names, file order

    def get(self, key: str) -> tuple[str | None, int | None]:
        """Value and 1-based column of metadata ``key`` (case-insensitive), or (None, None).

        Parameters
        ----------
        key : str
            Metadata key.

        Returns
        -------
        value : str or None
            Its value.
        column : int or None
            Its 1-based column on line 1.
        """
        for k, v in self.meta.items():
            if k.lower() == key.lower():
                return v, self.meta_col[k.lower()]
        return None, None


def decode(raw: bytes) -> str:
    """Decode bytes as UTF-8, falling back to Latin-1.

    Parameters
    ----------
    raw : bytes
        Encoded text.

    Returns
    -------
    str
        The decoded text.
    """
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def split_cells(text: str, path: str, line: int) -> list[str]:
    """Split one CSV line into its cells (quotes handled as :mod:`csv` does).

    Parameters
    ----------
    text : str
        The line, without its line ending.
    path : str
        File name, for the error message.
    line : int
        1-based line number, for the error message.

    Returns
    -------
    list of str
        The cells (not stripped); empty for an empty line.

    Raises
    ------
    InputError
        The line cannot be split into cells.
    """
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
        cells = split_cells(decode(line), path, len(rows) + 1)
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


def parse_header(raw: bytes, path: str) -> Header:
    """Parse the header rows at the start of a Motive CSV export.

    Parameters
    ----------
    raw : bytes
        The start of the file, at least up to and including the ``Frame`` row.
    path : str
        File name, for error messages.

    Returns
    -------
    Header
        The metadata, the columns grouped by rigid body, the skipped assets and the offset of the data rows.

    Raises
    ------
    InputError
        Malformed header, naming the file, line and column.
    """
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
    return Header(path=path, meta=meta, meta_col=meta_col, axis_line=a + 1, data_offset=ends[-1], width=width,
                   columns=columns, bodies=bodies, row_lines={k: i + 1 for k, i in idx.items()}, crlf=crlf,
                   skipped=skipped)


def skipped_text(skipped: dict[str, list[str]]) -> str:
    """``{"Bone": [...13], "Marker": [...4]}`` -> ``13 Bone (Skeleton:Hip, ...), 4 Marker (...)``.

    Parameters
    ----------
    skipped : dict of str to list of str
        Asset names by column type.

    Returns
    -------
    str
        One line.
    """
    parts = []
    for kind, names in skipped.items():
        shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
        parts.append(f"{len(names)} {kind} ({shown})")
    return "; ".join(parts)


def skipped_assets(series_or_header: dict) -> dict[str, list[str]]:
    """The asset names a read skipped, by Motive column type (``meta`` of a series or a header summary).

    Parameters
    ----------
    series_or_header : dict
        The ``meta`` mapping.

    Returns
    -------
    dict of str to list of str
        Asset names by column type.
    """
    return dict(series_or_header.get("skipped") or {})


def require_rigid_bodies(series, path=None) -> None:
    """Refuse a Motive CSV with no rigid body: say what it holds and what to export instead.

    Parameters
    ----------
    series : MocapSeries
        The recording read.
    path : str or Path, optional
        File named in the error.

    Raises
    ------
    InputError
        No rigid body in the file (markers only, skeleton bones only, or no asset at all).
    """
    if series.bodies:
        return
    skipped = skipped_assets(series.meta)
    held = skipped_text(skipped) if skipped else "no asset columns at all"
    fix = ("in Motive, define a rigid body for the EUC and for each rider segment (the recording contract's "
           "bodies: docs/motive_csv.md) and export with 'Rigid Bodies' enabled")
    if any(k.lower().startswith("bone") for k in skipped):
        fix += ("; skeleton bones are not read: their frames are not the contract's pivots, so track the "
                "segments as rigid bodies (a skeleton may stay in the take beside them)")
    raise InputError(f"no rigid bodies in the file: it holds {held}; {fix}",
                     path=path if path is not None else series.meta.get("path"))


def _group_bodies(columns: list[_Column], path: str, lines: dict[str, int], axis_line: int) -> list[BodyColumns]:
    groups: dict[tuple[str, str], BodyColumns] = {}
    by_name: dict[str, BodyColumns] = {}
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
            g = groups[key] = by_name[name] = BodyColumns(name=name, id=c.id, first=j)
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


def _float_meta(hdr: Header, key: str) -> float | None:
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


def _units(hdr: Header, warnings: list[str]) -> tuple[str, float]:
    value, col = hdr.get("Length Units")
    if not value:
        warnings.append("no 'Length Units' in the header: assumed Meters")
        return "Meters", 1.0
    try:
        return LENGTH_UNITS_M[value.lower()]
    except KeyError:
        raise InputError(f"unknown Length Units {value!r} (expected Meters, Centimeters or Millimeters)",
                         path=hdr.path, line=1, column=col, key="Length Units") from None


def _rotation_type(hdr: Header, warnings: list[str]) -> str | None:
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


def head_bytes(fh) -> bytes:
    """The first lines of an open file, up to the ``Frame`` row (as :func:`_header_lines` finds it).

    Reading stops at that row, after :data:`MAX_HEADER_LINES` lines, or at a line the header parser
    rejects (it reports it); the file is left positioned after the returned bytes.

    Parameters
    ----------
    fh : file
        The file, opened in binary mode.

    Returns
    -------
    bytes
        The header's lines.
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
            cells = split_cells(decode(text), "", len(lines))
            if len(lines) == 1:
                _parse_metadata(cells, "")
        except InputError:
            break
        if len(lines) > 1 and cells and cells[0].strip().lower() == "frame":
            break
    return b"".join(lines)


def check_world_up(world_up: str) -> str:
    """Check the configured up axis of the world frame.

    Parameters
    ----------
    world_up : str
        ``"y"`` or ``"z"``.

    Returns
    -------
    str
        ``world_up``, unchanged.

    Raises
    ------
    ConfigError
        ``world_up`` is neither ``"y"`` nor ``"z"``.
    """
    if world_up not in ("y", "z"):
        raise ConfigError(f"must be 'y' or 'z', got {world_up!r}", key="world_up")
    return world_up


def header_summary(hdr: Header, warnings: list[str]) -> dict:
    """Summarize a parsed header: rate, units, rotation type and the metadata of line 1.

    Parameters
    ----------
    hdr : Header
        Parsed header.
    warnings : list of str
        Appended to with the assumptions made (missing Length Units or Rotation Type).

    Returns
    -------
    dict
        ``path``, ``take_name``, ``format_version``, ``rate_hz`` (export) [Hz], ``capture_rate_hz`` [Hz],
        ``start_time`` (as written), ``rotation_type``, ``length_units``, ``coordinate_space``, ``header``
        (all key/value pairs of line 1). Values missing from the file are None.

    Raises
    ------
    InputError
        Invalid frame rate, Length Units or Rotation Type, or rotation columns that do not match it.
    """
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
    hdr = parse_header(b"".join(chunks), str(p))
    warnings: list[str] = []
    out = header_summary(hdr, warnings)
    out["bodies"] = [b.name for b in hdr.bodies]
    out["skipped"] = {k: list(v) for k, v in hdr.skipped.items()}
    out["n_columns"] = hdr.width
    out["warnings"] = warnings
    return out
