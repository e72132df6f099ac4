"""Benchmark: a campaign on a local Dask cluster of 2 worker processes, against the same tasks run serially.

Work: a campaign of simulated-seed tasks (``seed_tasks``: a deceleration ride of one 10 s run with default
noise and true h 0.61 m, written as a session and its Motive CSV, then ``euc-ros identify`` on it), 120
tasks (quick: 8). The figure is the campaign's rate on a ``dask.distributed`` ``LocalCluster`` of 2 worker
processes of one thread each (``run_campaign(tasks, client=...)``), in tasks per wall-minute. **Floor:** the
same tasks run serially in one process (``run_campaign(tasks, serial=True)``). The speed-up is the serial
wall time over the cluster's. The cluster's start-up (``LocalCluster`` until both workers are connected) is
timed separately and not in the figure (the note gives the speed-up with it); so is one untimed warm-up task
per process (the imports, loading the compiled simulator and kernels from their caches), on each worker and
before the serial run alike. The rows of every run must equal the serial run's in every column but
``seconds`` (as ``test/integration/test_campaign.py`` checks).

Each side runs in a fresh interpreter (the cluster is made inside it, so multiprocessing's resource tracker
ends with it), serial and cluster alternating, three times each (quick: once): the figure is the median, the
note the spread. Not pinned to a core (the cluster needs two); BLAS runs on one thread in every process
(:data:`~euc_ros.bench.throughput.ONE_CORE_ENV`). Target: a speed-up of at least 1.5 (ideal 2) when the
machine allows at least 2 CPUs to this process; on one CPU the target does not apply.

The campaign runner's module is named by the caller (:attr:`BenchContext.campaign`), as the command entry
point of the offline benchmarks is, so this module imports no command module.
"""
from __future__ import annotations

import importlib
import importlib.util
import json
import os
import statistics
import time

from euc_ros.bench.common import BenchContext, BenchError, environ, figure, self_peak_rss_mb
from euc_ros.bench.throughput import ONE_CORE_ENV

#: Worker processes of the local cluster (one thread each).
WORKERS = 2
#: Tasks of the campaign: full and --quick (multiples of WORKERS).
TASKS = {False: 120, True: 8}
#: Runs of each side: full and --quick.
REPEATS = {False: 3, True: 1}
#: Recorded length of each task's ride [s].
DURATION_S = 10.0
#: The untimed warm-up task: its seed (outside the campaign's) and ride length [s].
WARMUP_SEED = 1_000_000
WARMUP_DURATION_S = 2.0
#: Target speed-up (serial wall / cluster wall) with WORKERS workers on at least WORKERS CPUs.
TARGET_SPEEDUP = 1.5
#: Options of the simulated rides (``seed_tasks``), but for ``duration_s``.
SIMULATE = {"maneuver": "deceleration", "runs": 1, "h": 0.61, "effects": [], "params": {}, "noise": True}


def _runner(runner: str):
    if not runner:
        raise BenchError("no campaign runner module named (BenchContext.campaign)")
    return importlib.import_module(runner)


def _campaign(mod, n_tasks: int, duration_s: float) -> list:
    return mod.seed_tasks(range(n_tasks), {**SIMULATE, "duration_s": float(duration_s)})


def _warmup_task(mod, duration_s: float):
    return mod.seed_tasks([WARMUP_SEED], {**SIMULATE, "duration_s": float(duration_s)})[0]


def measure_serial(n_tasks: int, runner: str, duration_s: float = DURATION_S,
                   warmup_duration_s: float = WARMUP_DURATION_S) -> dict:
    """The campaign run serially in this process, after one untimed warm-up task.

    Returns ``{"wall_s", "cpu_s", "warmup_s", "warmup_status", "tasks", "duration_s", "task_s", "rows"}``
    (``task_s``: the sum of the rows' own ``seconds``; ``runner``: the campaign module,
    ``euc_ros.cli.campaign_tasks``).
    """
    mod = _runner(runner)
    tasks = _campaign(mod, n_tasks, duration_s)
    t0 = time.perf_counter()
    warm = mod.run_task(_warmup_task(mod, warmup_duration_s))
    warmup_s = time.perf_counter() - t0
    c0, w0 = time.process_time(), time.perf_counter()
    rows = mod.run_campaign(tasks, serial=True)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "warmup_s": warmup_s, "warmup_status": warm["status"],
            "tasks": len(tasks), "duration_s": float(duration_s), "task_s": sum(r["seconds"] for r in rows),
            "rows": rows}


