"""Fuzzing of the two parsers that read outside input: NatNet packets and Motive CSV files.

A mutation fuzzer (no coverage feedback; deterministic for a seed): every input is a seed from a
small corpus of valid inputs, mutated by one to four random operators (bit flips, random bytes,
interesting 32-bit values at aligned offsets, truncation, extension, deletion, duplication,
splicing two seeds; for CSV also cell, line and header edits), and for NatNet packets the header's
payload size is usually rewritten to agree with the new length so the parser goes deep. Each input
is parsed under a per-input time limit (``SIGALRM``) and classified:

``accepted``
    parsed; the result is checked for plausibility (CSV: increasing frames and times, finite
    positions and unit quaternions where tracked) and an implausible one counts as ``invalid``;
``rejected``
    a *clear* error: NatNet :class:`~euc_ros.core.io.natnet.NatNetError` with the byte offset and
    field, CSV :class:`~euc_ros.core.errors.InputError` with the file and a line or key; a rejection
    without them counts as ``unclear``;
``crash``
    any other exception (its type, message and the input are kept);
``hang``
    the time limit expired.

Rejections are grouped into classes (the message with numbers replaced by ``N``).

Seeds are written here from the protocol and file-format descriptions (``docs/natnet.md``,
docs/motive_csv.md), independently of the parsers.
"""
from __future__ import annotations

import base64
import os
import random
import re
import signal
import struct
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from euc_ros.bench.common import figure
from euc_ros.core.errors import InputError
from euc_ros.core.io.natnet import NatNetError, parse_packet

#: NatNet versions fuzzed (4.2 exercises the skip-by-byte-count path).
VERSIONS = ((3, 0), (3, 1), (4, 0), (4, 1), (4, 2))
#: Values written at aligned offsets by the ``interesting`` mutator.
INTERESTING_I32 = (0, 1, -1, 2, 3, 4, 13, 14, 255, 256, 0x7FFF, 0x8000, 0xFFFF, 0x10000, 100_000, 100_001,
                   0x7FFFFFFF, -0x80000000, -2)
#: Cell values written by the CSV ``cell`` mutator.
BAD_CELLS = ("", "nan", "NaN", "inf", "-inf", "-", "1e400", "abc", "0x10", " 1", '"', '""', "9" * 40, "-0",
             "1.5.2", "1e", "+", "1,2", "\u00e9", "\x00", "0.7071", "-1", "2147483648", "1e-320")

_NUM = re.compile(r"-?\d+(\.\d+)?(e[+-]?\d+)?", re.IGNORECASE)


# ---------------------------------------------------------------------------------------------------------------------
# NatNet seeds (from the protocol description, see docs/natnet.md)
# ---------------------------------------------------------------------------------------------------------------------

def _pkt(message_id: int, payload: bytes) -> bytes:
    return struct.pack("<HH", message_id, len(payload)) + payload


def _cstr(s: str) -> bytes:
    return s.encode() + b"\0"


def _i32(v: int) -> bytes:
    return struct.pack("<i", v)


def _sec(version, count: int, body: bytes) -> bytes:
    return _i32(count) + (_i32(len(body)) if tuple(version) >= (4, 1) else b"") + body


def natnet_frame(version, n_bodies: int = 14, frame_number: int = 1000) -> bytes:
    """A FRAMEOFDATA packet of ``n_bodies`` rigid bodies with one marker set, labeled markers, a force plate."""
    v = tuple(version)
    out = _i32(frame_number)
    out += _sec(v, 1, _cstr("all") + _i32(3) + struct.pack("<9f", *range(9)))
    out += _sec(v, 1, struct.pack("<3f", 0.5, 0.6, 0.7))
    bodies = b"".join(struct.pack("<i3f4ffh", i + 1, 0.1 * i, 1.0, -0.2 * i, 0.0, 0.0, 0.0, 1.0, 1e-4, 1)
                      for i in range(n_bodies))
    out += _sec(v, n_bodies, bodies)
    bone = struct.pack("<i3f4ffh", (5 << 16) | 1, 0, 0, 0, 0, 0, 0, 1, 1e-4, 1)
    out += _sec(v, 1, _i32(5) + _i32(1) + bone)
    if v >= (4, 1):
        out += _sec(v, 1, _i32(40) + _i32(1) + bone + _i32(1) + struct.pack("<i3ffhf", 1, 0, 0, 0, 0.01, 0, 0.0))
    out += _sec(v, 2, b"".join(struct.pack("<i3ffhf", k, 0.1, 0.2, 0.3, 0.014, 0, 1e-4) for k in range(2)))
    out += _sec(v, 1, _i32(7) + _i32(1) + _i32(2) + struct.pack("<2f", 1.0, 2.0))
    out += _sec(v, 0, b"")
    out += struct.pack("<IIdQQQ", 1, 0, 10.5, 1_000_000, 1_000_500, 1_001_000)
    if v >= (4, 1):
        out += struct.pack("<II", 1_700_000_000, 5)
    out += struct.pack("<h", 0) + _i32(0)
    return _pkt(7, out)


