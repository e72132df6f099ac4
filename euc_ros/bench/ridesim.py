"""Benchmark: real-time factor of the ride simulator per core (recorded seconds per CPU second).

Whole ride: :func:`~euc_ros.core.ridesim.simulate.simulate_ride` of the deceleration maneuver (7 s
recorded and 2 s settling per run, default noise, 6 runs; --quick: 1) with the compiled method
(the default): integration, sampling of the truth, 3-D placement of the skeleton and mocap synthesis.
Floor: the compiled integration of the same runs alone (balanced initial state and DOP853 with dense
output, :func:`~euc_ros.core.ridesim.simulate.integrate_run`): the physics with nothing around it.
The reference method (the Python right-hand side through ``scipy.integrate.solve_ivp``) is measured
on the same rides beside them. Each measurement runs in a fresh interpreter pinned to one CPU after one
untimed ride (the sympy derivation, or loading the compiled cache), three times; the figure is the median,
the note the spread. Time is the process's CPU time (``time.process_time``), so other load on a shared
machine does not count; the wall times are in the details.
"""
from __future__ import annotations

import time

from euc_ros.bench.common import BenchContext, figure, pinned_to_one_core

#: Runs per ride: full and --quick.
RUNS = {False: 6, True: 1}
#: Timed repeats of each measurement.
REPEATS = 3
MANEUVER = "deceleration"


def _config(runs: int, method: str, duration_s: float | None):
    from euc_ros.core.ridesim import RideConfig

    return RideConfig(maneuver=MANEUVER, runs=runs, seed=1, method=method, duration_s=duration_s)


def _timed(fn, repeats: int) -> tuple[list[float], list[float], object]:
    """CPU and wall seconds of ``repeats`` calls of fn on one core, and its last result."""
    cpu, wall = [], []
    with pinned_to_one_core():
        for _ in range(repeats):
            c0, w0 = time.process_time(), time.perf_counter()
            out = fn()
            cpu.append(time.process_time() - c0)
            wall.append(time.perf_counter() - w0)
    return cpu, wall, out


def measure_ride(runs: int, method: str, repeats: int = REPEATS, duration_s: float | None = None) -> dict:
    """Whole rides on one core: CPU and wall seconds, recorded seconds and real-time factors.

    Returns ``{"cpu_s": [...], "wall_s": [...], "recorded_s", "rtf": [...]}`` (``duration_s``: recorded
    seconds per run, default the maneuver's).
    """
    from euc_ros.core.ridesim import RideConfig, simulate_ride

    simulate_ride(RideConfig(maneuver=MANEUVER, runs=1, seed=0, duration_s=0.5, method=method))
    cpu, wall, ride = _timed(lambda: simulate_ride(_config(runs, method, duration_s)), repeats)
    recorded = float(sum(r.plan.duration_s for r in ride.runs))
    return {"cpu_s": cpu, "wall_s": wall, "recorded_s": recorded, "rtf": [recorded / c for c in cpu],
            "nfev": [r.solver_stats["nfev"] for r in ride.runs]}


def measure_integration(runs: int, repeats: int = REPEATS, duration_s: float | None = None) -> dict:
    """The compiled integration of the same runs alone, on one core (keys as :func:`measure_ride`)."""
    import numpy as np

    from euc_ros.core.ridesim.maneuvers import plan_run
    from euc_ros.core.ridesim.simulate import integrate_run, run_dynamics, true_params
    from euc_ros.core.ridesim.skeleton import Skeleton
    from euc_ros.core.ridesim.truth_model import PlanarParams

    config = _config(runs, "compiled", duration_s)
    session = config.nominal_session()
    params = true_params(PlanarParams.from_session(session), config.effects)
    skeleton = Skeleton.for_session(session)
    children = np.random.SeedSequence(config.seed).spawn(2 * runs)
    plans = [plan_run(MANEUVER, k, np.random.default_rng(children[2 * k]), duration_s) for k in range(runs)]
    dyns = [run_dynamics(p, config, params, skeleton) for p in plans]
    integrate_run(dyns[0], config, -0.5, 0.5)
    cpu, wall, _ = _timed(lambda: [integrate_run(d, config, -config.settle_s, p.duration_s)
                                   for p, d in zip(plans, dyns, strict=True)], repeats)
    recorded = float(sum(p.duration_s for p in plans))
    return {"cpu_s": cpu, "wall_s": wall, "recorded_s": recorded, "rtf": [recorded / c for c in cpu]}


def _spread(rtf: list[float]) -> str:
    return f"{min(rtf):.0f}-{max(rtf):.0f}x over {len(rtf)} runs"


def run(ctx: BenchContext) -> dict:
    """The ride-simulator benchmark (see the module docstring)."""
    import statistics

    t_start = time.monotonic()
    runs = RUNS[ctx.quick]
    ctx.log(f"  {runs} runs of {MANEUVER}, {REPEATS} repeats per method")
    fast = ctx.isolated("euc_ros.bench.ridesim:measure_ride", runs=runs, method="compiled")
    ref = ctx.isolated("euc_ros.bench.ridesim:measure_ride", runs=runs, method="reference")
    floor = ctx.isolated("euc_ros.bench.ridesim:measure_integration", runs=runs)
    med = {k: statistics.median(v["rtf"]) for k, v in (("fast", fast), ("ref", ref), ("floor", floor))}
    figures = [
        figure("ride simulation, compiled (whole ride)", med["fast"], "x real time per core", floor=med["floor"],
               lower_is_better=False, target=">= 100x real time", met=med["fast"] >= 100,
               note=f"{fast['recorded_s']:g} s recorded; {_spread(fast['rtf'])}; integration alone "
                    f"{_spread(floor['rtf'])}"),
        figure("ride simulation, reference (Python right-hand side, solve_ivp)", med["ref"], "x real time per core",
               floor=med["floor"], lower_is_better=False,
               note=f"{_spread(ref['rtf'])}; compiled {med['fast'] / med['ref']:.0f}x faster"),
    ]
    return {"name": "ridesim", "title": "Ride simulator real-time factor (one core)", "figures": figures,
            "peak_rss_mb": {"compiled": fast["peak_rss_mb"], "reference": ref["peak_rss_mb"],
                            "integration alone": floor["peak_rss_mb"]},
            "details": {"compiled": fast, "reference": ref, "integration": floor},
            "wall_s": time.monotonic() - t_start}
