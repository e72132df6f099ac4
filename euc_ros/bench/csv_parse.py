"""Benchmark 3: Motive CSV parse rate (frames per second) of ``read_motive_csv``, 14 rigid bodies.

The file is the benchmark recording (simulated, 120 Hz, 14 bodies of 8 columns: 114 columns per
row; 10 minutes, or 1 minute with ``--quick``). ``read_motive_csv`` parses the header, every cell,
validates the frame column, converts Y-up to Z-up and normalises the quaternions.

Floor: ``numpy.loadtxt(path, delimiter=",", skiprows=<header lines>)`` reading the same numbers
into one float array and nothing else. Each runs in a fresh interpreter on one core, :data:`REPEATS` times
(the rate is the fastest call's).

Memory: each measurement also reports how far its call raised the resident set above the
interpreter's (``VmHWM`` after the call minus ``VmRSS`` before it, the high-water mark reset at the
start: :func:`~euc_ros.bench.common.peak_rss_increase`), so imports are not counted: the reader's compiled
parser (:mod:`~euc_ros.core.io.csv_compiled`, used from 16 MB of data rows) is imported and its compiled
code loaded before, as the reader's module is (numba's runtime, about 100 MB that a process pays once;
reported in the note). The second figure compares the reader's increase with the loader's; the target is at
most 1.5x.
"""
from __future__ import annotations

import os
import time

import numpy as np

from euc_ros.bench.common import BenchContext, BenchError, figure, peak_rss_increase, pinned_to_one_core
from euc_ros.bench.data import ride_recording

#: Recording lengths [s]: full and --quick.
DURATION_S = {False: 600.0, True: 60.0}
#: Target of the memory figure: the reader's peak RSS increase over numpy.loadtxt's on the same file.
MEMORY_TARGET_RATIO = 1.5
#: Timed calls of each reader: the rate is the fastest's (one call alone moved 2x with the VM's other load);
#: the memory is the first call's.
REPEATS = 3


def header_lines(path: str) -> int:
    """Number of lines up to and including the ``Frame,Time,...`` row."""
    with open(path, "rb") as f:
        for i, line in enumerate(f, start=1):
            if line.split(b",", 1)[0].strip().strip(b'"').lower() == b"frame" and i > 1:
                return i
    raise ValueError(f"{path}: no Frame row")


def measure_ours(path: str) -> dict:
    """``read_motive_csv`` on one core: ``{"wall_s", "frames", "bodies", "rss"}`` (``rss``: peak_rss_increase)."""
    from euc_ros.core.io.motive_csv import read_motive_csv

    before = _rss_mb()
    from euc_ros.core.io.csv_compiled import parse_rows

    parse_rows(b"0", 1, 1)              # the compiled parser's one-time import and load (as the reader's import)
    runtime_mb = _rss_mb() - before
    with pinned_to_one_core():
        with peak_rss_increase() as rss:
            walls, s = _timed(lambda: read_motive_csv(path, world_up="y"))
        frames, bodies = int(s.n_frames), len(s.bodies)
        del s
        walls += [_timed(lambda: read_motive_csv(path, world_up="y"))[0][0] for _ in range(REPEATS - 1)]
    return {"wall_s": min(walls), "walls_s": walls, "frames": frames, "bodies": bodies, "rss": rss,
            "compiled_runtime_mb": runtime_mb}


def _timed(call) -> tuple[list[float], object]:
    """``([wall time of call()], its result)``."""
    t0 = time.perf_counter()
    out = call()
    return [time.perf_counter() - t0], out


def _rss_mb() -> float:
    """The resident set now [MB] (``VmRSS``)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def measure_numpy(path: str) -> dict:
    """``numpy.loadtxt`` of the data rows on one core: ``{"wall_s", "frames", "columns", "rss"}``."""
    skip = header_lines(path)
    with pinned_to_one_core():
        with peak_rss_increase() as rss:
            walls, a = _timed(lambda: np.loadtxt(path, delimiter=",", skiprows=skip, dtype=float))
        shape = a.shape
        del a
        walls += [_timed(lambda: np.loadtxt(path, delimiter=",", skiprows=skip, dtype=float))[0][0]
                  for _ in range(REPEATS - 1)]
    return {"wall_s": min(walls), "walls_s": walls, "frames": int(shape[0]), "columns": int(shape[1]), "rss": rss}


def memory_figure(ours: dict, floor: dict) -> dict:
    """The reader's peak RSS increase against numpy.loadtxt's (``rss`` of the two measurements) [MB]."""
    mem, mem_floor = ours["rss"]["increase_mb"], floor["rss"]["increase_mb"]
    met = None if mem is None or not mem_floor else mem <= MEMORY_TARGET_RATIO * mem_floor
    reset = ours["rss"]["hwm_reset"] and floor["rss"]["hwm_reset"]
    note = None
    if mem is not None and mem_floor is not None:
        note = (f"peak RSS over the interpreter's ({ours['rss']['baseline_mb']:.0f} and "
                f"{floor['rss']['baseline_mb']:.0f} MB): read_motive_csv {mem:.0f} MB, numpy.loadtxt {mem_floor:.0f} MB"
                + ("" if reset else "; high-water mark not reset: upper bounds")
                + (f"; the compiled parser's runtime, loaded once per process before: "
                   f"{ours['compiled_runtime_mb']:.0f} MB" if ours.get("compiled_runtime_mb") is not None else ""))
    return figure("read_motive_csv peak memory", mem, "MB", floor=mem_floor, lower_is_better=True,
                  target=f"<= {MEMORY_TARGET_RATIO:g}x numpy's loader", met=met, note=note)


def _spread(walls: list[float]) -> str:
    """``"0.29 s (0.29-0.31)"``: the fastest call and the range of all."""
    return f"{min(walls):.2f} s ({min(walls):.2f}-{max(walls):.2f})"


def run(ctx: BenchContext) -> dict:
    """Benchmark 3 (see the module docstring)."""
    duration = DURATION_S[ctx.quick]
    rec = ride_recording(ctx.cache_dir, duration, log=ctx.log)
    t_start = time.monotonic()
    path = str(rec["csv"])
    ours = ctx.isolated("euc_ros.bench.csv_parse:measure_ours", path=path)
    floor = ctx.isolated("euc_ros.bench.csv_parse:measure_numpy", path=path)
    if ours["frames"] != floor["frames"]:
        raise BenchError(f"read_motive_csv read {ours['frames']} frames, numpy.loadtxt {floor['frames']}")
    rate, floor_rate = ours["frames"] / ours["wall_s"], floor["frames"] / floor["wall_s"]

    size_mb = os.path.getsize(path) / 1e6
    figures = [figure("read_motive_csv", rate, "frames/s", floor=floor_rate, lower_is_better=False,
                      note=f"{ours['frames']} frames x {ours['bodies']} bodies ({size_mb:.0f} MB) in "
                           f"{_spread(ours['walls_s'])}; numpy.loadtxt {_spread(floor['walls_s'])} (fastest of "
                           f"{REPEATS} calls)"),
               memory_figure(ours, floor)]
    return {"name": "csv_parse", "title": "Motive CSV parse rate and memory (14 bodies, one core)", "figures": figures,
            "peak_rss_mb": {"read_motive_csv": ours["peak_rss_mb"], "numpy.loadtxt": floor["peak_rss_mb"]},
            "details": {"file_mb": size_mb, "ours": ours, "numpy": floor}, "wall_s": time.monotonic() - t_start}