def natnet_modeldef(version, n_bodies: int = 14) -> bytes:
    """A MODELDEF packet: a marker set, ``n_bodies`` rigid bodies, a skeleton, a camera (and an asset at 4.1+)."""
    v = tuple(version)

    def ds(dtype: int, body: bytes) -> bytes:
        return _i32(dtype) + (_i32(len(body)) if v >= (4, 1) else b"") + body

    def rb_desc(name: str, rb_id: int, n_markers: int) -> bytes:
        out = _cstr(name) + struct.pack("<ii3f", rb_id, -1, 0.0, 0.0, 0.0) + _i32(n_markers)
        out += b"".join(struct.pack("<3f", 0.01 * k, 0, 0) for k in range(n_markers))
        out += b"".join(_i32(k) for k in range(n_markers))
        if v[0] >= 4:
            out += b"".join(_cstr(f"{name}_{k}") for k in range(n_markers))
        return out

    sets = [ds(0, _cstr("all") + _i32(2) + _cstr("m1") + _cstr("m2"))]
    sets += [ds(1, rb_desc(f"B{i}", i + 1, 3)) for i in range(n_bodies)]
    sets.append(ds(2, _cstr("Skel") + _i32(5) + _i32(1) + rb_desc("bone", (5 << 16) | 1, 1)))
    sets.append(ds(5, _cstr("Cam") + struct.pack("<3f4f", 0, 0, 0, 0, 0, 0, 1)))
    if v >= (4, 1):
        sets.append(ds(6, _cstr("Asset") + _i32(0) + _i32(40) + _i32(1) + rb_desc("arb", 41, 1) + _i32(1)
                       + _cstr("am") + struct.pack("<i3ffh", 1, 0, 0, 0, 0.01, 0)))
    return _pkt(5, _i32(len(sets)) + b"".join(sets))


def natnet_server_info(version=(4, 1)) -> bytes:
    """A SERVERINFO packet announcing NatNet ``version``."""
    payload = b"Motive".ljust(256, b"\0") + bytes((3, 1, 0, 0)) + bytes((*version, 0, 0))
    return _pkt(1, payload + struct.pack("<QHB4B", 10_000_000, 1511, 1, 239, 255, 42, 99))


def natnet_seeds() -> list[tuple[bytes, tuple[int, int]]]:
    """The NatNet seed corpus: ``(packet, version)`` pairs."""
    seeds = []
    for v in VERSIONS:
        seeds += [(natnet_frame(v), v), (natnet_frame(v, n_bodies=1), v), (natnet_modeldef(v), v)]
    seeds += [(natnet_server_info((4, 1)), (4, 1)), (natnet_server_info((3, 0)), (3, 0)),
              (_pkt(8, _cstr("hello")), (4, 1)), (_pkt(3, _i32(0)), (4, 1)), (_pkt(3, _cstr("OK")), (4, 1)),
              (_pkt(100, b""), (4, 1))]
    return seeds


# ---------------------------------------------------------------------------------------------------------------------
# Motive CSV seeds (docs/motive_csv.md)
# ---------------------------------------------------------------------------------------------------------------------

