"""The compiled reader of a Motive CSV's data rows against numpy's text reader, bit for bit, and the
whole reader with and without it on generated and real files."""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.io import motive_csv
from euc_ros.core.io.csv_compiled import parse_rows
from euc_ros.core.io.motive_csv import block as motive_block

REAL = Path(__file__).resolve().parents[4].parent / "shared" / "data" / "motive_real"
needs_real = pytest.mark.skipif(not REAL.is_dir(), reason=f"real Motive exports not available ({REAL} is absent)")


def _numpy(text: bytes, width: int) -> np.ndarray:
    """numpy's reading of the same rows (blank cells as nan, as the reader's checked path fills them)."""
    rows = [",".join(c if c else "nan" for c in line.split(",")) for line in text.decode().splitlines()]
    return np.loadtxt(io.StringIO("\n".join(rows)), dtype=float, delimiter=",", ndmin=2).reshape(-1, width)


def _text(values: np.ndarray, fmt: str, blank=None, eol: str = "\n") -> bytes:
    lines = []
    for r, row in enumerate(values):
        cells = [fmt % v for v in row]
        if blank is not None:
            cells = ["" if blank[r, c] else x for c, x in enumerate(cells)]
        lines.append(",".join(cells))
    return eol.join(lines).encode()


@pytest.mark.parametrize("fmt", ["%.6f", "%.3f", "%.8f", "%d", "%.15g", "%.6e", "%.2E"])
@pytest.mark.parametrize("eol", ["\n", "\r\n"])
def test_equal_to_numpy_bit_for_bit(fmt, eol):
    rng = np.random.default_rng(len(fmt) + len(eol))
    values = rng.normal(0.0, 2.0, (300, 9)) * 10.0 ** rng.integers(-5, 4, (300, 9))
    if fmt == "%d":
        values = np.round(values * 1000)
    values[::17, 3] = -0.0
    blank = rng.random(values.shape) < 0.05
    text = _text(values, fmt, blank, eol)
    got = parse_rows(text, 300, 9)
    assert got is not None
    want = _numpy(text, 9)
    assert np.array_equal(got, want, equal_nan=True)
    assert np.array_equal(np.signbit(got), np.signbit(want))      # -0.0 stays negative


@pytest.mark.parametrize("text", [
    b'1.0,"2.0",3.0',               # a quote
    b"1.0, 2.0,3.0",                # a space
    b"1.0,nan,3.0",                 # a word
    b"1.0,2.0",                     # too few cells
    b"1.0,2.0,3.0,4.0",             # too many cells
    b"1.0,2.0,3.0\r",               # a bare CR
    b"1.0,1234567890123456,3.0",    # 16 significant digits (beyond the exact path)
    b"1.0,1e23,3.0",                # a power of ten beyond 10^22
    b"1.0,1e,3.0",                  # an exponent without digits
    b"1.0,-,3.0",                   # a sign alone
    b"1.0,2.0x,3.0",                # a stray byte
])
def test_anything_outside_the_fast_path_is_given_up(text):
    assert parse_rows(text, 1, 3) is None


def test_two_rows_asked_of_one_is_given_up():
    assert parse_rows(b"1,2,3", 2, 3) is None


def _both(path: Path, monkeypatch):
    """The reader with the compiled path on every file, and with numpy's alone."""
    monkeypatch.setattr(motive_block, "_COMPILED_MIN_BYTES", 0)
    fast = motive_csv.read_motive_csv(path)
    monkeypatch.setattr(motive_block, "_COMPILED_MIN_BYTES", 1 << 62)
    slow = motive_csv.read_motive_csv(path)
    return fast, slow


def _assert_same(a, b):
    for k in ("t", "frame", "position", "quat", "tracked", "mean_marker_error"):
        assert np.array_equal(getattr(a, k), getattr(b, k), equal_nan=True), k
    assert a.bodies == b.bodies and a.meta["warnings"] == b.meta["warnings"]


def test_a_generated_ride_reads_the_same_with_and_without_it(short_ride, monkeypatch):
    out, _ = short_ride
    _assert_same(*_both(next(out.glob("*.csv")), monkeypatch))


@needs_real
@pytest.mark.shared
@pytest.mark.parametrize("name", sorted(p.name for p in REAL.glob("*.csv")) if REAL.is_dir() else [])
def test_real_exports_read_the_same_with_and_without_it(name, monkeypatch):
    """Real exports (CRLF, quoted header cells, occlusions, Euler angles, millimetres): where a file is
    outside the fast path the checked path reads it, so the result is the same either way."""
    try:
        fast, slow = _both(REAL / name, monkeypatch)
    except Exception as e:                      # a file the reader refuses is refused alike by both
        monkeypatch.setattr(motive_block, "_COMPILED_MIN_BYTES", 1 << 62)
        with pytest.raises(type(e)):
            motive_csv.read_motive_csv(REAL / name)
        return
    _assert_same(fast, slow)
