"""Campaigns: identify and residual over many sessions or simulated seeds, on a Dask cluster.

A campaign is a list of independent tasks, each one ``euc-ros identify`` (and ``residual``) on one
session's recordings, or on one simulated ride of a seed. :func:`run_campaign` runs them on a
``dask.distributed`` cluster (a local one by default, a lab's scheduler by address) or serially, and
gathers one row per task. The rows are the same whichever way the tasks ran: a task is a pure
function of its description (the commands' own JSON, read back), and the rows are sorted by task.

A task that raises is a row with ``status: failed`` and the error, never the end of the campaign. A
worker that dies mid-task (killed, out of memory) loses nothing: the scheduler runs the task again
elsewhere (``retries``), and the row comes back as if nothing had happened.

Examples
--------
>>> tasks = session_tasks([])
>>> tasks
[]
"""
from __future__ import annotations

import contextlib
import csv
import os
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from euc_ros.core.errors import ConfigError, describe_error

#: Recording files a session folder may hold.
RECORDING_SUFFIXES = (".csv", ".mcap")
#: Columns of the result table, in order.
COLUMNS = ("task", "kind", "session", "seed", "status", "h_m", "h_ci95_lo_m", "h_ci95_hi_m", "rmse_nm",
           "effect", "rmse_after_nm", "h_after_m", "h_true_m", "seconds", "error")


@dataclass(frozen=True)
class Task:
    """One unit of a campaign.

    Attributes
    ----------
    name : str
        Unique, sortable name (the session folder, or ``seed_0007``).
    kind : {"session", "simulate", "open_world"}
    session : str
        Session file (kind ``session``).
    recordings : tuple of str
        Its recordings (kind ``session``).
    seed : int
        Seed of the simulated ride (kinds ``simulate`` and ``open_world``).
    simulate : dict
        Options of the simulated ride: ``maneuver``, ``runs``, ``duration_s``, ``effects`` (list), ``params``
        (dict), ``noise`` (bool); for ``open_world`` the ``family`` and ``duration_s``, ``rate_hz``, ``rtol``
        (:mod:`euc_ros.core.openworld.study`).
    residual : bool
        Also run ``euc-ros residual``.
    """

    name: str
    kind: str
    session: str = ""
    recordings: tuple[str, ...] = ()
    seed: int = -1
    simulate: dict = field(default_factory=dict)
    residual: bool = False


def session_tasks(folders, *, residual: bool = False) -> list[Task]:
    """One task per session folder: its ``session.yaml`` and every CSV, ``.mcap`` or bag folder in it.

    Raises
    ------
    ConfigError
        A folder without ``session.yaml`` or without recordings, naming it.
    """
    tasks = []
    for folder in sorted(Path(f) for f in folders):
        session = folder / "session.yaml"
        if not session.is_file():
            raise ConfigError("no session.yaml in this session folder", path=folder)
        recs = sorted(str(p) for p in folder.iterdir()
                      if p.suffix.lower() in RECORDING_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").exists()))
        if not recs:
            raise ConfigError("no recording (Motive .csv, bag folder or .mcap) in this session folder", path=folder)
        tasks.append(Task(folder.name, "session", str(session), tuple(recs), residual=residual))
    return tasks


def seed_tasks(seeds, simulate: dict, *, residual: bool = False) -> list[Task]:
    """One task per seed: a simulated ride with ``simulate``'s options, identified (and traced)."""
    return [Task(f"seed_{int(s):06d}", "simulate", seed=int(s), simulate=dict(simulate), residual=residual)
            for s in seeds]


def _analysis_json(command: str, session: str, recordings: list[str]) -> dict:
    """The JSON document of ``identify`` or ``residual`` on these files, or RuntimeError.

    The library's pipelines, as the commands run them; the RuntimeError carries the command's one-line error.
    """
    from euc_ros.core.errors import EucError
    from euc_ros.core.identify.pipeline import identify_recordings
    from euc_ros.core.residual.pipeline import trace_residual

    try:
        run = identify_recordings(session, recordings) if command == "identify" else trace_residual(session, recordings)
    except EucError as exc:
        raise RuntimeError(f"euc-ros {command}: error: {exc}") from None
    return run.data


def _simulate(task: Task, out: Path) -> tuple[str, list[str], float]:
    from euc_ros.core.ridesim.effects import make_effects
    from euc_ros.core.ridesim.mocap_synth import MocapNoise
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    o = task.simulate
    cfg = RideConfig(maneuver=o.get("maneuver", "deceleration"), runs=int(o.get("runs", 1)), seed=task.seed,
                     duration_s=o.get("duration_s"), h=float(o.get("h", 0.61)),
                     effects=make_effects(list(o.get("effects", [])), dict(o.get("params", {}))),
                     **({} if o.get("noise", True) else {"noise": MocapNoise.none()}))
    result = simulate_ride(cfg)
    write_ride(result, out)
    return str(out / "session.yaml"), sorted(str(p) for p in out.glob("*.csv")), float(cfg.h)


def run_task(task: Task) -> dict:
    """Run one task; a row of :data:`COLUMNS` (``status`` ``ok`` or ``failed`` with the error).

    An ``open_world`` task gives a row of :data:`euc_ros.core.openworld.study.COLUMNS` instead.
    """
    if task.kind == "open_world":
        from euc_ros.core.openworld.study import run_task as run_open_world

        return run_open_world(task)
    row = {c: None for c in COLUMNS}
    row.update(task=task.name, kind=task.kind, session=task.session or None,
               seed=task.seed if task.kind == "simulate" else None)
    start = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="euc_campaign_") as tmp:
            tmp = Path(tmp)
            if task.kind == "simulate":
                session, recs, row["h_true_m"] = _simulate(task, tmp / "ride")
            else:
                session, recs = task.session, list(task.recordings)
            ident = _analysis_json("identify", session, recs)
            row["h_m"], row["rmse_nm"] = ident["h_m"], ident["rmse_nm"]
            lo, hi = ident.get("h_ci95_m") or (None, None)
            row["h_ci95_lo_m"], row["h_ci95_hi_m"] = lo, hi
            if task.residual:
                res = _analysis_json("residual", session, recs)
                row["effect"], row["rmse_after_nm"], row["h_after_m"] = (res["effect"], res["rmse_after_nm"],
                                                                         res["h_after_m"])
        row["status"] = "ok"
    except Exception as exc:       # a task's failure is its row, never the campaign's end
        row["status"] = "failed"
        row["error"] = describe_error(exc)
    row["seconds"] = round(time.perf_counter() - start, 3)
    return row


