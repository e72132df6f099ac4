"""`euc-ros unicycle`: the autonomous unicycle offline: gains, steady states, stability maps, maneuvers.

Subcommands::

    euc-ros unicycle gains --maneuver lane_change|turn --speed V [--pole -8] [--json OUT]
    euc-ros unicycle steady-states [--speed V ...] [--json OUT]
    euc-ros unicycle stability --out DIR [--grid N]
    euc-ros unicycle simulate --maneuver lane_change|turn --speed V [--target T] [--t-end 10] [--json OUT] [--plot PNG]

Model parameters default to Table I of the steering paper (``--wheel-mass``, ``--point-mass``,
``--radius``, ``--gravity`` override them). Figures use matplotlib (imported lazily, Agg backend).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from euc_ros.cli.figures.unicycle_maps import plot_run, stability_figures
from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import ConfigError
from euc_ros.core.unicycle import linearize as lz
from euc_ros.core.unicycle import steady as st
from euc_ros.core.unicycle import steering as sg
from euc_ros.core.unicycle.dynamics import UnicycleParams
from euc_ros.core.unicycle.linearize import straight_rolling_state
from euc_ros.core.unicycle.simulate import maneuver_metrics, simulate
from euc_ros.core.unicycle.steering import SteeringController, steering_gains

HELP = "autonomous unicycle: steering gains, steady states, stability maps, maneuver simulation"


def add_model_args(p: argparse.ArgumentParser) -> None:
    """The model options (Table I defaults) of a ``euc-ros unicycle`` subcommand.

    Parameters
    ----------
    p : argparse.ArgumentParser
        The subcommand's parser.
    """
    d = UnicycleParams()
    g = p.add_argument_group("model (Table I defaults)")
    g.add_argument("--wheel-mass", type=float, default=d.m, metavar="KG", help=f"wheel mass m (default {d.m})")
    g.add_argument("--point-mass", type=float, default=d.m0, metavar="KG",
                   help=f"point mass m0 on the axle (default {d.m0})")
    g.add_argument("--radius", type=float, default=d.R, metavar="M", help=f"wheel radius R (default {d.R})")
    g.add_argument("--gravity", type=float, default=d.g, metavar="M/S2", help=f"gravity g (default {d.g})")


def params_from_args(args: argparse.Namespace):
    """The :class:`UnicycleParams` of the model options (:func:`add_model_args`).

    Parameters
    ----------
    args : argparse.Namespace

    Returns
    -------
    UnicycleParams
    """
    return UnicycleParams(m=args.wheel_mass, m0=args.point_mass, R=args.radius, g=args.gravity)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros unicycle``."""
    sub = parser.add_subparsers(dest="unicycle_command", metavar="SUBCOMMAND", required=True)

    p = sub.add_parser("gains", help="gains placing every non-zero closed-loop root at --pole (Tables II, III)")
    p.add_argument("--maneuver", required=True, choices=("lane_change", "turn"))
    p.add_argument("--speed", required=True, type=float, metavar="M/S", help="design speed v = R phi_dot*")
    p.add_argument("--pole", type=float, default=-8.0, metavar="1/S", help="closed-loop root (default -8)")
    p.add_argument("--json", type=Path, metavar="OUT", help="write the gains and closed-loop roots as JSON")
    add_model_args(p)

    p = sub.add_parser("steady-states", help="critical pitch rates, speeds and tilt angle; controllability ranks")
    p.add_argument("--speed", type=float, nargs="+", default=[1.0, 5.0], metavar="M/S",
                   help="speeds for the controllability ranks (default 1 5)")
    p.add_argument("--json", type=Path, metavar="OUT", help="write the values as JSON")
    add_model_args(p)

    p = sub.add_parser("stability", help="stability maps like Figs 3, 5 and 6 of the paper (PNG)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="directory for the PNG files")
    p.add_argument("--grid", type=int, default=160, metavar="N", help="grid points per axis (default 160)")
    add_model_args(p)

    p = sub.add_parser("simulate", help="run a maneuver in closed loop on the nonlinear model (in-process)")
    p.add_argument("--maneuver", required=True, choices=("lane_change", "turn"))
    p.add_argument("--speed", required=True, type=float, metavar="M/S")
    p.add_argument("--target", type=float, default=None,
                   help="lane change: final y_G in m (default -2.5 below the critical speed, -10 above); "
                        "turn: final yaw in deg (default -90, a right turn)")
    p.add_argument("--pole", type=float, default=-8.0, metavar="1/S")
    p.add_argument("--t-end", type=float, default=10.0, metavar="S", help="simulated time (default 10)")
    p.add_argument("--dt", type=float, default=0.01, metavar="S", help="control period (default 0.01)")
    p.add_argument("--max-tilt", type=float, default=80.0, metavar="DEG", help="stop at this |tilt| (default 80)")
    p.add_argument("--json", type=Path, metavar="OUT", help="write the metrics as JSON")
    p.add_argument("--plot", type=Path, metavar="PNG", help="plot the run (like Fig. 8)")
    add_model_args(p)


def main(args: argparse.Namespace) -> int:
    """Dispatch to the subcommand."""
    check_outputs([Output("--json", getattr(args, "json", None)), Output("--out", getattr(args, "out", None), "dir")])
    return {"gains": _gains, "steady-states": _steady_states, "stability": _stability,
            "simulate": _simulate}[args.unicycle_command](args)


def _write_json(path: Path | None, data: dict) -> None:
    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=2) + "\n")
    except OSError as exc:
        raise ConfigError(f"cannot write: {exc.strerror}", path=path) from None