def _csv_header(rate: str, bodies: list[str], rot: str, units: str, n_rot: int, extra_meta: str = "") -> list[str]:
    meta = (f"Format Version,1.23,Take Name,fuzz,Capture Frame Rate,{rate},Export Frame Rate,{rate},"
            f"Capture Start Time,2024-05-02 10.15.00.000 AM,Total Frames in Take,10,Total Exported Frames,10,"
            f"Rotation Type,{rot},Length Units,{units},Coordinate Space,Global{extra_meta}")
    rot_axes = ["X", "Y", "Z", "W"][:n_rot]
    types, names, ids, kinds, comps = [""], [""], [""], [""], ["Frame", "Time (Seconds)"]
    for i, b in enumerate(bodies):
        cols = [("Rotation", a) for a in rot_axes] + [("Position", a) for a in "XYZ"] + [("Mean Marker Error", "")]
        for kind, comp in cols:
            types.append("Rigid Body")
            names.append(b)
            ids.append(str(i + 1))
            kinds.append(kind)
            comps.append(comp)
    types, names, ids, kinds = (["", *x[1:]] for x in (types, names, ids, kinds))
    return [meta, "", ",".join(["", "Type", *types[1:]]), ",".join(["", "Name", *names[1:]]),
            ",".join(["", "ID", *ids[1:]]), ",".join(["", "", *kinds[1:]]), ",".join(comps)]


def csv_seeds() -> list[bytes]:
    """The Motive CSV seed corpus: quaternion (with an occluded cell block), Euler XYZ in mm, CRLF + BOM."""
    rng = np.random.default_rng(5)
    seeds = []
    for rot, units, n_rot, scale in (("Quaternion", "Meters", 4, 1.0), ("XYZ", "Millimeters", 3, 1000.0)):
        bodies = ["E", "H", "TL"]
        lines = _csv_header("120.000000", bodies, rot, units, n_rot)
        for k in range(10):
            row = [str(k), f"{k / 120:.6f}"]
            for j in range(len(bodies)):
                if rot == "Quaternion":
                    q = rng.normal(size=4)
                    q /= np.linalg.norm(q)
                    r = [f"{x:.6f}" for x in q]
                else:
                    r = [f"{x:.4f}" for x in rng.uniform(-30, 30, 3)]
                p = [f"{x * scale:.6f}" for x in rng.uniform(-1, 1, 3)]
                block = r + p + [f"{0.0002 * scale:.6f}"]
                if k == 4 and j == 1:
                    block = [""] * len(block)   # occluded
                row += block
            lines.append(",".join(row))
        seeds.append(("\n".join(lines) + "\n").encode())
    seeds.append(b"\xef\xbb\xbf" + seeds[0].replace(b"\n", b"\r\n"))
    return seeds


# ---------------------------------------------------------------------------------------------------------------------
# Mutation
# ---------------------------------------------------------------------------------------------------------------------

def _mutate_bytes(data: bytearray, rng: random.Random, corpus: list[bytes]) -> bytearray:
    n = len(data)
    op = rng.randrange(9)
    if op == 0 and n:                                     # bit flips
        for _ in range(rng.randint(1, 8)):
            data[rng.randrange(n)] ^= 1 << rng.randrange(8)
    elif op == 1 and n:                                   # random bytes
        for _ in range(rng.randint(1, 4)):
            data[rng.randrange(n)] = rng.randrange(256)
    elif op == 2 and n >= 4:                              # interesting int32 at an aligned offset
        at = rng.randrange(0, n - 3) & ~3 if rng.random() < 0.7 else rng.randrange(0, n - 3)
        struct.pack_into("<i", data, at, rng.choice(INTERESTING_I32))
    elif op == 3 and n:                                   # truncate
        del data[rng.randrange(n):]
    elif op == 4:                                         # extend
        data += bytes(rng.randrange(256) for _ in range(rng.randint(1, 64)))
    elif op == 5 and n:                                   # delete a slice
        a = rng.randrange(n)
        del data[a:a + rng.randint(1, 32)]
    elif op == 6 and n:                                   # duplicate a slice
        a = rng.randrange(n)
        b = min(n, a + rng.randint(1, 64))
        data[a:a] = data[a:b]
    elif op == 7 and corpus:                              # splice with another seed
        other = rng.choice(corpus)
        a, b = rng.randrange(len(data) + 1), rng.randrange(len(other) + 1)
        data = data[:a] + bytearray(other[b:])
    elif n:                                               # overwrite a run with one value
        a = rng.randrange(n)
        v = rng.choice((0, 0xFF, 0x7F, 0x80))
        for i in range(a, min(n, a + rng.randint(1, 16))):
            data[i] = v
    return data


