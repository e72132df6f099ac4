"""Benchmark: how the cost of ``identify`` and ``residual`` grows with the length of the recording.

The target is that time and peak memory grow linearly with the recording, and that the peak memory
stay within 1.5x of the recording's own arrays. This benchmark runs both commands on recordings of
1, 10 and 60 minutes (``--quick``: 0.5 and 1.5 minutes) of the same session and states:

Recordings
    One simulated figure-eight ride (:func:`euc_ros.bench.data.ride_recording`: 120 Hz, 14 rigid
    bodies, the simulator's noise and occlusions) of 10 minutes (``--quick``: 1 minute) is the base.
    Shorter recordings are its first minutes; longer ones are the base repeated
    (:func:`growth_recording`), with frame numbers and times continuing, and the first
    :data:`SEAM_FRAMES` frames of every repeat written as untracked for every body (blank cells): the
    jump from the end of one repeat to the start of the next is then an occlusion the analysis
    splits at, as it splits a real recording, instead of a step in every pose. Only the Motive CSV
    is measured (the bag reader's cost is in the throughput benchmark). The derived files are
    cached beside the base recording (text rewritten line by line, never simulated again).

What is measured, per command and length, each in a fresh interpreter pinned to one core
(:meth:`~euc_ros.bench.common.BenchContext.isolated`, :func:`measure_command`):
    The command first runs untimed on a 10 s recording (the one-time imports and first-call costs,
    as in the throughput benchmark); then the garbage collector runs and freed heap memory is given
    back to the OS (``malloc_trim``), and the **baseline** is the resident set at that moment
    (``VmRSS``: the interpreter, the imported modules, what the warm-up left). The kernel's
    high-water mark is reset (``/proc/self/clear_refs``), the command runs on the recording, and:

    * ``wall_s``: its wall time (reading the CSV, state reconstruction, analysis, interval, output);
    * ``peak_mb``: the peak resident set during the command (``VmHWM`` after the reset: total RSS,
      baseline included);
    * ``above_mb``: ``peak_mb - baseline_mb``, the command's own peak memory.

Floor, per length (:func:`measure_load`, same isolation): reading the recording alone
(:func:`euc_ros.core.io.recordings.load_recording`), with its wall time and the **arrays' own
size**: the sum of ``.nbytes`` of every array the reader returns (times, frame numbers, positions,
quaternions, tracked flags, marker errors): the memory no analysis of the whole recording can do
without.

Figures
    * time per recorded minute at each length [s/min] (ratio: to the load's time per minute);
    * the time's growth exponent: the slope of log(wall time) against log(length) from the shortest
      to the longest recording (1.0 is linear; fixed costs, like the bootstrap's 1000 replicates,
      make the short recording relatively dear and the slope lower). Target <= 1.1. The slope over
      the last step (10 to 60 minutes) is in the note: it shows a superlinear part best;
    * peak memory above baseline at the longest length in units of the arrays' own size (target
      <= 1.5), with the total peak RSS in the note;
    * the memory's growth: the slope of ``above_mb`` against the arrays' size between the two
      longest recordings (MB of peak per MB of recording: the asymptotic ratio, free of fixed
      costs), and the log-log exponent of ``above_mb`` against length.
"""
from __future__ import annotations

import contextlib
import gc
import io
import math
import os
import time
from pathlib import Path

import numpy as np

from euc_ros.bench.common import BenchContext, BenchError, figure, peak_rss_increase, pinned_to_one_core, resolve_target
from euc_ros.bench.data import ride_recording
from euc_ros.core.io.recordings import load_recording

#: Recording lengths [min]: full and --quick.
LENGTHS_MIN = {False: (1, 10, 60), True: (0.5, 1.5)}
#: Length of the simulated base recording [s]: full and --quick.
BASE_S = {False: 600.0, True: 60.0}
#: Length of the warm-up recording [s].
WARMUP_S = 10.0
#: Frames written untracked at the start of every repeat of the base (> the analysis' max_gap of 5).
SEAM_FRAMES = 12
#: Version of the derived files (bump when their content changes).
DERIVED_VERSION = 2
#: Targets: time growth exponent, peak above baseline / arrays' size at the longest length.
TARGET_TIME_EXPONENT = 1.1
TARGET_MEMORY_RATIO = 1.5
COMMANDS = ("identify", "residual")


# ------------------------------------------------------------------------------------------ recordings
def _split_csv(text: bytes) -> tuple[list[bytes], list[bytes]]:
    """Header lines (up to the ``Frame,`` row) and data lines of a Motive CSV (CRLF or LF)."""
    nl = b"\r\n" if b"\r\n" in text[:4096] else b"\n"
    lines = text.split(nl)
    while lines and not lines[-1]:
        lines.pop()
    for i, line in enumerate(lines[:64]):
        if line.startswith(b"Frame,"):
            return lines[:i + 1], lines[i + 1:]
    raise BenchError("no 'Frame,' header row in the base recording")


