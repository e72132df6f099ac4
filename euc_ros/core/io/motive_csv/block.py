"""The data block of a Motive CSV export: the rows after the header, read by :func:`read_rows`.

The rows are read in chunks of about 1 MB and converted by the compiled parser or numpy's C reader (a
per-cell scan only where they fail, to name the line and column of an error), then turned into poses in
place in arrays sized once.
"""
from __future__ import annotations

import io
import os
import re

import numpy as np
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import InputError
from euc_ros.core.io.motive_csv.header import QUATERNION, BodyColumns, Header, decode, split_cells

#: Rows per chunk when an error has to be located.
_CHUNK_ROWS = 2048

_NUMBER = re.compile(rb"\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)\s*", re.IGNORECASE)

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

    def __init__(self, f, hdr: Header) -> None:
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
        shown = "" if cell is None else f": {decode(cell)[:40]!r}"
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
                cells = [c.encode("latin-1", "replace") for c in split_cells(row.decode("latin-1"), self.hdr.path,
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
                    raise InputError(f"cell beyond the {width} columns of the header: {decode(cells[j])[:40]!r}",
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
    """``op`` folded over a short last axis, one call per component.

    This is ``op.reduce(a, axis=-1)`` for ``np.logical_and`` / ``np.logical_or`` / ``np.maximum`` (the same
    values, NaN propagating alike), where numpy's reduction over a three- or four-long axis costs several
    times more.
    """
    out = a[..., 0].copy()
    for i in range(1, a.shape[-1]):
        op(out, a[..., i], out=out)
    return out


def _compiled_rows(data: bytes, n_rows: int, width: int) -> np.ndarray | None:
    """:func:`~euc_ros.core.io.csv_compiled.parse_rows` (numba, imported on first use)."""
    from euc_ros.core.io.csv_compiled import parse_rows

    return parse_rows(data, n_rows, width)


def _loadtxt(data: bytes, n_rows: int, width: int) -> np.ndarray | None:
    """With numpy's C text reader, convert an in-memory block; None unless it gives exactly (n_rows, width)."""
    try:
        values = np.loadtxt(io.BytesIO(data), dtype=float, delimiter=",", comments=None, ndmin=2)
    except ValueError:
        return None
    if values.shape != (n_rows, width):
        return None
    return values


class _SeriesArrays:
    """The arrays of a :class:`~euc_ros.core.mocap.series.MocapSeries`, sized once and filled chunk by chunk.

    The arrays have room for every data row.

    Each chunk's float matrix is turned into poses in place (frame check, duplicate frames dropped,
    units, gaps, quaternion normalisation or Euler conversion, axis swap) and then freed, so the
    reader never holds the whole file, nor the whole matrix of its cells.
    """

    def __init__(self, n: int, selected: list[BodyColumns], rot_type: str | None, scale: float, world_up: str,
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


def read_rows(fh, hdr: Header, selected: list[BodyColumns], rot_type: str | None, scale: float, world_up: str,
              check_reach: bool) -> tuple[_Block, _SeriesArrays]:
    """The data rows of the open file ``fh``, chunk by chunk, into arrays sized once (docs/motive_csv.md, "Memory").

    Returns the block (row count, line numbering, :meth:`_Block.error`) and the filled arrays; a file the
    exact scan has to read in whole 2048-row blocks is read again, aligned.

    Parameters
    ----------
    fh : file
        The file, opened in binary mode, positioned at the first data row.
    hdr : Header
        Its parsed header.
    selected : list of BodyColumns
        The bodies to read.
    rot_type : str or None
        Rotation type of the file: quaternion, or the Euler sequence of its angle columns [deg].
    scale : float
        Factor of the positions to metres.
    world_up : str
        ``"y"`` or ``"z"``: the file's up axis.
    check_reach : bool
        Keep the largest tracked coordinate magnitude (the block's ``reach``) for the caller's check.

    Returns
    -------
    block : _Block
        Row count and line numbering.
    arrays : _SeriesArrays
        The filled arrays.
    """
    block = _Block(fh, hdr)
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
    return block, out
