"""Compiled reading of a Motive CSV's data rows (numba): decimal numbers straight from the file's bytes.

Motive writes plain decimals (``-0.076868``, ``1.305007``, frame numbers): few significant digits and no
exponent. Such a number is ``m * 10^e`` with an integer ``m < 2^53`` and ``|e| <= 22``, where both ``m`` and
``10^|e|`` are exact doubles, so one multiplication or division gives the correctly rounded value (Clinger's
fast path): the double any correct reader gives, numpy's included, bit for bit. :func:`parse_rows` reads a
block of rows in one pass; anything else (a longer mantissa, a larger exponent, ``nan``, quotes, spaces, a
row of another width, a bare CR) makes it give up (None), and the caller's checked path reads the block.
Compiled on first use and cached on disk (numba ``cache=True``).
"""
from __future__ import annotations

import numba
import numpy as np

#: Powers of ten exactly representable as doubles (10^0 .. 10^22).
_POW10 = np.array([10.0 ** k for k in range(23)])


@numba.njit(cache=True, nogil=True)
def _parse(buf, n_rows, width, pow10, out):
    """Fill ``out`` (n_rows, width); returns False at the first thing outside the fast path."""
    n = buf.shape[0]
    pos = 0
    for r in range(n_rows):
        for c in range(width):
            # one cell: [sign] digits [. digits] [(e|E) [sign] digits], or blank (NaN)
            if pos >= n:
                if r == n_rows - 1 and c == width - 1:
                    out[r, c] = np.nan          # the data ends on a blank cell
                    break
                return False                    # too few rows or cells
            ch = buf[pos]
            if ch == 44 or ch == 10 or ch == 13:     # ',' or a line end right away: a blank cell
                out[r, c] = np.nan
            else:
                neg = False
                if ch == 45 or ch == 43:        # '-' or '+'
                    neg = ch == 45
                    pos += 1
                m = 0
                digits = 0                      # significant digits (leading zeros not counted)
                frac = 0
                seen = False
                while pos < n and 48 <= buf[pos] <= 57:
                    d = buf[pos] - 48
                    if digits or d:
                        digits += 1
                    m = m * 10 + d
                    seen = True
                    pos += 1
                    if digits > 15:
                        return False
                if pos < n and buf[pos] == 46:  # '.'
                    pos += 1
                    while pos < n and 48 <= buf[pos] <= 57:
                        d = buf[pos] - 48
                        if digits or d:
                            digits += 1
                        m = m * 10 + d
                        frac += 1
                        seen = True
                        pos += 1
                        if digits > 15:
                            return False
                if not seen:
                    return False                # a sign or a point alone, a letter, a quote, a space
                e = -frac
                if pos < n and (buf[pos] == 101 or buf[pos] == 69):    # 'e' or 'E'
                    pos += 1
                    eneg = False
                    if pos < n and (buf[pos] == 45 or buf[pos] == 43):
                        eneg = buf[pos] == 45
                        pos += 1
                    x = 0
                    any_ = False
                    while pos < n and 48 <= buf[pos] <= 57:
                        x = x * 10 + (buf[pos] - 48)
                        any_ = True
                        pos += 1
                        if x > 400:
                            return False
                    if not any_:
                        return False
                    e += -x if eneg else x
                v = float(m)
                if e < 0:
                    if e < -22:
                        return False
                    v = v / pow10[-e]
                elif e > 0:
                    if e > 22:
                        return False
                    v = v * pow10[e]
                out[r, c] = -v if neg else v
            # the cell's end: ',' before the next cell, a line end (or the data's end) after the last
            if pos < n:
                ch = buf[pos]
            else:
                ch = 10 if (r == n_rows - 1 and c == width - 1) else 0
            if c < width - 1:
                if ch != 44:
                    return False                # a row of too few cells, or a stray byte
                pos += 1
            else:
                if ch == 13:                    # CRLF
                    if pos + 1 < n and buf[pos + 1] == 10:
                        pos += 2
                    else:
                        return False
                elif ch == 10:
                    pos += 1
                else:
                    return False                # a row of too many cells, or a stray byte
    return pos >= n                             # every byte read: nothing after the last row


def parse_rows(data: bytes, n_rows: int, width: int) -> np.ndarray | None:
    """The (n_rows, width) float matrix of ``n_rows`` LF- or CRLF-separated rows of ``width`` cells.

    NaN for a blank cell; equal bit for bit to a correctly rounded reader's; None for anything outside the
    fast path (module docstring).

    Parameters
    ----------
    data : bytes
        The rows' text.
    n_rows : int
        Number of rows.
    width : int
        Cells per row.

    Returns
    -------
    numpy.ndarray or None
        The values (n_rows, width), or None.
    """
    buf = np.frombuffer(data, dtype=np.uint8)
    out = np.empty((n_rows, width))
    if n_rows <= 0 or width <= 0 or not _parse(buf, n_rows, width, _POW10, out):
        return None
    return out