def measure_cluster(n_tasks: int, runner: str, workers: int = WORKERS, duration_s: float = DURATION_S,
                    warmup_duration_s: float = WARMUP_DURATION_S) -> dict:
    """The campaign on a local Dask cluster of ``workers`` processes (one thread each) made in this process.

    Timed apart: ``startup_s`` (``LocalCluster`` and ``Client`` until every worker is connected), ``warmup_s``
    (one untimed task on each worker), ``wall_s`` (``run_campaign`` on the cluster) and ``shutdown_s``.
    ``worker_cpu_s``: each worker's CPU time during the campaign; ``cpu_s``: this process's (scheduler and
    client); ``worker_peak_rss_mb``: each worker's peak resident set; ``task_s``: the sum of the rows' own
    ``seconds`` (the tasks' time inside the workers).
    """
    from distributed import Client, LocalCluster

    mod = _runner(runner)
    tasks = _campaign(mod, n_tasks, duration_s)
    warm_task = _warmup_task(mod, warmup_duration_s)
    t0 = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        client.wait_for_workers(workers)
        startup_s = time.perf_counter() - t0
        pids = client.run(os.getpid)
        addrs = sorted(pids)
        t0 = time.perf_counter()
        warm = client.gather([client.submit(mod.run_task, warm_task, workers=[a], allow_other_workers=False,
                                            pure=False, key=f"euc-bench-warmup-{i}") for i, a in enumerate(addrs)])
        warmup_s = time.perf_counter() - t0
        cpu_before = client.run(time.process_time)
        c0, w0 = time.process_time(), time.perf_counter()
        rows = mod.run_campaign(tasks, client=client)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        cpu_after = client.run(time.process_time)
        rss = client.run(self_peak_rss_mb)
        t_close = time.perf_counter()
    shutdown_s = time.perf_counter() - t_close
    return {"wall_s": wall, "cpu_s": cpu, "startup_s": startup_s, "warmup_s": warmup_s, "shutdown_s": shutdown_s,
            "warmup_status": [w["status"] for w in warm], "workers": len(addrs),
            "worker_pids": [pids[a] for a in addrs], "measuring_pid": os.getpid(),
            "worker_cpu_s": [cpu_after[a] - cpu_before[a] for a in addrs if a in cpu_after and a in cpu_before],
            "worker_peak_rss_mb": [round(rss[a], 1) for a in addrs if a in rss], "tasks": len(tasks),
            "duration_s": float(duration_s), "task_s": sum(r["seconds"] for r in rows), "rows": rows}


def _key(row: dict) -> str:
    """A row without ``seconds``, as text (NaN equals NaN, floats compare exactly)."""
    return json.dumps({k: v for k, v in row.items() if k != "seconds"}, sort_keys=True, default=str)


def differing_rows(rows: list[dict], reference: list[dict]) -> list[str]:
    """Tasks whose row differs from the reference's, is missing in either, or stands in another place.

    A row differs when any column but ``seconds`` does; the rows are sorted by task.

    Examples
    --------
    >>> a = [{"task": "s1", "h_m": 0.6, "seconds": 1.0}, {"task": "s2", "h_m": 0.5, "seconds": 1.0}]
    >>> differing_rows([dict(a[0], seconds=9.0), a[1]], a)
    []
    >>> differing_rows([a[0], dict(a[1], h_m=0.51)], a)
    ['s2']
    """
    ref = {r["task"]: _key(r) for r in reference}
    got = {r["task"]: _key(r) for r in rows}
    out = {n for n in ref.keys() | got.keys() if ref.get(n) != got.get(n)}
    out |= {a["task"] for a, b in zip(rows, reference) if a["task"] != b["task"]}
    return sorted(out)


def _spread(values: list[float], fmt: str = ".2f", unit: str = "") -> str:
    if len(values) == 1:
        return "one run"
    return f"{min(values):{fmt}}-{max(values):{fmt}}{unit} over {len(values)} runs"