def _header_with_frames(first: bytes, total: int, exported: int) -> bytes:
    """Line 1 of a Motive CSV with ``Total Frames in Take`` and ``Total Exported Frames`` replaced."""
    cells = first.split(b",")
    for key, value in ((b"Total Frames in Take", total), (b"Total Exported Frames", exported)):
        if key in cells:
            i = cells.index(key)
            if i + 1 < len(cells):
                cells[i + 1] = str(value).encode()
    return b",".join(cells)


def derive_csv(base_csv: Path, out_csv: Path, frames: int, rate_hz: float, *, seam_frames: int = SEAM_FRAMES) -> int:
    """Write a Motive CSV of ``frames`` frame numbers made of ``base_csv``'s rows; returns the rows written.

    The base's rows are taken in order and repeated with frame numbers shifted by the base's frame
    span (last frame + 1), so frame numbers and times continue; the first ``seam_frames`` rows of
    every repeat after the first have every cell but the frame and the time blank (untracked). Rows
    are copied as text (only the frame and time cells are rewritten), so the numbers are the base's.
    """
    head, rows = _split_csv(Path(base_csv).read_bytes())
    if not rows:
        raise BenchError(f"{base_csv}: no data rows")
    nl = b"\r\n"
    base_frames = np.array([int(r.split(b",", 1)[0]) for r in rows], dtype=np.int64)
    span = int(base_frames[-1]) + 1
    offsets = range(0, frames, span)
    written = int(sum(np.count_nonzero(base_frames + off < frames) for off in offsets))
    blank_tail = b"," * (rows[0].count(b",") - 2)     # the cells after frame and time, all blank
    tmp = out_csv.with_name(out_csv.name + ".partial")
    with open(tmp, "wb") as f:
        f.write(nl.join([_header_with_frames(head[0], frames, written), *head[1:]]) + nl)
        for off in offsets:
            body = []
            for fr, row in zip(base_frames, rows):
                g = int(fr) + off
                if g >= frames:
                    break
                tail = blank_tail if (off > 0 and fr < seam_frames) else row.split(b",", 2)[2]
                body.append(b"%d,%.6f,%s" % (g, g / rate_hz, tail))
            f.write(nl.join(body) + nl)
    tmp.replace(out_csv)
    return written


def growth_recording(cache_dir: Path, base: dict, minutes: float, base_s: float, rate_hz: float = 120.0,
                     log=None) -> dict:
    """``{"csv", "session"}`` of a recording of ``minutes`` made from ``base`` (see the module docstring)."""
    if abs(minutes * 60.0 - base_s) < 1e-6:
        return {"csv": base["csv"], "session": base["session"]}
    root = Path(cache_dir) / f"growth_{Path(base['dir']).name}_{minutes:g}min_v{DERIVED_VERSION}"
    csv = root / "recording.csv"
    session = root / "session.yaml"
    if not csv.exists():
        if log:
            log(f"  making a {minutes:g}-minute recording from {Path(base['csv']).name} (once)")
        root.mkdir(parents=True, exist_ok=True)
        session.write_bytes(Path(base["session"]).read_bytes())
        derive_csv(Path(base["csv"]), csv, int(round(minutes * 60.0 * rate_hz)), rate_hz)
    return {"csv": csv, "session": session}


# ------------------------------------------------------------------------------------------ measuring
def series_nbytes(series) -> int:
    """Bytes of every array a reader returned: times, frames, poses, tracked flags, errors (and arrays in meta)."""
    arrays = [series.t, series.frame, series.position, series.quat, series.tracked, series.mean_marker_error]
    arrays += [v for v in series.meta.values() if isinstance(v, np.ndarray)]
    return int(sum(np.asarray(a).nbytes for a in arrays if a is not None))


def _release_freed_memory() -> None:
    """Collect garbage and give freed heap pages back to the OS (glibc ``malloc_trim``), where possible."""
    gc.collect()
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


@contextlib.contextmanager
def _baseline_and_peak():
    """Baseline RSS now (after releasing freed memory), the high-water mark reset; fills the dict on exit."""
    _release_freed_memory()
    with peak_rss_increase() as rss:
        yield rss


