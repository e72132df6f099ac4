"""Benchmark 2: offline throughput of ``identify`` and ``residual`` on a 10-minute recording.

Both commands run in process (``euc_ros.cli.main.main``, output discarded, no progress bar, no
plots) on one simulated 120 Hz recording of 14 rigid bodies, once as a Motive CSV and once as a
rosbag2 MCAP bag, each in a fresh interpreter pinned to one core (``os.sched_setaffinity``). The
figure is recording-seconds per wall-second (``x real time``); the wall time covers reading the
file, the state reconstruction and the analysis, not the interpreter start nor the one-time imports
(each measurement first runs the same command, untimed, on a 10 s recording, and loads the compiled CSV
parser, which the short recording's CSV does not need). The workers run
BLAS on one thread (:data:`ONE_CORE_ENV`).

Each command is timed :data:`REPEATS` times in its worker (--quick: once) after the warm-up: the
figure is the median, the note gives the spread.

Floor: loading the same recording alone (:func:`euc_ros.core.io.recordings.load_recording`) in a
fresh interpreter on one core: neither command can be faster than reading its input. The ratio is
the command's cost in units of that load. The notes also give the process' CPU time (on a shared
machine the wall time includes the waits for the one core; the CPU time does not). Targets
(:data:`TARGETS`): identify with its interval at least 600x real time on the bag and 250x on the
CSV; residual with discovery, noise floor and interval at least 200x on the bag.
"""
from __future__ import annotations

import contextlib
import io
import statistics
import time

from euc_ros.bench.common import BenchContext, BenchError, environ, figure, pinned_to_one_core, resolve_target
from euc_ros.bench.data import ride_recording
from euc_ros.core.io.recordings import load_recording

#: Recording lengths [s]: full and --quick.
DURATION_S = {False: 600.0, True: 60.0}
#: Length of the warm-up recording [s] (the one-time imports happen on it, untimed).
WARMUP_S = 10.0
#: Targets [x real time] per (command, source); residual on the CSV is reported without one.
TARGETS = {("identify", "bag"): 600.0, ("identify", "csv"): 250.0, ("residual", "bag"): 200.0}
#: Timed runs of each command after its warm-up: full and --quick.
REPEATS = {False: 3, True: 1}


def _prime_csv_parser(paths) -> None:
    """The compiled CSV parser's one-time import and load (about 0.4 s), untimed, when a recording is a CSV.

    The warm-up's short CSV is read by numpy (the compiled parser starts at 16 MB of data rows), so without
    this the first timed read of the long CSV would pay it (as a process's first long CSV does, once).
    """
    if any(str(p).lower().endswith(".csv") for p in paths):
        from euc_ros.core.io.csv_compiled import parse_rows

        parse_rows(b"0", 1, 1)


def measure_load(path: str, warmup_path: str | None = None) -> dict:
    """Load a recording on one core (after an untimed load of ``warmup_path``); ``{"wall_s", "recording_s", ...}``."""
    with pinned_to_one_core() as cpu:
        if warmup_path:
            load_recording(warmup_path)
            _prime_csv_parser([path])
        t0, c0 = time.perf_counter(), time.process_time()
        s = load_recording(path)
        wall, cpu_s = time.perf_counter() - t0, time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu_s, "recording_s": float(s.t[-1] - s.t[0]) + 1.0 / s.rate_hz,
            "frames": int(s.n_frames), "cpu": cpu}


def measure_command(argv: list[str], warmup_argv: list[str] | None = None, *, entry: str, repeats: int = 1) -> dict:
    """Run ``euc-ros ARGV`` in process on one core ``repeats`` times.

    Returns ``{"wall_s", "cpu_s"`` (medians),
    ``"wall_runs_s", "cpu_runs_s", "warmup_s", "exit_code", "cpu"}``.

    ``entry``: the command-line entry point, ``module:function`` (:attr:`BenchContext.command`).

    ``warmup_argv`` (the same command on a short recording) runs first, untimed, so the one-time
    imports (scipy.signal alone takes about 1 s) are not charged to the throughput; with it, the compiled CSV
    parser is loaded too (:func:`_prime_csv_parser`).
    """
    main = resolve_target(entry)
    sink = io.StringIO()
    warm = float("nan")
    with pinned_to_one_core() as cpu, contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
        if warmup_argv:
            t0 = time.perf_counter()
            main(list(warmup_argv))
            warm = time.perf_counter() - t0
            _prime_csv_parser(argv)
        walls, cpus, code = [], [], 0
        for _ in range(max(int(repeats), 1)):
            t0, c0 = time.perf_counter(), time.process_time()
            code = main(list(argv)) or code
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
    return {"wall_s": statistics.median(walls), "cpu_s": statistics.median(cpus), "wall_runs_s": walls,
            "cpu_runs_s": cpus, "warmup_s": warm, "exit_code": int(code), "cpu": cpu,
            "output_tail": sink.getvalue()[-300:]}


