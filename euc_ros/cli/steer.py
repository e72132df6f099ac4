"""`euc-ros steer`: one steering maneuver of the autonomous unicycle in closed loop over topics.

::

    euc-ros steer --maneuver lane_change|turn --speed V --out DIR [--json OUT] [--target T] [--pole -8]
                  [--dt 0.01] [--duration 10] [--timeout 120] [--overwrite] [--verbose]

Starts three processes through :mod:`euc_ros.ros.launcher`: ``recorder`` (``unicycle/state``,
``unicycle/command``, ``unicycle/pose`` into ``DIR/bag``), ``steering_controller`` and
``unicycle_sim`` in lockstep mode (each step waits for the command of that step, so the run is
deterministic and equals the in-process simulation). When the simulator ends (after ``--duration``
simulated seconds, or when the state leaves the model's domain) the launch is shut down, the bag
is read back, and the command writes ``DIR/steer_<maneuver>_<speed>.png`` (tilt, mass position,
yaw, input and the path, like Fig. 8 of the steering paper) and reports the final lateral error,
the final yaw error, max |u| and max tilt (printed, and as JSON with ``--json``).

Exit codes: 0 the maneuver ran to the end; 1 the state left the model's domain, or a process
failed or timed out; 2 a user error (e.g. a speed at which the gains are ill-conditioned).

:func:`euc_ros.lockstep.run_steer` is the same thing as a function.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from euc_ros.cli.figures.unicycle_maps import plot_run
from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.cli.unicycle import add_model_args, params_from_args
from euc_ros.core.errors import ConfigError
from euc_ros.lockstep import DEFAULT_TIMEOUT_S, SteerFailed, run_steer

HELP = "run a steering maneuver in closed loop over topics (simulator, controller, recorder as processes)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros steer``."""
    parser.add_argument("--maneuver", required=True, choices=("lane_change", "turn"))
    parser.add_argument("--speed", required=True, type=float, metavar="M/S",
                        help="design speed; the unicycle starts in straight rolling at this speed")
    parser.add_argument("--out", required=True, type=Path, metavar="DIR",
                        help="output directory (DIR/bag must not exist yet)")
    parser.add_argument("--json", type=Path, metavar="OUT", help="also write the report as JSON")
    parser.add_argument("--target", type=float, default=None,
                        help="lane change: final y_G in m (default -2.5 below the critical speed, -10 above); "
                             "turn: final yaw in deg (default -90, a right turn)")
    parser.add_argument("--pole", type=float, default=-8.0, metavar="1/S", help="closed-loop root (default -8)")
    parser.add_argument("--dt", type=float, default=0.01, metavar="S", help="control period (default 0.01)")
    parser.add_argument("--duration", type=float, default=10.0, metavar="S", help="simulated time (default 10)")
    parser.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT_S, metavar="S",
                        help=f"wall-clock limit of the run (default {DEFAULT_TIMEOUT_S:g})")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing bag DIR/bag")
    parser.add_argument("--verbose", action="store_true", help="stream the nodes' logs")
    add_model_args(parser)


def main(args: argparse.Namespace) -> int:
    """Run the maneuver over topics, print the report; 0 ok, 1 domain stop or failure."""
    check_outputs([Output("--out", args.out, "dir"), Output("--json", args.json)])
    target = args.target
    if target is not None and args.maneuver == "turn":
        target = math.radians(target)
    try:
        report = run_steer(args.maneuver, args.speed, args.out, target=target, pole=args.pole, dt=args.dt,
                           duration=args.duration, params=params_from_args(args), timeout=args.timeout,
                           stream=sys.stdout if args.verbose else None, overwrite=args.overwrite,
                           plot=plot_run)
    except SteerFailed as exc:
        print(f"euc-ros steer: error: {exc}", file=sys.stderr)
        return 1
    print(format_report(report))
    if args.json is not None:
        try:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(report, indent=2) + "\n")
        except OSError as exc:
            raise ConfigError(f"cannot write: {exc.strerror}", path=args.json) from None
    return 0 if report["status"] == "ok" else 1


def format_report(report: dict) -> str:
    """The printed summary of a run (one line per quantity)."""
    return "\n".join([
        f"{report['maneuver']} at {report['speed_m_per_s']:g} m/s over topics (lockstep): status {report['status']} "
        f"at t = {report['sim_time_s']:.2f} s ({report['steps']} steps, wall {report['wall_time_s']:.1f} s, "
        f"stepping {report['real_time_factor']:.1f}x real time)",
        f"  final lateral error  {report['final_lateral_error_m']:+.3e} m",
        f"  final yaw error      {report['final_yaw_error_rad']:+.3e} rad ({report['final_yaw_error_deg']:+.3e} deg)",
        f"  max |u|              {report['max_abs_u_n']:.3f} N",
        f"  max |tilt|           {report['max_tilt_rad']:.4f} rad ({report['max_tilt_deg']:.2f} deg)",
        "  gains                " + ", ".join(f"{k} {v:.2f}" for k, v in report["gains"].items()),
        f"  same run in process: final position differs by {report['in_process_difference_m']:.1e} m",
        f"  bag {report['bag']}",
        f"  figure {report['png']}",
    ])