def measure_load(path: str, world_up: str = "y", warmup_path: str | None = None) -> dict:
    """Read a recording alone on one core; wall time, arrays' size, baseline and peak RSS."""
    with pinned_to_one_core() as cpu:
        if warmup_path:
            load_recording(warmup_path, world_up)
        with _baseline_and_peak() as rss:
            t0 = time.perf_counter()
            s = load_recording(path, world_up)
            wall = time.perf_counter() - t0
    return {"wall_s": wall, "arrays_mb": series_nbytes(s) / 2**20, "frames": int(s.n_frames),
            "recording_s": float(s.t[-1] - s.t[0]) + 1.0 / s.rate_hz, "baseline_mb": rss["baseline_mb"],
            "peak_mb": rss["peak_mb"], "above_mb": rss["increase_mb"], "hwm_reset": rss["hwm_reset"], "cpu": cpu}


def measure_command(argv: list[str], warmup_argv: list[str] | None = None, *, entry: str) -> dict:
    """Run ``euc-ros ARGV`` in process on one core after an untimed warm-up; time, baseline and peak RSS.

    ``entry``: the command-line entry point, ``module:function`` (:attr:`BenchContext.command`).
    """
    main = resolve_target(entry)
    sink = io.StringIO()
    with pinned_to_one_core() as cpu, contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        if warmup_argv:
            main(list(warmup_argv))
        with _baseline_and_peak() as rss:
            t0 = time.perf_counter()
            code = main(list(argv))
            wall = time.perf_counter() - t0
    return {"wall_s": wall, "exit_code": int(code), "baseline_mb": rss["baseline_mb"], "peak_mb": rss["peak_mb"],
            "above_mb": rss["increase_mb"], "hwm_reset": rss["hwm_reset"], "cpu": cpu,
            "output_tail": sink.getvalue()[-300:]}


# ------------------------------------------------------------------------------------------ analysis
def loglog_slope(x, y) -> float:
    """Least-squares slope of log(y) against log(x) (NaN with fewer than two positive points).

    >>> round(loglog_slope([1, 10, 60], [2.0, 20.0, 120.0]), 6)
    1.0
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2 or np.ptp(np.log(x[ok])) == 0:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


def endpoint_exponent(x, y) -> float:
    """``log(y[-1] / y[0]) / log(x[-1] / x[0])``: the growth exponent from the first to the last point."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if x.size < 2 or not (x[0] > 0 and x[-1] > x[0] and y[0] > 0 and y[-1] > 0):
        return float("nan")
    return float(math.log(y[-1] / y[0]) / math.log(x[-1] / x[0]))