def summarize(serial: list[dict], cluster: list[dict], *, cores: int, cpu_count: int | None,
              workers: int = WORKERS) -> tuple[list[dict], dict]:
    """Figures and details from the measured runs (:func:`measure_serial`, :func:`measure_cluster`, with rows).

    The rows of every run are compared with the first serial run's; the speed-up's target applies with at
    least ``workers`` CPUs allowed (``cores``) and is met only when every row is identical.
    """
    n, duration = serial[0]["tasks"], serial[0]["duration_s"]
    ref = serial[0]["rows"]
    diffs = {f"serial {i + 1}": differing_rows(r["rows"], ref) for i, r in enumerate(serial[1:], start=1)}
    diffs.update({f"cluster {i + 1}": differing_rows(r["rows"], ref) for i, r in enumerate(cluster)})
    differing = sorted({t for d in diffs.values() for t in d})
    identical = not differing
    worst = n - max((len(d) for d in diffs.values()), default=0)
    ok = sum(r["status"] == "ok" for r in ref)

    s_wall = statistics.median(r["wall_s"] for r in serial)
    c_wall = statistics.median(r["wall_s"] for r in cluster)
    startup = statistics.median(r["startup_s"] for r in cluster)
    speedup = s_wall / c_wall
    pairs = [s["wall_s"] / c["wall_s"] for s, c in zip(serial, cluster)]
    with_startup = s_wall / (c_wall + startup)
    ideal = min(workers, cores)
    applies = cores >= workers
    where = (f"{workers} worker processes of one thread on {cores} allowed of {cpu_count} logical CPUs "
             f"(ideal {ideal}x)")
    if applies:
        target, met = f">= {TARGET_SPEEDUP:g}x (ideal {workers}x)", speedup >= TARGET_SPEEDUP and identical
    else:
        target, met = f"n/a: {cores} CPU allowed, fewer than the {workers} workers", None
    worker_cpu = statistics.median(sum(r["worker_cpu_s"]) for r in cluster)
    speed_note = (f"{where}; per pair of serial and cluster runs {_spread(pairs)}; with the cluster's start-up "
                  f"counted {with_startup:.2f}x")
    if not identical:
        speed_note += "; not met: the rows differ from the serial run's"

    def med(runs: list[dict], key: str) -> float:
        return statistics.median(r[key] for r in runs)

    def spread(runs: list[dict], key: str) -> str:
        return _spread([r[key] for r in runs], ".1f", " s")

    figures = [
        figure(f"campaign on a local Dask cluster ({workers} worker processes)", 60.0 * n / c_wall, "tasks/min",
               floor=60.0 * n / s_wall, lower_is_better=False,
               note=f"{n} tasks (simulated {duration:g} s ride + identify); cluster {c_wall:.1f} s "
                    f"({spread(cluster, 'wall_s')}), serial {s_wall:.1f} s ({spread(serial, 'wall_s')}); the "
                    f"cluster's start-up {startup:.1f} s ({spread(cluster, 'startup_s')}) is not in the figure, nor "
                    f"one untimed warm-up task per process (serial {med(serial, 'warmup_s'):.1f} s, cluster "
                    f"{med(cluster, 'warmup_s'):.1f} s); time inside the tasks: serial {med(serial, 'task_s'):.1f} s, "
                    f"cluster {med(cluster, 'task_s'):.1f} s; CPU time: serial {med(serial, 'cpu_s'):.1f} s, cluster "
                    f"workers {worker_cpu:.1f} s + scheduler and client {med(cluster, 'cpu_s'):.1f} s"),
        figure("speed-up (serial wall / cluster wall)", speedup, "x", target=target, met=met, note=speed_note),
        figure("rows identical to the serial run (every column but seconds)", worst, "rows",
               target=f"all {n}, every run", met=identical,
               note=(f"{len(serial)} serial and {len(cluster)} cluster runs compared with the first serial run; "
                     f"{ok} of {n} tasks ok" + (f"; differing: {', '.join(differing[:10])}" if differing else ""))),
    ]
    details = {"tasks": n, "workers": workers, "duration_s": duration, "cores_allowed": cores,
               "logical_cpus": cpu_count, "speedup": speedup, "speedup_per_pair": pairs,
               "speedup_with_startup": with_startup, "rows_identical": identical, "differing_rows": diffs,
               "tasks_ok": ok,
               "serial": [{k: v for k, v in r.items() if k != "rows"} for r in serial],
               "cluster": [{k: v for k, v in r.items() if k != "rows"} for r in cluster]}
    return figures, details


def run(ctx: BenchContext) -> dict:
    """The campaign benchmark (see the module docstring)."""
    with environ(ONE_CORE_ENV):               # inherited by the isolated workers and the cluster's processes
        return _run(ctx)


def _run(ctx: BenchContext) -> dict:
    if importlib.util.find_spec("distributed") is None:
        raise BenchError("dask.distributed is not installed (requirements.txt): campaigns need it")
    t_start = time.monotonic()
    n, repeats = TASKS[ctx.quick], REPEATS[ctx.quick]
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    ctx.log(f"  {n} tasks ({DURATION_S:g} s rides, identify), serially and on {WORKERS} workers, {repeats}x each")
    serial, cluster = [], []
    for i in range(repeats):
        ctx.log(f"  serial {i + 1}/{repeats}")
        serial.append(ctx.isolated("euc_ros.bench.campaign:measure_serial", n_tasks=n, runner=ctx.campaign))
        ctx.log(f"  cluster {i + 1}/{repeats}")
        cluster.append(ctx.isolated("euc_ros.bench.campaign:measure_cluster", n_tasks=n, runner=ctx.campaign,
                                    workers=WORKERS))
    figures, details = summarize(serial, cluster, cores=cores, cpu_count=os.cpu_count())
    rss = {"serial": max(r["peak_rss_mb"] for r in serial),
           "cluster: scheduler and client": max(r["peak_rss_mb"] for r in cluster)}
    for k in range(WORKERS):
        peaks = [r["worker_peak_rss_mb"][k] for r in cluster if len(r["worker_peak_rss_mb"]) > k]
        if peaks:
            rss[f"cluster: worker {k + 1}"] = max(peaks)
    return {"name": "campaign", "title": f"Campaign on a local Dask cluster of {WORKERS} workers against serial",
            "figures": figures, "peak_rss_mb": rss, "details": details, "wall_s": time.monotonic() - t_start}
