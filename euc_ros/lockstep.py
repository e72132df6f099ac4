"""One steering maneuver of the autonomous unicycle in closed loop over topics, in lockstep.

:func:`run_steer` starts three processes through :mod:`euc_ros.ros.launcher`: ``recorder``
(``unicycle/state``, ``unicycle/command``, ``unicycle/pose`` into ``DIR/bag``), ``steering_controller``
and ``unicycle_sim`` in lockstep mode (each step waits for the command of that step, so the run is
deterministic and equals the in-process simulation). When the simulator ends the launch is shut
down, the bag is read back (:func:`steer_result_from_bag`) and the run is reported. ``euc-ros steer``
(:mod:`euc_ros.cli.steer`) prints and plots it; the unicycle benchmark (:mod:`euc_ros.bench.unicycle`)
times it.
"""
from __future__ import annotations

import io
import math
import shutil
import time
from pathlib import Path
from typing import Callable

import numpy as np

from euc_ros.core.errors import ConfigError, EucError, InputError
from euc_ros.core.io.bags import read_bag
from euc_ros.core.unicycle.dynamics import UnicycleParams
from euc_ros.core.unicycle.linearize import straight_rolling_state
from euc_ros.core.unicycle.simulate import SimulationResult, maneuver_metrics, simulate
from euc_ros.core.unicycle.steering import SteeringController
from euc_ros.ros.launcher import Launcher, NodeSpec

#: Topics the recorder takes.
STEER_TOPICS = ("unicycle/state", "unicycle/command", "unicycle/pose")


#: Default wall-clock limit of a run [s].
DEFAULT_TIMEOUT_S = 120.0


class SteerFailed(EucError):
    """A process of the closed loop failed or the run timed out (exit code 1, not a user error)."""


def steer_result_from_bag(bag, dt: float):
    """The closed-loop run recorded in ``bag`` as a :class:`~euc_ros.core.unicycle.simulate.SimulationResult`.

    States are taken once per step (a resent state is a duplicate), in step order. ``u[k]`` is the
    input applied over step ``k`` (the ``u`` field of state ``k + 1``); ``y_des[k]`` is the
    reference of the command answering state ``k``.

    Returns
    -------
    result : SimulationResult
    log_ns : numpy.ndarray
        Receive times [ns] of the states at the recorder (wall clock).

    Raises
    ------
    InputError
        The bag holds no ``unicycle/state`` messages, or the steps are not contiguous from 0.
    """
    from euc_ros.ros.convert import UNICYCLE_STATE_FIELDS  # the ROS layer imports rclpy

    states: dict[int, tuple] = {}
    refs: dict[int, list] = {}
    for topic, _, log_ns, msg in read_bag(bag, topics=["/unicycle/state", "/unicycle/command"]):
        if topic == "/unicycle/state":
            states.setdefault(int(msg.step), (log_ns, msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec,
                                              [getattr(msg, f) for f in UNICYCLE_STATE_FIELDS], msg.u, msg.status))
        else:
            refs.setdefault(int(msg.step), list(msg.reference))
    if not states:
        raise InputError("no /unicycle/state messages", path=bag)
    steps = np.array(sorted(states))
    if steps[0] != 0 or np.any(np.diff(steps) != 1):
        raise InputError(f"state steps are not contiguous from 0 (have {len(steps)}, from {steps[0]} to "
                         f"{steps[-1]}): messages were lost", path=bag)
    rows = [states[k] for k in steps]
    log_ns = np.array([r[0] for r in rows], dtype=np.int64)
    t = np.array([r[1] for r in rows], dtype=np.int64) / 1e9
    x = np.array([r[2] for r in rows], dtype=float)
    u = np.array([r[3] for r in rows[1:]], dtype=float)
    y_des = np.array([refs.get(int(k), []) for k in steps[:-1]], dtype=object)
    width = max((len(r) for r in y_des), default=0)
    y = np.full((len(y_des), width), np.nan)
    for i, r in enumerate(y_des):
        y[i, :len(r)] = r
    return SimulationResult(t, x, u, y, str(rows[-1][4]), float(dt)), log_ns


