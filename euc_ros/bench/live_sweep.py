"""Benchmark: the live pipeline at every OptiTrack rate and body count, against the bare relay floor.

For every frame rate of :data:`RATES_HZ` and body count of :data:`BODIES` (``--quick``: the two cells
of :data:`CELLS`, 5 s each) a simulated figure-eight ride captured at that rate (:func:`live_recording`:
the EUC and 13 rider segments, plus static-offset copies of them as further rigid bodies, e.g. props or
a second rider the pipeline does not use) is replayed in real time by ``mocap_ingest`` into
``rider_state`` and ``torque_estimator`` (composed in one ``pipeline_container`` process, linked
in-process: :mod:`euc_ros.nodes.container`; three processes with ``composed=False``), with ``monitor``
and the ``recorder`` (every pipeline topic into an MCAP bag) as separate processes and the latency
probe of :mod:`euc_ros.bench.latency`. The floor is the bare relay chain of :mod:`euc_ros.bench.relay`
(source, two relay hops, each a plain rclpy node on rclpy's SingleThreadedExecutor) at the same rate
and body count, measured right after.

Per cell: hop and end-to-end p50/p99 (filter lag excluded, as in :mod:`~euc_ros.bench.latency`), the
CPU use of each process over the stream (1 = one core; ``/proc/<pid>/stat`` sampled every 0.2 s,
first second excluded), frames dropped (lost in transport, without a state, states without a
torque) and the frames the recorder's bag holds. Target per cell: 0 dropped and end-to-end p99 at
most :data:`TARGET_RATIO` x the floor's. The cells of :data:`SKELETON_CELLS` run again with the rider's CoG
from the fitted chain (``cog_method: skeleton``). The headline case (360 Hz x 14 bodies for 10 minutes) is
:mod:`euc_ros.bench.soak`.
"""
from __future__ import annotations

import dataclasses
import io
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from euc_ros.bench.common import BenchContext, cpu_fraction, figure
from euc_ros.bench.latency import analyze, measure_floor, probe_spec, rt_env, run_chain
from euc_ros.bench.probe import load
from euc_ros.bench.recording import bag_counts
from euc_ros.core.session import default_session, save_session
from euc_ros.ros.launcher import NodeSpec

#: Frame rates [Hz] and body counts of the full sweep (every pair is a cell).
RATES_HZ = (120, 240, 360, 500)
BODIES = (14, 28, 56)
#: Cells (rate [Hz], bodies) of the sweep: full (every rate with every body count) and --quick (its lightest
#: cell and a heavy one; 360 Hz x 14 bodies is the soak's).
CELLS = {False: tuple((r, n) for r in RATES_HZ for n in BODIES), True: ((120, 14), (360, 56))}
#: Cells run with the rider's CoG from the fitted chain (``cog_method: skeleton``, every frame fitted on its own),
#: in both variants: the rate and body count a lab with a 360 Hz system records.
SKELETON_CELLS = ((360, 14),)
#: Stream length per cell [s]: full and --quick.
CELL_S = {False: 60.0, True: 5.0}
#: Target: end-to-end p99 at most this multiple of the floor's.
TARGET_RATIO = 1.5
#: Seed and cache version of the recordings.
SEED = 11
CACHE_VERSION = 1