def mutate_natnet(seed: bytes, rng: random.Random, corpus: list[bytes]) -> bytes:
    """One to four byte mutations; the header's size usually rewritten to the new payload length."""
    data = bytearray(seed)
    for _ in range(rng.randint(1, 4)):
        data = _mutate_bytes(data, rng, corpus)
    if len(data) >= 4 and rng.random() < 0.75:
        struct.pack_into("<H", data, 2, min(len(data) - 4, 0xFFFF))
    return bytes(data)


def _mutate_csv_structure(data: bytes, rng: random.Random) -> bytes:
    lines = data.split(b"\n")
    op = rng.randrange(7)
    i = rng.randrange(len(lines))
    if op == 0:                                           # a cell replaced
        cells = lines[i].split(b",")
        cells[rng.randrange(len(cells))] = rng.choice(BAD_CELLS).encode("utf-8")
        lines[i] = b",".join(cells)
    elif op == 1:                                         # a line deleted
        del lines[i]
    elif op == 2:                                         # a line duplicated
        lines.insert(i, lines[i])
    elif op == 3:                                         # two lines swapped
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    elif op == 4:                                         # a cell dropped or added
        cells = lines[i].split(b",")
        if rng.random() < 0.5 and len(cells) > 1:
            del cells[rng.randrange(len(cells))]
        else:
            cells.insert(rng.randrange(len(cells) + 1), rng.choice(BAD_CELLS).encode("utf-8"))
        lines[i] = b",".join(cells)
    elif op == 5:                                         # a header value replaced
        cells = lines[0].split(b",")
        k = rng.randrange(1, len(cells), 2) if len(cells) > 1 else 0
        cells[k] = rng.choice((*BAD_CELLS, "XYZ", "ZYX", "Quaternion", "Centimeters", "Inches", "0", "-120"))\
            .encode("utf-8")
        lines[0] = b",".join(cells)
    else:                                                 # a line of separators inserted
        lines.insert(i, b"," * rng.randint(0, 40))
    return b"\n".join(lines)


def mutate_csv(seed: bytes, rng: random.Random, corpus: list[bytes]) -> bytes:
    """One to three structural or byte mutations."""
    data = seed
    for _ in range(rng.randint(1, 3)):
        data = _mutate_csv_structure(data, rng) if rng.random() < 0.6 else bytes(
            _mutate_bytes(bytearray(data), rng, corpus))
    return data


# ---------------------------------------------------------------------------------------------------------------------
# Targets and classification
# ---------------------------------------------------------------------------------------------------------------------

class _Timeout(BaseException):
    """Raised by SIGALRM inside a parse that ran past its time limit."""


def rejection_class(message: str) -> str:
    """The message with numbers replaced by ``N`` and quoted cell contents by ``'...'`` (a class key)."""
    msg = re.sub(r"'[^']*'", "'...'", message)
    msg = re.sub(r'"[^"]*"', '"..."', msg)
    return _NUM.sub("N", msg)[:160]


def check_natnet(data: bytes, version) -> tuple[str, str | None]:
    """Parse one packet; ``(outcome, class)`` with outcome accepted / rejected / unclear."""
    try:
        parse_packet(data, version)
    except NatNetError as exc:
        clear = exc.offset is not None and bool(exc.field)
        return ("rejected" if clear else "unclear"), rejection_class(f"{exc.field}: {exc.detail}")
    return "accepted", None