#: Environment of the measuring workers: BLAS on one thread, as the worker runs on one core (OpenBLAS
#: starts one thread per CPU at import; pinned to one core the second one only spins: measured on the
#: 10-minute bag, residual 7.4 s of CPU with two BLAS threads, 5.5 s with one).
ONE_CORE_ENV = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def run(ctx: BenchContext) -> dict:
    """Benchmark 2 (see the module docstring)."""
    with environ(ONE_CORE_ENV):               # inherited by the isolated workers
        return _run(ctx)


def _run(ctx: BenchContext) -> dict:
    duration = DURATION_S[ctx.quick]
    rec = ride_recording(ctx.cache_dir, duration, bag=True, log=ctx.log)
    warm = ride_recording(ctx.cache_dir, WARMUP_S, bag=True, log=ctx.log)
    t_start = time.monotonic()
    figures, rss, details = [], {}, {"recording_length_s": duration}
    for kind in ("csv", "bag"):
        path = str(rec[kind])
        ctx.log(f"  load {kind} (floor)")
        load = ctx.isolated("euc_ros.bench.throughput:measure_load", path=path, warmup_path=str(warm[kind]))
        rec_s = load["recording_s"]
        floor_rate = rec_s / load["wall_s"]
        rss[f"load {kind}"] = load["peak_rss_mb"]
        details[f"load_{kind}"] = load
        for cmd in ("identify", "residual"):
            ctx.log(f"  {cmd} {kind}")
            argv = [cmd, str(rec["session"]), path, "--no-progress"]
            warm_argv = [cmd, str(warm["session"]), str(warm[kind]), "--no-progress"]
            if cmd == "residual":
                argv += ["--json", str(ctx.tmp_dir / f"residual_{kind}.json")]
                warm_argv += ["--json", str(ctx.tmp_dir / f"residual_warmup_{kind}.json")]
            r = ctx.isolated("euc_ros.bench.throughput:measure_command", argv=argv, warmup_argv=warm_argv,
                             entry=ctx.command, repeats=REPEATS[ctx.quick], timeout_s=1800.0)
            if r["exit_code"] != 0:
                raise BenchError(f"euc-ros {' '.join(argv)} exited {r['exit_code']}: {r['output_tail']}")
            rate = rec_s / r["wall_s"]
            want = TARGETS.get((cmd, kind))
            target, met = (f">= {want:g}x real time", rate >= want) if want else (None, None)
            rates = [rec_s / w for w in r["wall_runs_s"]]
            spread = f"{min(rates):.0f}-{max(rates):.0f}x over {len(rates)} runs; " if len(rates) > 1 else ""
            figures.append(figure(f"{cmd} on {kind}", rate, "x real time", floor=floor_rate, lower_is_better=False,
                                  target=target, met=met,
                                  note=f"{spread}{r['wall_s']:.2f} s for {rec_s:.0f} s of recording; load alone "
                                       f"{load['wall_s']:.2f} s; CPU time {r['cpu_s']:.2f} s "
                                       f"({rec_s / r['cpu_s']:.0f}x real time per CPU second), load alone "
                                       f"{load['cpu_s']:.2f} s"))
            rss[f"{cmd} {kind}"] = r["peak_rss_mb"]
            details[f"{cmd}_{kind}"] = {k: v for k, v in r.items() if k != "output_tail"}
    return {"name": "throughput", "title": f"Offline throughput on a {duration / 60:g}-minute recording (one core)",
            "figures": figures, "peak_rss_mb": rss, "details": details, "wall_s": time.monotonic() - t_start}