def extra_bodies(series, n_bodies: int):
    """``series`` with rigid bodies added up to ``n_bodies``.

    Copies of its bodies 3 m, 6 m, ... to the side (named ``<body>_c<k>``), tracked where the original is.
    Returns ``series`` if it has enough.
    """
    n0 = len(series.bodies)
    if n_bodies <= n0:
        return series
    idx = [i % n0 for i in range(n_bodies - n0)]
    copies = [i // n0 + 1 for i in range(n_bodies - n0)]
    shift = np.array([[0.0, 3.0 * k, 0.0] for k in copies])[:, None, :]
    names = [f"{series.bodies[i]}_c{k}" for i, k in zip(idx, copies)]
    return dataclasses.replace(
        series, bodies=list(series.bodies) + names,
        position=np.concatenate([series.position, series.position[idx] + shift]),
        quat=np.concatenate([series.quat, series.quat[idx]]),
        tracked=np.concatenate([series.tracked, series.tracked[idx]]),
        mean_marker_error=np.concatenate([series.mean_marker_error, series.mean_marker_error[idx]]))


def live_recording(cache_dir: Path, rate_hz: float, n_bodies: int, duration_s: float, log=None) -> dict[str, Path]:
    """``{"dir", "csv", "session"}`` of a cached simulated ride at ``rate_hz`` with ``n_bodies`` bodies."""
    root = Path(cache_dir) / f"live_{int(rate_hz)}hz_{n_bodies}b_{int(round(duration_s))}s_seed{SEED}_v{CACHE_VERSION}"
    csv, session = root / "ride.csv", root / "session.yaml"
    if not csv.exists():
        if log:
            log(f"  generating a {duration_s:g} s ride at {rate_hz:g} Hz with {n_bodies} bodies into {root} (once)")
        from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
        from euc_ros.core.ridesim.writers import write_motive_csv

        tmp = root.with_name(root.name + ".partial")
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        sess = dataclasses.replace(default_session("y"), rate_hz=float(rate_hz))
        ride = simulate_ride(RideConfig(maneuver="figure_eight", runs=1, seed=SEED, session=sess,
                                        duration_s=float(duration_s)))
        save_session(ride.session, tmp / "session.yaml")
        write_motive_csv(extra_bodies(ride.runs[0].mocap, n_bodies), tmp / "ride.csv")
        shutil.rmtree(root, ignore_errors=True)
        tmp.rename(root)
    return {"dir": root, "csv": csv, "session": session}


def stream_cpu(sampler, probe: dict, warmup_s: float = 1.0) -> dict[str, float]:
    """CPU use per process (1 = one core) while frames arrived at the probe (first ``warmup_s`` excluded)."""
    arr = probe.get("mocap__frame", {}).get("arrival_ns", np.zeros(0))
    if arr.size < 2:
        return {}
    t0, t1 = float(arr.min()) * 1e-9 + warmup_s, float(arr.max()) * 1e-9
    return {label: round(cpu_fraction(series, t0, t1), 3) for label, series in sampler.cpu.items()}


def measure_cell(rec: dict, out_dir: Path, *, record: bool = True, floor: bool = True, composed: bool = True,
                 log=None, realtime: int | None = None, cog_method: str = "segments") -> dict:
    """Pipeline (and floor) on one recording: :func:`euc_ros.bench.latency.analyze` per chain, CPU and bag.

    ``composed``: ingest, rider_state and torque_estimator in one ``pipeline_container`` process
    (:mod:`euc_ros.nodes.container`, linked in-process); otherwise three processes. ``realtime``:
    SCHED_FIFO priority of the estimation chain and the probe (the monitor and recorder stay at normal
    priority), and of every process of the floor. ``cog_method``: rider_state's (``segments`` or ``skeleton``).
    """
    from euc_ros.core.io.motive_csv import read_motive_csv

    series = read_motive_csv(rec["csv"])
    n_frames, rate, n_bodies = series.n_frames, float(series.rate_hz), len(series.bodies)
    del series
    duration = n_frames / rate
    out_dir.mkdir(parents=True, exist_ok=True)
    probe_out, bag = out_dir / "pipeline_probe.npz", out_dir / "bag"
    shutil.rmtree(bag, ignore_errors=True)
    session = str(rec["session"])
    rider = {"session_file": session, "cog_method": cog_method}
    env = rt_env(realtime)
    specs = [
        probe_spec(probe_out, realtime),
        NodeSpec("monitor", parameters={"expected_rate_hz": rate}, required=False),
    ]
    ingest = {"csv_path": str(rec["csv"]), "rate_factor": 1.0, "exit_when_done": True,
              "wait_subscribers": 3 + int(record), "start_delay": 1.0, "linger": 2.0}
    if composed:
        specs.append(NodeSpec("pipeline_container", parameters={**rider, "h": 0.61, **ingest},
                              env=env))
    else:
        specs += [
            NodeSpec("torque_estimator", parameters={"session_file": session, "h": 0.61}, required=False, env=env),
            NodeSpec("rider_state", parameters=rider, required=False, env=env),
            NodeSpec("mocap_ingest", parameters=ingest, env=env),
        ]
    if record:
        specs.insert(1, NodeSpec("recorder", parameters={"output": str(bag)}, required=False))
    sampler = run_chain(specs, probe_out, duration + 120.0, io.StringIO())
    data = load(probe_out)
    pipe = analyze(data, n_frames, rate)
    pipe["cpu"] = stream_cpu(sampler, data)
    pipe["peak_rss_mb"] = sampler.peaks_mb()
    if record:
        counts = bag_counts(bag) if (bag / "metadata.yaml").exists() else {}
        pipe["bag_counts"] = counts
        pipe["bag_frames"] = counts.get("/mocap/frame", 0)
    out = {"rate_hz": rate, "bodies": n_bodies, "duration_s": duration, "composed": composed, "realtime": realtime,
           "cog_method": cog_method, "pipeline": pipe}
    if floor:
        if log:
            log(f"    floor: bare relay chain, {n_frames} frames at {rate:g} Hz, {n_bodies} bodies")
        fl = measure_floor(n_frames, rate, n_bodies, out_dir, duration + 90.0, realtime=realtime)
        out["floor"] = fl
        out["ratio_p99"] = pipe["end_to_end"]["p99"] / fl["end_to_end"]["p99"]
    out["met"] = bool(pipe["frames_dropped"] == 0 and out.get("ratio_p99", 0.0) <= TARGET_RATIO
                      and (not record or out["pipeline"]["bag_frames"] == n_frames))
    return out


def cell_figure(cell: dict, label: str):
    """One table row: end-to-end p99 against the floor, drops, CPU in the note."""
    p, f = cell["pipeline"], cell["floor"]
    cpu = ", ".join(f"{k} {v:.2f}" for k, v in sorted(p["cpu"].items()) if np.isfinite(v))
    bag = f", bag {p['bag_frames']}/{p['frames_sent']} frames" if "bag_frames" in p else ""
    return figure(label, p["end_to_end"]["p99"], "ms", floor=f["end_to_end"]["p99"],
                  target=f"<= {TARGET_RATIO:g}x floor, 0 dropped", met=cell["met"],
                  note=(f"p50 {p['end_to_end']['p50']:.2f} ms (floor {f['end_to_end']['p50']:.2f}); hops p99 "
                        + " / ".join(f"{h['p99']:.2f}" for h in p["hops"].values())
                        + f" ms; dropped {p['frames_dropped']} of {p['frames_sent']}{bag}; CPU (cores) {cpu}"))


def run(ctx: BenchContext) -> dict:
    """The rate x body sweep (see the module docstring)."""
    plan = [(rate, n, "segments") for rate, n in CELLS[ctx.quick]] + [(r, n, "skeleton") for r, n in SKELETON_CELLS]
    recs = {(rate, n): live_recording(ctx.cache_dir, rate, n, CELL_S[ctx.quick], log=ctx.log)
            for rate, n, _ in plan}
    t_start = time.monotonic()
    cells = []
    figures = []
    for rate, n, cog in plan:
        skeleton = ", rider CoG from the fitted chain" if cog == "skeleton" else ""
        ctx.log(f"  pipeline at {rate} Hz with {n} bodies{skeleton}, {CELL_S[ctx.quick]:g} s")
        cell = measure_cell(recs[rate, n], ctx.tmp_dir / "live_sweep" / f"{rate}_{n}_{cog}", log=ctx.log,
                            realtime=ctx.realtime, cog_method=cog)
        cells.append(cell)
        figures.append(cell_figure(cell, f"{rate} Hz x {n} bodies{skeleton}: end-to-end p99"))
    return {"name": "live_sweep", "title": "Live pipeline at every rate and body count (with recorder and monitor)",
            "figures": figures, "details": {"cells": cells, "cell_s": CELL_S[ctx.quick], "machine_cores": _cores()},
            "wall_s": time.monotonic() - t_start}


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 0)


if __name__ == "__main__":   # pragma: no cover - a manual single cell: python -m euc_ros.bench.live_sweep RATE BODIES S [PRIO [COG]]  # noqa: E501
    import json
    import tempfile

    r, b, s = float(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    prio = int(sys.argv[4]) if len(sys.argv) > 4 else None      # optional SCHED_FIFO priority
    cog = sys.argv[5] if len(sys.argv) > 5 else "segments"    # optional rider CoG method
    cache = Path.home() / ".cache" / "euc_ros" / "bench"
    rec = live_recording(cache, r, b, s, log=print)
    with tempfile.TemporaryDirectory() as d:
        cell = measure_cell(rec, Path(d), log=print, realtime=prio, cog_method=cog)
    print(json.dumps({k: v for k, v in cell.items()}, indent=1, default=str))