def run_campaign(tasks: list[Task], *, scheduler: str | None = None, workers: int | None = None,
                 serial: bool = False, retries: int = 3, progress=None, client=None) -> list[dict]:
    """Run every task and return their rows, sorted by task name.

    Parameters
    ----------
    tasks : list of Task
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default a local cluster.
    workers : int, optional
        Worker processes of the local cluster (default: the CPU count), one thread each.
    serial : bool
        Run in this process, one task after the other (no Dask).
    retries : int
        Times a task is run again when its worker dies under it.
    progress : callable, optional
        ``progress(done, total, row)`` after each task.
    client : distributed.Client, optional
        Use this client (tests, notebooks) instead of making one.
    """
    names = [t.name for t in tasks]
    if len(set(names)) != len(names):
        raise ConfigError("task names must be unique", key="tasks")
    rows = []
    if serial:
        for t in tasks:
            rows.append(run_task(t))
            if progress:
                progress(len(rows), len(tasks), rows[-1])
        return sorted(rows, key=lambda r: r["task"])
    from distributed import Client, LocalCluster, as_completed

    with contextlib.ExitStack() as stack:
        if client is None:
            if scheduler:
                client = stack.enter_context(Client(scheduler))
            else:
                n = workers or os.cpu_count() or 1
                cluster = stack.enter_context(LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                                           dashboard_address=None))
                client = stack.enter_context(Client(cluster))
        futures = [client.submit(run_task, t, key=f"euc-campaign-{t.name}", retries=retries, pure=False)
                   for t in tasks]
        for fut in as_completed(futures):
            try:
                row = fut.result()
            except Exception as exc:   # the task could not run at all (every retry lost its worker)
                task = tasks[futures.index(fut)]
                row = {c: None for c in COLUMNS}
                row.update(task=task.name, kind=task.kind, session=task.session or None, status="failed",
                           error=f"{type(exc).__name__}: {exc}")
                if task.kind == "open_world":
                    row.update(family=task.simulate.get("family"), seed=task.seed)
            # the row is here: its result on the worker is let go, so a worker lost later does not make the
            # cluster compute the task again ahead of those still waiting
            fut.release()
            rows.append(row)
            if progress:
                progress(len(rows), len(tasks), row)
    return sorted(rows, key=lambda r: r["task"])


def write_table(rows: list[dict], path: str | Path) -> Path:
    """The rows as CSV (one line per task, :data:`COLUMNS`)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k) for k in COLUMNS})
    return path


def summary(rows: list[dict]) -> dict:
    """Counts, and for simulated rides the h error and the interval's coverage of the truth."""
    ok = [r for r in rows if r["status"] == "ok"]
    out = {"tasks": len(rows), "ok": len(ok), "failed": len(rows) - len(ok),
           "failures": [{"task": r["task"], "session": r["session"], "seed": r["seed"], "error": r["error"]}
                        for r in rows if r["status"] != "ok"]}
    sim = [r for r in ok if r.get("h_true_m") is not None]
    if sim:
        err = [r["h_m"] - r["h_true_m"] for r in sim]
        covered = [r["h_ci95_lo_m"] <= r["h_true_m"] <= r["h_ci95_hi_m"] for r in sim
                   if r["h_ci95_lo_m"] is not None]
        n = len(err)
        mean = sum(err) / n
        sd = (sum((e - mean) ** 2 for e in err) / (n - 1)) ** 0.5 if n > 1 else float("nan")
        out["h_error_mean_m"] = mean
        out["h_error_se_m"] = sd / n ** 0.5 if n > 1 else float("nan")
        out["coverage_95"] = sum(covered) / len(covered) if covered else None
    return out


def task_dict(task: Task) -> dict:
    """JSON form of a task (for logs)."""
    return asdict(task)
