"""Benchmark: the headline live case, 360 Hz x 14 bodies for 10 minutes, through the whole pipeline.

``mocap_ingest`` replays a simulated 10-minute figure-eight ride captured at 360 Hz (14 rigid bodies)
in real time into ``rider_state``, ``torque_estimator``, ``monitor`` and the ``recorder`` (every
pipeline topic into an MCAP bag), with the latency probe; then the bare relay chain at the same rate
and body count for the same number of frames (the floor). Measured as one cell of
:mod:`euc_ros.bench.live_sweep`: end-to-end p50/p99 against the floor, frames dropped, frames in the
bag, CPU per process, peak RSS. Targets: 0 frames dropped, every frame in the bag, end-to-end
p99 at most 1.5x the floor's. ``--quick`` runs 10 s.
"""
from __future__ import annotations

import time

from euc_ros.bench.common import BenchContext, figure
from euc_ros.bench.live_sweep import cell_figure, live_recording, measure_cell

#: Stream length [s]: full and --quick.
DURATION_S = {False: 600.0, True: 10.0}
RATE_HZ, BODIES = 360, 14


def run(ctx: BenchContext) -> dict:
    """The soak (see the module docstring)."""
    duration = DURATION_S[ctx.quick]
    rec = live_recording(ctx.cache_dir, RATE_HZ, BODIES, duration, log=ctx.log)
    t0 = time.monotonic()
    ctx.log(f"  pipeline at {RATE_HZ} Hz with {BODIES} bodies for {duration:g} s, then the floor")
    cell = measure_cell(rec, ctx.tmp_dir / "soak", log=ctx.log, realtime=ctx.realtime)
    p = cell["pipeline"]
    span = f"{duration / 60:g} min" if duration >= 60 else f"{duration:g} s"
    figures = [cell_figure(cell, f"{span} at {RATE_HZ} Hz x {BODIES} bodies: end-to-end p99"),
               figure("frames dropped", p["frames_dropped"], "frames", floor=cell["floor"]["frames_dropped"],
                      target="0", met=p["frames_dropped"] == 0,
                      note=f"of {p['frames_sent']} sent; in the bag {p.get('bag_frames', 0)}; "
                           f"states {p['states']}, torques {p['torques']}, NaN torques {p['nan_torques']}")]
    rt = f", SCHED_FIFO {ctx.realtime}" if ctx.realtime is not None else ""
    return {"name": "soak", "title": f"Soak: {span} at {RATE_HZ} Hz x {BODIES} bodies, whole pipeline{rt}",  # noqa: E501
            "figures": figures, "peak_rss_mb": {f"pipeline {k}": v for k, v in p["peak_rss_mb"].items()},
            "details": cell, "wall_s": time.monotonic() - t0}