def implausibility(s) -> str | None:
    """Why an accepted series is implausible (None if it is fine).

    Frames and times must be strictly increasing and times finite; tracked poses finite, with unit
    quaternions of w >= 0; untracked poses NaN.
    """
    if s.t.size != s.frame.size:
        return "t and frame differ in length"
    if not np.all(np.isfinite(s.t)):
        return "non-finite time"
    if s.frame.size > 1 and not np.all(np.diff(s.frame) > 0):
        return "frames not increasing"
    if s.frame.size > 1 and not np.all(np.diff(s.t) > 0):
        return "times not increasing"
    tr = s.tracked
    if not np.all(np.isfinite(s.position[tr])) or not np.all(np.isfinite(s.quat[tr])):
        return "non-finite tracked pose"
    if not np.all(np.abs(np.linalg.norm(s.quat[tr], axis=-1) - 1.0) < 1e-6) or not np.all(s.quat[tr][..., 3] >= 0):
        return "quaternion not unit or w < 0"
    if not np.all(np.isnan(s.position[~tr])):
        return "untracked pose not NaN"
    return None


def check_csv(data: bytes, path: Path, world_up: str = "y") -> tuple[str, str | None]:
    """Write ``data`` to ``path`` and read it; ``(outcome, class)``; outcome also ``invalid`` (implausible result)."""
    from euc_ros.core.io.motive_csv import read_motive_csv

    path.write_bytes(data)
    try:
        s = read_motive_csv(path, world_up=world_up)
    except InputError as exc:
        clear = exc.path is not None and (exc.line is not None or exc.key is not None)
        return ("rejected" if clear else "unclear"), rejection_class(exc.detail)
    why = implausibility(s)
    return ("accepted", None) if why is None else ("invalid", why)


# ---------------------------------------------------------------------------------------------------------------------
# Runner
# ---------------------------------------------------------------------------------------------------------------------

def fuzz(kind: str, n_inputs: int, *, time_budget_s: float = 60.0, seed: int = 0, per_input_timeout_s: float = 1.0,
         crash_dir: str | None = None) -> dict:
    """Run the mutation fuzzer on ``kind`` (``"natnet"`` or ``"csv"``).

    Parameters
    ----------
    kind : {"natnet", "csv"}
    n_inputs : int
        Inputs to try (the run also stops after ``time_budget_s``).
    time_budget_s : float
        Wall-clock budget [s].
    seed : int
        Seed of the mutation choices (equal seeds give equal inputs).
    per_input_timeout_s : float
        An input whose parse takes longer is a hang [s].
    crash_dir : str, optional
        Where crashing and hanging inputs are written (``<kind>_<n>.bin``).

    Returns
    -------
    dict
        ``inputs``, ``wall_s``, ``inputs_per_s``, counts per outcome (``accepted``, ``rejected``,
        ``unclear``, ``invalid``, ``crash``, ``hang``), ``classes`` (rejection class -> count, most
        common first), ``rejection_classes`` (their number), ``invalid_classes`` (why accepted
        results were implausible -> count), ``failures`` (up to 20: outcome, error, base64 input),
        ``max_input_s``.
    """
    rng = random.Random(seed)
    counts = Counter()
    classes: Counter = Counter()
    invalid: Counter = Counter()
    failures = []
    tmpdir = None
    if kind == "natnet":
        corpus = natnet_seeds()
        raw = [d for d, _ in corpus]
    elif kind == "csv":
        raw = csv_seeds()
        base = Path("/dev/shm") if os.access("/dev/shm", os.W_OK) else None
        tmpdir = tempfile.TemporaryDirectory(prefix="euc_fuzz_", dir=base)
        path = Path(tmpdir.name) / "input.csv"
    else:
        raise ValueError(f"unknown fuzz target {kind!r}")

    def on_alarm(signum, frame):
        raise _Timeout

    old = signal.signal(signal.SIGALRM, on_alarm)
    t0 = time.perf_counter()
    max_input = 0.0
    n = 0
    try:
        while n < n_inputs and time.perf_counter() - t0 < time_budget_s:
            n += 1
            if kind == "natnet":
                seed_bytes, version = corpus[rng.randrange(len(corpus))]
                if rng.random() < 0.1:
                    version = rng.choice(VERSIONS)
                data = mutate_natnet(seed_bytes, rng, raw)
            else:
                data = mutate_csv(raw[rng.randrange(len(raw))], rng, raw)
            ts = time.perf_counter()
            signal.setitimer(signal.ITIMER_REAL, per_input_timeout_s)
            try:
                if kind == "natnet":
                    outcome, cls = check_natnet(data, version)
                else:
                    outcome, cls = check_csv(data, path, "y" if rng.random() < 0.8 else "z")
            except _Timeout:
                outcome, cls, err = "hang", None, f"no result within {per_input_timeout_s:g} s"
            except Exception as exc:   # a crash: anything but the documented error
                outcome, cls, err = "crash", None, f"{type(exc).__name__}: {exc}"
            else:
                err = cls
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            max_input = max(max_input, time.perf_counter() - ts)
            counts[outcome] += 1
            if cls is not None and outcome in ("rejected", "unclear"):
                classes[cls] += 1
            elif cls is not None and outcome == "invalid":
                invalid[cls] += 1
            if outcome in ("crash", "hang", "unclear", "invalid") and len(failures) < 20:
                failures.append({"outcome": outcome, "error": err, "input_b64": base64.b64encode(data).decode()})
                if crash_dir:
                    Path(crash_dir).mkdir(parents=True, exist_ok=True)
                    (Path(crash_dir) / f"{kind}_{outcome}_{n}.bin").write_bytes(data)
    finally:
        signal.signal(signal.SIGALRM, old)
        if tmpdir is not None:
            tmpdir.cleanup()
    wall = time.perf_counter() - t0
    out = {"kind": kind, "inputs": n, "wall_s": wall, "inputs_per_s": n / wall if wall > 0 else 0.0,
           "max_input_s": max_input, "seeds": len(raw), "rejection_classes": len(classes),
           "classes": dict(classes.most_common()), "invalid_classes": dict(invalid.most_common()),
           "failures": failures}
    for k in ("accepted", "rejected", "unclear", "invalid", "crash", "hang"):
        out[k] = int(counts[k])
    return out


