"""Benchmark 5: real-time factor of the autonomous-unicycle simulation, in process and over topics.

In process: :func:`euc_ros.core.unicycle.simulate.simulate` of the steering paper's lane change
(Table I model, 1 m/s, pole -8, dt 10 ms, 5 RK4 substeps) with the
:class:`~euc_ros.core.unicycle.steering.SteeringController` in the loop, one core. Floor: the same
number of RK4 substeps of the same equations of motion
(:func:`~euc_ros.core.unicycle.simulate.rk4_step`) in a bare loop, no controller and no
bookkeeping: the physics alone.

Lockstep over topics: ``euc-ros steer`` (:func:`euc_ros.lockstep.run_steer`: ``unicycle_sim`` in
lockstep mode, ``steering_controller`` and ``recorder`` as processes); its real-time factor is the
simulated time over the wall time of the stepping (from the first answered state on). Floor: a bare
rclpy lockstep ping-pong (:mod:`euc_ros.bench.relay` ``lockstep-sim``/``lockstep-ctrl``) exchanging
UnicycleState and SteeringCommand with the same QoS, one round trip per step.
"""
from __future__ import annotations

import io
import json
import os
import sys
import time
from pathlib import Path

from euc_ros.bench.common import BenchContext, BenchError, PeakRssSampler, figure, pinned_to_one_core, run_launched
from euc_ros.core.unicycle.dynamics import UnicycleParams
from euc_ros.core.unicycle.linearize import straight_rolling_state
from euc_ros.core.unicycle.simulate import DEFAULT_SUBSTEPS, rk4_step, simulate
from euc_ros.core.unicycle.steering import SteeringController
from euc_ros.lockstep import run_steer
from euc_ros.ros.launcher import NodeSpec

#: Simulated time [s] in process and over topics: full and --quick.
IN_PROCESS_S = {False: 600.0, True: 30.0}
LOCKSTEP_S = {False: 20.0, True: 5.0}
DT = 0.01


def measure_in_process(t_end: float) -> dict:
    """Closed-loop lane change in process on one core: ``{"wall_s", "sim_s", "rtf", "status"}``."""
    p = UnicycleParams()
    ctrl = SteeringController(p, "lane_change", 1.0, -8.0)
    x0 = straight_rolling_state(p, 1.0)
    with pinned_to_one_core():
        t0 = time.perf_counter()
        res = simulate(p, ctrl, x0, t_end, DT)
        wall = time.perf_counter() - t0
    sim_s = float(res.t[-1] - res.t[0])
    return {"wall_s": wall, "sim_s": sim_s, "rtf": sim_s / wall, "status": res.status}


def measure_physics_floor(t_end: float) -> dict:
    """The RK4 substeps alone on one core: ``{"wall_s", "sim_s", "rtf"}``."""
    p = UnicycleParams()
    x = [float(v) for v in straight_rolling_state(p, 1.0)]
    n = int(round(t_end / DT))
    h = DT / DEFAULT_SUBSTEPS
    with pinned_to_one_core():
        t0 = time.perf_counter()
        for _ in range(n * DEFAULT_SUBSTEPS):
            x = rk4_step(p, x, 0.0, h)
        wall = time.perf_counter() - t0
    return {"wall_s": wall, "sim_s": n * DT, "rtf": n * DT / wall}


def measure_lockstep_floor(steps: int, out_dir, timeout_s: float = 120.0) -> dict:
    """Bare rclpy lockstep ping-pong of ``steps`` steps: ``{"steps_per_s", "rtf", "peak_rss_mb"}``."""
    result = Path(out_dir) / "lockstep_floor.json"
    relay = ["-m", "euc_ros.bench.relay"]
    specs = [NodeSpec(sys.executable, name="lockstep_ctrl", args=[*relay, "lockstep-ctrl"], ros_args=False,
                      required=False),
             NodeSpec(sys.executable, name="lockstep_sim", ros_args=False,
                      args=[*relay, "lockstep-sim", "--steps", str(steps), "--dt", str(DT), "--result", str(result)])]
    log = io.StringIO()
    launcher, finished, peaks = run_launched(specs, timeout_s, log)
    if not finished or not result.exists():
        raise BenchError("lockstep floor failed: " + " | ".join(log.getvalue().strip().splitlines()[-6:]))
    r = json.loads(result.read_text(encoding="utf-8"))
    r["rtf"] = r["steps_per_s"] * DT
    r["peak_rss_mb"] = peaks
    return r


def run(ctx: BenchContext) -> dict:
    """Benchmark 5 (see the module docstring)."""
    t_start = time.monotonic()
    t_in = IN_PROCESS_S[ctx.quick]
    ctx.log(f"  in process: {t_in:g} s simulated")
    inproc = ctx.isolated("euc_ros.bench.unicycle:measure_in_process", t_end=t_in)
    phys = ctx.isolated("euc_ros.bench.unicycle:measure_physics_floor", t_end=t_in)
    t_ls = LOCKSTEP_S[ctx.quick]
    out = ctx.tmp_dir / "unicycle"
    ctx.log(f"  lockstep over topics: {t_ls:g} s simulated")
    with PeakRssSampler(children_of=os.getpid()) as rss:
        report = run_steer("lane_change", 1.0, out / "steer", duration=t_ls, dt=DT)
    steer_rss = rss.peaks_mb()
    floor = measure_lockstep_floor(int(round(t_ls / DT)) + 1, out)
    figures = [
        figure("in process (closed loop)", inproc["rtf"], "x real time", floor=phys["rtf"], lower_is_better=False,
               note=f"{inproc['sim_s']:g} s in {inproc['wall_s']:.2f} s; the RK4 physics alone "
                    f"{phys['wall_s']:.2f} s"),
        figure("lockstep over topics", report["real_time_factor"], "x real time", floor=floor["rtf"],
               lower_is_better=False,
               note=f"{report['steps']} steps, {report['real_time_factor'] / DT:.0f} steps/s; bare ping-pong "
                    f"{floor['steps_per_s']:.0f} steps/s"),
    ]
    return {"name": "unicycle", "title": "Unicycle simulation real-time factor", "figures": figures,
            "peak_rss_mb": {"in process": inproc["peak_rss_mb"], "physics floor": phys["peak_rss_mb"],
                            **{f"steer {k}": v for k, v in steer_rss.items()},
                            **{f"floor {k}": v for k, v in floor["peak_rss_mb"].items()}},
            "details": {"in_process": inproc, "physics_floor": phys, "steer_status": report["status"],
                        "steer_steps": report["steps"], "steer_rtf": report["real_time_factor"],
                        "lockstep_floor": {k: v for k, v in floor.items() if k != "peak_rss_mb"}},
            "wall_s": time.monotonic() - t_start}