# ---------------------------------------------------------------------------------------------
def _gains(args: argparse.Namespace) -> int:
    g = steering_gains(params_from_args(args), args.maneuver, args.speed, args.pole)
    data = g.as_dict()
    print(f"{g.maneuver} at {g.speed:g} m/s, every non-zero closed-loop root at {g.pole:g} 1/s")
    for name, k in zip(g.names, g.K):
        print(f"  {name:8s} {k:12.2f} {data['units'][name]}")
    roots = ", ".join(f"{z.real:.3f}{z.imag:+.3f}j" if abs(z.imag) > 5e-4 else f"{z.real:.3f}"
                      for z in g.closed_loop_roots)
    print(f"  closed-loop roots: {roots}")
    _write_json(args.json, data)
    return 0


def steady_state_summary(params, speeds=(1.0, 5.0)) -> dict:
    """Critical values (eqs (23), (27), (31), (44), (54)) and controllability ranks (eqs (56), (63))."""
    out = {
        "wheel_critical_pitch_rate": st.wheel_critical_pitch_rate(params),
        "wheel_critical_speed": st.wheel_critical_speed(params),
        "unicycle_critical_pitch_rate": st.unicycle_critical_pitch_rate(params),
        "unicycle_critical_speed": st.critical_speed(params),
        "critical_tilt_angle_deg": math.degrees(st.critical_tilt_angle()),
        "spinning_critical_yaw_rate": st.spinning_critical_yaw_rate(params),
        "units": {"pitch_rate": "rad/s", "speed": "m/s", "yaw_rate": "rad/s"},
        "controllability": [],
    }
    if params.m0 > 0:
        out["non_tilted_turning_yaw_rate"] = st.non_tilted_turning(0.0, params)[0]
        for v in speeds:
            A, B = lz.linearize_straight_rolling(params, sg.check_speed(params, v))
            Mc = sg.controllability_matrix(A, B)
            out["controllability"].append({
                "speed": float(v), "rank": sg.numerical_rank(Mc),
                "output_rank": {m: sg.numerical_rank(sg.output_matrix(m) @ Mc) for m in sg.MANEUVERS},
                "open_loop_stable": st.straight_rolling_is_stable(params, v / params.R)})
    return out


def _steady_states(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    s = steady_state_summary(params, args.speed)
    print(f"wheel:    critical pitch rate sqrt(g/3R) = {s['wheel_critical_pitch_rate']:.4f} rad/s "
          f"({s['wheel_critical_speed']:.4f} m/s)")
    print(f"unicycle: critical pitch rate sqrt(g/2R) = {s['unicycle_critical_pitch_rate']:.4f} rad/s "
          f"({s['unicycle_critical_speed']:.4f} m/s)")
    print(f"critical tilt angle (eq 23): {s['critical_tilt_angle_deg']:.2f} deg; "
          f"spinning critical yaw rate: {s['spinning_critical_yaw_rate']:.4f} rad/s")
    for c in s["controllability"]:
        print(f"at {c['speed']:g} m/s: rank Mc = {c['rank']}, output ranks "
              + ", ".join(f"{k} {v}" for k, v in c["output_rank"].items())
              + f"; open-loop straight rolling {'stable' if c['open_loop_stable'] else 'unstable'}")
    _write_json(args.json, s)
    return 0


def _stability(args: argparse.Namespace) -> int:
    try:
        paths = stability_figures(params_from_args(args), args.out, args.grid)
    except OSError as exc:
        raise ConfigError(f"cannot write figures: {exc.strerror}", path=args.out) from None
    for p in paths:
        print(p)
    return 0


def _simulate(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    target = args.target
    if target is not None and args.maneuver == "turn":
        target = math.radians(target)
    if not (0 < args.max_tilt < 90):
        raise ConfigError(f"must lie in (0, 90) deg, got {args.max_tilt!r}", key="max_tilt")
    ctrl = SteeringController(params, args.maneuver, args.speed, args.pole, target=target)
    res = simulate(params, ctrl, straight_rolling_state(params, ctrl.speed), args.t_end, args.dt,
                   max_tilt=math.radians(args.max_tilt))
    met = maneuver_metrics(res, ctrl)
    data = {"maneuver": ctrl.maneuver, "speed": ctrl.speed, "target": ctrl.target, **met.as_dict(),
            "gains": {n: float(k) for n, k in zip(ctrl.gains.names, ctrl.gains.K)}}
    print(f"{ctrl.maneuver} at {ctrl.speed:g} m/s: status {met.status} at t = {met.t_end:.2f} s; "
          f"final lateral error {met.final_lateral_error:.3e} m, final yaw error "
          f"{math.degrees(met.final_yaw_error):.3e} deg, max |u| {met.max_abs_u:.2f} N, "
          f"max |tilt| {math.degrees(met.max_abs_tilt):.2f} deg")
    _write_json(args.json, data)
    if args.plot is not None:
        plot_run(res, ctrl, args.plot)
    return 0 if met.status == "ok" else 1


if __name__ == "__main__":  # pragma: no cover
    from euc_ros.cli.main import main as _main

    sys.exit(_main(["unicycle", *sys.argv[1:]]))