# ---------------------------------------------------------------------------------------------------------------------
# Benchmark
# ---------------------------------------------------------------------------------------------------------------------

#: Inputs and time budgets [s] per target: full and --quick.
INPUTS = {False: {"natnet": 500_000, "csv": 200_000}, True: {"natnet": 10_000, "csv": 2_000}}
BUDGET_S = {False: {"natnet": 120.0, "csv": 180.0}, True: {"natnet": 5.0, "csv": 5.0}}


def run(ctx) -> dict:
    """The fuzz job of ``euc-ros bench``: NatNet and CSV, each in its own interpreter."""
    t_start = time.monotonic()
    figures, rss, details = [], {}, {}
    for kind in ("natnet", "csv"):
        n, budget = INPUTS[ctx.quick][kind], BUDGET_S[ctx.quick][kind]
        ctx.log(f"  fuzz {kind}: up to {n} inputs in {budget:g} s")
        r = ctx.isolated("euc_ros.bench.fuzz:fuzz", kind=kind, n_inputs=n, time_budget_s=budget, seed=1,
                         crash_dir=str(ctx.tmp_dir / "fuzz_failures"), timeout_s=budget + 120)
        bad = r["crash"] + r["hang"] + r["unclear"] + r["invalid"]
        figures.append(figure(f"{kind}: inputs, failures", r["inputs"], "inputs",
                              target="0 crash, hang, unclear, invalid", met=bad == 0,
                              note=f"{r['inputs_per_s']:.0f} inputs/s; accepted {r['accepted']}, rejected "
                                   f"{r['rejected']} in {r['rejection_classes']} classes; crash {r['crash']}, hang "
                                   f"{r['hang']}, unclear {r['unclear']}, invalid {r['invalid']}"
                                   + (f" ({', '.join(f'{k}: {v}' for k, v in r['invalid_classes'].items())})"
                                      if r["invalid"] else "")
                                   + f"; slowest input {r['max_input_s'] * 1e3:.1f} ms"))
        rss[f"fuzz {kind}"] = r["peak_rss_mb"]
        details[kind] = r
    total = sum(d["inputs"] for d in details.values())
    return {"name": "fuzz", "title": f"Fuzzing NatNet packets and Motive CSV files ({total} inputs)",
            "figures": figures, "peak_rss_mb": rss, "details": details, "wall_s": time.monotonic() - t_start}