def _remove_bag(bag: Path) -> None:
    """Delete a rosbag2 directory, refusing anything that does not look like one."""
    entries = list(bag.iterdir()) if bag.is_dir() else []
    if not bag.is_dir() or any(not (e.is_file() and (e.suffix == ".mcap" or e.name == "metadata.yaml"))
                               for e in entries):
        raise ConfigError("exists and is not a bag directory (metadata.yaml and .mcap files only); not replacing it",
                          path=bag)
    shutil.rmtree(bag)


def run_steer(maneuver: str, speed: float, out_dir, *, target: float | None = None, pole: float = -8.0,
              dt: float = 0.01, duration: float = 10.0, params=None, timeout: float = DEFAULT_TIMEOUT_S,
              stream=None, overwrite: bool = False,
              plot: Callable[[SimulationResult, SteeringController, Path], None] | None = None) -> dict:
    """Run one maneuver over topics (recorder, controller, simulator as processes) and report it.

    Parameters
    ----------
    maneuver : {'lane_change', 'turn'}
    speed : float
        Design and initial speed [m/s].
    out_dir : str or Path
        Output directory: ``bag/`` (must not exist) and ``steer_<maneuver>_<speed>.png``.
    target : float, optional
        Lane change: final ``y_G`` [m]; turn: final yaw [rad] (defaults as in
        :class:`~euc_ros.core.unicycle.steering.SteeringController`).
    pole, dt, duration : float
        Closed-loop root [1/s], control period [s], simulated time [s].
    params : UnicycleParams, optional
        Model (Table I by default), used by the simulator and for the design.
    timeout : float
        Wall-clock limit [s].
    stream : file, optional
        Where the nodes' logs go (default: kept, and shown in the error of a failed run).
    overwrite : bool
        Replace an existing ``DIR/bag`` (only a directory that holds nothing but a bag's
        ``metadata.yaml`` and ``.mcap`` files).
    plot : callable, optional
        ``plot(result, controller, png_path)`` draws the run into ``png_path``
        (``DIR/steer_<maneuver>_<speed>.png``, reported as ``png``); without it no figure is made
        (``png`` is None).

    Returns
    -------
    dict
        The report (keys ``maneuver``, ``speed_m_per_s``, ``final_lateral_error_m``,
        ``final_yaw_error_rad``, ``max_abs_u_n``, ``max_tilt_rad``, ``max_tilt_deg``, ``status``,
        ``gains``, ``closed_loop_roots``, ``sim_time_s``, ``wall_time_s`` and more; see
        ``docs/steering.md``).

    Raises
    ------
    ConfigError
        Bad maneuver, speed (e.g. where the gains are ill-conditioned), pole, target, dt or duration,
        or an existing ``DIR/bag``.
    SteerFailed
        A process failed or the run did not end within ``timeout``.
    """
    params = UnicycleParams() if params is None else params
    ctrl = SteeringController(params, maneuver, speed, pole, target=target)   # validates; the gains for the report
    if not (math.isfinite(dt) and 1e-4 <= dt <= 1.0):
        raise ConfigError(f"must be a control period in [1e-4, 1] s, got {dt!r}", key="dt")
    if not (math.isfinite(duration) and dt <= duration <= 1e5):
        raise ConfigError(f"must be a simulated time in [dt, 1e5] s, got {duration!r}", key="duration")
    out = Path(out_dir)
    bag = out / "bag"
    if bag.exists():
        if not overwrite:
            raise ConfigError("already exists; remove it, choose another --out or pass --overwrite", path=bag)
        _remove_bag(bag)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create: {exc.strerror}", path=out) from None

    model = {"wheel_mass": params.m, "point_mass": params.m0, "radius": params.R, "gravity": params.g}
    ctrl_params = {"maneuver": ctrl.maneuver, "speed": ctrl.speed, "pole": float(pole), "wait_observers": 1,
                   "maneuver_start": ctrl.start, "maneuver_duration": ctrl.duration, **model}
    ctrl_params["lane_offset" if ctrl.maneuver == "lane_change" else "turn_angle"] = ctrl.target
    specs = [
        NodeSpec("recorder", parameters={"output": str(bag), "topics": list(STEER_TOPICS)}, required=False),
        NodeSpec("steering_controller", parameters=ctrl_params),
        NodeSpec("unicycle_sim", parameters={"mode": "lockstep", "speed": ctrl.speed, "dt": float(dt),
                                             "duration": float(duration), "wait_observers": 1, **model}),
    ]
    log = io.StringIO() if stream is None else stream
    t0 = time.monotonic()
    with Launcher(specs, stream=log) as launcher:
        finished = launcher.wait(timeout=timeout)
    wall = time.monotonic() - t0
    codes = launcher.exit_codes

    def _fail(why: str) -> SteerFailed:
        tail = "" if stream is not None else " | ".join(log.getvalue().strip().splitlines()[-6:])
        return SteerFailed(why + (f"; last log lines: {tail}" if tail else ""))

    if not finished or "unicycle_sim" not in codes or launcher.failed != "unicycle_sim":
        if launcher.failed and launcher.failed != "unicycle_sim":
            raise _fail(f"{launcher.failed} exited with code {codes.get(launcher.failed)} before the simulation ended")
        raise _fail(f"the simulation did not end within {timeout:g} s of wall time")
    if codes["unicycle_sim"] not in (0, 1):
        raise _fail(f"unicycle_sim exited with code {codes['unicycle_sim']}")
    if not bag.exists():
        raise _fail("the recorder wrote no bag")

    try:
        result, log_ns = steer_result_from_bag(bag, dt)
    except InputError as exc:
        raise _fail(f"the recorded run is unusable: {exc}") from None
    met = maneuver_metrics(result, ctrl)
    # wall time of the stepping, from the first answered state on (start-up waits for DDS discovery)
    stepping_s = max((log_ns[-1] - log_ns[min(1, len(log_ns) - 1)]) / 1e9, 1e-9) * len(log_ns) / max(len(log_ns) - 1, 1)
    # the same run in process (a check that the topics changed nothing)
    ref = simulate(params, ctrl, straight_rolling_state(params, ctrl.speed), duration, dt)
    n = min(len(ref.x), len(result.x))
    diff = float(np.hypot(*(result.x[n - 1, 8:10] - ref.x[n - 1, 8:10])))
    png = None
    if plot is not None:
        png = out / f"steer_{ctrl.maneuver}_{ctrl.speed:g}.png"
        plot(result, ctrl, png)
    return {
        "maneuver": ctrl.maneuver, "speed_m_per_s": ctrl.speed, "target": ctrl.target,
        "target_unit": "m" if ctrl.maneuver == "lane_change" else "rad",
        "final_lateral_error_m": met.final_lateral_error, "final_yaw_error_rad": met.final_yaw_error,
        "final_yaw_error_deg": math.degrees(met.final_yaw_error), "max_abs_u_n": met.max_abs_u,
        "max_tilt_rad": met.max_abs_tilt, "max_tilt_deg": math.degrees(met.max_abs_tilt), "status": met.status,
        "gains": {name: float(k) for name, k in zip(ctrl.gains.names, ctrl.gains.K)},
        "gain_units": ctrl.gains.as_dict()["units"],
        "closed_loop_roots": [[float(z.real), float(z.imag)] for z in ctrl.gains.closed_loop_roots],
        "pole": ctrl.gains.pole, "dt_s": float(dt), "steps": int(len(result.x) - 1), "sim_time_s": met.t_end,
        "wall_time_s": wall, "stepping_wall_time_s": stepping_s, "real_time_factor": met.t_end / stepping_s,
        "final_x_g_m": float(result.x[-1, 8]), "final_y_g_m": float(result.x[-1, 9]),
        "in_process_difference_m": diff, "exit_codes": dict(codes), "bag": str(bag),
        "png": None if png is None else str(png),
    }