def incremental_ratio(x, y) -> float:
    """``(y[-1] - y[-2]) / (x[-1] - x[-2])``: the slope over the last step (NaN without two points)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if x.size < 2 or not x[-1] > x[-2]:
        return float("nan")
    return float((y[-1] - y[-2]) / (x[-1] - x[-2]))


def summarize(minutes, loads: list[dict], runs: dict[str, list[dict]]) -> dict:
    """Growth figures of each command from per-length measurements (JSON-ready).

    Parameters
    ----------
    minutes : sequence of float
        Recording lengths [min], increasing.
    loads : list of dict
        Per length, :func:`measure_load`'s result (``wall_s``, ``arrays_mb``).
    runs : dict
        Per command, per length, :func:`measure_command`'s result (``wall_s``, ``peak_mb``, ``above_mb``).
    """
    m = np.asarray(minutes, float)
    arrays = np.array([ld["arrays_mb"] for ld in loads], float)
    out = {"minutes": [float(v) for v in m], "arrays_mb": [float(v) for v in arrays],
           "load_s_per_min": [float(ld["wall_s"] / mm) for ld, mm in zip(loads, m)], "commands": {}}
    for cmd, rs in runs.items():
        wall = np.array([r["wall_s"] for r in rs], float)
        above = np.array([r["above_mb"] if r.get("above_mb") is not None else np.nan for r in rs], float)
        peak = np.array([r["peak_mb"] if r.get("peak_mb") is not None else np.nan for r in rs], float)
        out["commands"][cmd] = {
            "wall_s": [float(v) for v in wall], "s_per_min": [float(v) for v in wall / m],
            "peak_mb": [float(v) for v in peak], "above_mb": [float(v) for v in above],
            "baseline_mb": [r.get("baseline_mb") for r in rs],
            "above_per_arrays": [float(v) for v in above / arrays],
            "time_exponent": endpoint_exponent(m, wall), "time_exponent_fit": loglog_slope(m, wall),
            "time_exponent_last_step": endpoint_exponent(m[-2:], wall[-2:]) if m.size >= 2 else float("nan"),
            "memory_exponent": endpoint_exponent(m, above),
            "memory_slope_mb_per_min": incremental_ratio(m, above),
            "memory_per_arrays_slope": incremental_ratio(arrays, above),
        }
    return out


def _figures(summary: dict) -> list[dict]:
    figs = []
    m = summary["minutes"]
    longest = f"{m[-1]:g} min"
    for cmd, s in summary["commands"].items():
        for k, mm in enumerate(m):
            figs.append(figure(f"{cmd}, {mm:g} min: time per recorded minute", s["s_per_min"][k], "s/min",
                               floor=summary["load_s_per_min"][k],
                               note=f"wall time {s['wall_s'][k]:.2f} s; peak RSS {s['peak_mb'][k]:.0f} MB, "
                                    f"{s['above_mb'][k]:.0f} MB above the baseline of {s['baseline_mb'][k]:.0f} MB; "
                                    f"arrays {summary['arrays_mb'][k]:.0f} MB"))
        e = s["time_exponent"]
        figs.append(figure(f"{cmd}: time growth exponent {m[0]:g}-{m[-1]:g} min", e, "",
                           target=f"<= {TARGET_TIME_EXPONENT:g}",
                           met=None if not np.isfinite(e) else e <= TARGET_TIME_EXPONENT,
                           note=f"log-log slope; fit over all lengths {s['time_exponent_fit']:.3f}, last step "
                                f"{m[-2]:g}-{m[-1]:g} min {s['time_exponent_last_step']:.3f}"))
        r = s["above_per_arrays"][-1]
        figs.append(figure(f"{cmd}: peak memory above baseline / arrays' size, {longest}", r, "x",
                           target=f"<= {TARGET_MEMORY_RATIO:g}",
                           met=None if not np.isfinite(r) else r <= TARGET_MEMORY_RATIO,
                           note=f"{s['above_mb'][-1]:.0f} MB above baseline for {summary['arrays_mb'][-1]:.0f} MB of "
                                f"arrays; total peak RSS {s['peak_mb'][-1]:.0f} MB "
                                f"({s['peak_mb'][-1] / summary['arrays_mb'][-1]:.2f}x the arrays)"))
        figs.append(figure(f"{cmd}: memory slope {m[-2]:g}-{m[-1]:g} min", s["memory_per_arrays_slope"],
                           "MB per MB of arrays",
                           note=f"{s['memory_slope_mb_per_min']:.1f} MB per recorded minute; log-log exponent of the "
                                f"peak above baseline {m[0]:g}-{m[-1]:g} min {s['memory_exponent']:.3f}"))
    return figs


def run(ctx: BenchContext) -> dict:
    """The growth benchmark (see the module docstring)."""
    base_s = BASE_S[ctx.quick]
    minutes = LENGTHS_MIN[ctx.quick]
    base = ride_recording(ctx.cache_dir, base_s, log=ctx.log)
    warm = ride_recording(ctx.cache_dir, WARMUP_S, log=ctx.log)
    recs = [growth_recording(ctx.cache_dir, base, mm, base_s, log=ctx.log) for mm in minutes]
    t_start = time.monotonic()
    loads, runs, rss = [], {c: [] for c in COMMANDS}, {}
    for mm, rec in zip(minutes, recs):
        ctx.log(f"  load {mm:g} min (floor)")
        ld = ctx.isolated("euc_ros.bench.growth:measure_load", path=str(rec["csv"]), warmup_path=str(warm["csv"]))
        loads.append(ld)
        rss[f"load {mm:g} min"] = ld["peak_mb"]
        for cmd in COMMANDS:
            ctx.log(f"  {cmd} {mm:g} min")
            argv = [cmd, str(rec["session"]), str(rec["csv"]), "--no-progress"]
            warm_argv = [cmd, str(warm["session"]), str(warm["csv"]), "--no-progress"]
            if cmd == "residual":
                argv += ["--json", str(ctx.tmp_dir / f"growth_residual_{mm:g}.json")]
                warm_argv += ["--json", str(ctx.tmp_dir / "growth_residual_warmup.json")]
            r = ctx.isolated("euc_ros.bench.growth:measure_command", argv=argv, warmup_argv=warm_argv,
                             entry=ctx.command, timeout_s=3600.0)
            if r["exit_code"] != 0:
                raise BenchError(f"euc-ros {' '.join(argv)} exited {r['exit_code']}: {r['output_tail']}")
            r.pop("output_tail", None)
            runs[cmd].append(r)
            rss[f"{cmd} {mm:g} min"] = r["peak_mb"]
    summary = summarize(minutes, loads, runs)
    details = {"summary": summary, "loads": loads, "runs": runs, "base_recording_s": base_s,
               "seam_frames": SEAM_FRAMES, "load_average": [round(x, 2) for x in os.getloadavg()]}
    return {"name": "growth", "title": f"Cost growth of identify and residual, {minutes[0]:g} to {minutes[-1]:g} min",
            "figures": _figures(summary), "peak_rss_mb": rss, "details": details,
            "wall_s": time.monotonic() - t_start}
