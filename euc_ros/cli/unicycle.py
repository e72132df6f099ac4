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

import numpy as np

from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.cli.plots import save_figure
from euc_ros.core.errors import ConfigError
from euc_ros.core.unicycle import linearize as lz
from euc_ros.core.unicycle import steady as st
from euc_ros.core.unicycle import steering as sg
from euc_ros.core.unicycle.dynamics import UnicycleParams
from euc_ros.core.unicycle.linearize import straight_rolling_state
from euc_ros.core.unicycle.simulate import maneuver_metrics, reference_path, simulate
from euc_ros.core.unicycle.steering import SteeringController, steering_gains

HELP = "autonomous unicycle: steering gains, steady states, stability maps, maneuver simulation"

#: Point masses of the panels of the Fig. 6-like map [kg].
FIG6_MASSES = (0.0, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0)
#: Tilt range of the maps [deg] and yaw-rate range [rad/s].
MAP_TILT_DEG = 85.0
MAP_YAW_RATE = 15.0


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


# ---------------------------------------------------------------------------------------------
def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


_COLORS = ("#ffffff", "#e66a6a", "#77c777")  # infeasible / unstable / stable


def _category(smap) -> np.ndarray:
    return np.where(~smap.feasible, 0, np.where(smap.stable, 2, 1))


def _fold_category(n_stable, n_unstable) -> np.ndarray:
    """0 none, 1 unstable only, 2 one stable, 3 two or more stable, 4 stable and unstable."""
    return np.select([(n_stable == 0) & (n_unstable == 0), n_stable == 0, (n_unstable == 0) & (n_stable == 1),
                      n_unstable == 0], [0, 1, 2, 3], default=4)


def _map_axes(grid: int):
    th = np.radians(np.linspace(-MAP_TILT_DEG, MAP_TILT_DEG, grid))
    pd = np.linspace(-MAP_YAW_RATE, MAP_YAW_RATE, grid + (grid % 2 == 1))  # even count: avoid psi_dot = 0
    return th, pd


def stability_figures(params, out_dir: Path, grid: int = 160) -> list[Path]:
    """Write PNG maps like Figs 3, 5 and 6 of the steering paper into ``out_dir``; return the paths.

    * ``fig3_wheel_stability.png``: turning rolling of the wheel in the (tilt, yaw rate),
      (yaw rate, pitch rate) and (tilt, pitch rate) planes, green stable, red unstable, with the
      critical yaw rates (22) and the critical tilt angle (23).
    * ``fig5_unicycle_steady_states.png``: steady states of the unicycle: where the point mass is
      below the wheel centre, above it, or below the ground (eq (47)); straight rolling,
      non-tilted turning (44), spinning and tilted spinning (46).
    * ``fig6_unicycle_stability.png``: stability of turning rolling for ``m0`` in
      :data:`FIG6_MASSES`.
    """
    from matplotlib.colors import ListedColormap

    if grid < 8:
        raise ConfigError(f"needs at least 8 points per axis, got {grid}", key="grid")
    plt = _pyplot()
    out_dir.mkdir(parents=True, exist_ok=True)
    cmap = ListedColormap(_COLORS)
    th, pd = _map_axes(grid)
    thd = np.degrees(th)
    paths = []

    # Fig. 3: the wheel
    w = st.wheel_stability_map(params, th, pd)
    cat = _category(w)
    TH, PD = np.meshgrid(thd, pd, indexing="ij")
    fig, ax = plt.subplots(1, 3, figsize=(16, 5))
    ax[0].pcolormesh(TH, PD, cat, cmap=cmap, vmin=0, vmax=2, shading="nearest")
    lev = [-20, -10, -5, -2, 2, 5, 10, 20]
    masked = np.where(np.abs(w.phi_dot) < 60, w.phi_dot, np.nan)   # phi_dot* jumps through infinity at psi_dot* = 0
    cs = ax[0].contour(TH, PD, masked, levels=lev, colors="k", linewidths=0.6)
    ax[0].clabel(cs, fontsize=7)
    c1, c2 = st.wheel_critical_yaw_rates(th, params)
    for sgn in (1, -1):
        ax[0].plot(thd, sgn * c1, "b-", lw=1.2)
        ax[0].plot(thd, sgn * c2, "b-", lw=1.2)
    for sgn in (1, -1):
        ax[0].axvline(sgn * np.degrees(st.critical_tilt_angle()), color="b", ls=":", lw=1)
    ax[0].set(xlabel="tilt angle theta* [deg]", ylabel="yaw rate psi_dot* [rad/s]",
              title="(a) stability, level sets of phi_dot* [rad/s]", ylim=(-MAP_YAW_RATE, MAP_YAW_RATE))
    # (b), (c): count the steady states through each point (the surface folds)
    fold_cmap = ListedColormap(["#ffffff", "#e66a6a", "#77c777", "#1f7a33", "#f2d13a"])
    fd_axis = np.linspace(-30, 30, grid + (grid % 2 == 1))
    PDb, FDb = np.meshgrid(pd, fd_axis, indexing="ij")
    ns, nu = st.wheel_steady_state_counts_rates(params, PDb, FDb, max_tilt=th[-1])
    ax[1].pcolormesh(PDb, FDb, _fold_category(ns, nu), cmap=fold_cmap, vmin=0, vmax=4, shading="nearest")
    ax[1].set(xlabel="yaw rate psi_dot* [rad/s]", ylabel="pitch rate phi_dot* [rad/s]",
              title="(b) in the (psi_dot*, phi_dot*) plane")
    THc, FDc = np.meshgrid(th, fd_axis, indexing="ij")
    ns, nu = st.wheel_steady_state_counts_tilt(params, THc, FDc)
    ax[2].pcolormesh(np.degrees(THc), FDc, _fold_category(ns, nu), cmap=fold_cmap, vmin=0, vmax=4, shading="nearest")
    ax[2].set(xlabel="tilt angle theta* [deg]", ylabel="pitch rate phi_dot* [rad/s]",
              title="(c) in the (theta*, phi_dot*) plane")
    for a in (ax[1], ax[2]):
        a.axhline(st.wheel_critical_pitch_rate(params), color="b", ls="--", lw=0.8)
        a.axhline(-st.wheel_critical_pitch_rate(params), color="b", ls="--", lw=0.8)
    fig.suptitle(f"Rolling wheel (R = {params.R} m), turning rolling: green stable, red unstable, dark green two "
                 f"stable states, yellow a stable and an unstable one, white none;\nblue: critical yaw rates (22), "
                 f"critical tilt (23), critical pitch rate (27)")
    paths.append(save_figure(fig, out_dir / "fig3_wheel_stability.png"))

    # Fig. 5: unicycle steady states
    if params.m0 > 0:
        u = st.unicycle_stability_map(params, th, pd)
        zG = params.R * np.cos(TH * np.pi / 180)
        region = np.where(~u.feasible, 0, np.where(u.mass_height > zG, 2, 1))
        fig, ax = plt.subplots(figsize=(8, 6))
        ax.pcolormesh(TH, PD, region, cmap=ListedColormap(["#ffffff", "#9fd3f0", "#c9a8e8"]), vmin=0, vmax=2,
                      shading="nearest")
        ax.axvline(0, color="k", lw=1.5, label="spinning (theta* = 0, r* = 0)")
        ts = np.radians(np.linspace(-MAP_TILT_DEG, MAP_TILT_DEG, 4 * grid))
        ws, _ = st.tilted_spinning(ts, params)
        ax.plot(np.degrees(ts), ws, "k--", lw=1.2, label="tilted spinning (46)")
        ax.plot(np.degrees(ts), -ws, "k--", lw=1.2)
        ntt = st.non_tilted_turning(0.0, params)[0]
        ax.plot([0, 0], [ntt, -ntt], "ko", ms=7, label="non-tilted turning (44)")
        ax.plot([0], [0], "ks", ms=8, label="straight rolling")
        ax.set(xlabel="tilt angle theta* [deg]", ylabel="yaw rate psi_dot* [rad/s]", ylim=(-MAP_YAW_RATE, MAP_YAW_RATE),
               title=f"Unicycle steady states (m = {params.m} kg, m0 = {params.m0} kg, u = 0)\n"
                     "light blue: mass below the centre, purple: above, white: mass below the ground (47)")
        ax.legend(loc="lower left", fontsize=8)
        paths.append(save_figure(fig, out_dir / "fig5_unicycle_steady_states.png"))

    # Fig. 6: stability for several point masses
    fig, axes = plt.subplots(2, 4, figsize=(18, 8.5), sharex=True, sharey=True)
    for a, m0 in zip(axes.ravel(), FIG6_MASSES):
        pm = UnicycleParams(m=params.m, m0=m0, R=params.R, g=params.g)
        smap = st.unicycle_stability_map(pm, th, pd)
        a.pcolormesh(TH, PD, _category(smap), cmap=cmap, vmin=0, vmax=2, shading="nearest")
        a.set_title(f"m0 = {m0:g} kg")
    for a in axes[1]:
        a.set_xlabel("tilt angle theta* [deg]")
    for a in axes[:, 0]:
        a.set_ylabel("yaw rate psi_dot* [rad/s]")
    fig.suptitle(f"Unicycle turning rolling (m = {params.m} kg, R = {params.R} m, u = 0): green stable, red unstable, "
                 "white: no feasible steady state")
    paths.append(save_figure(fig, out_dir / "fig6_unicycle_stability.png"))
    return paths


def _stability(args: argparse.Namespace) -> int:
    try:
        paths = stability_figures(params_from_args(args), args.out, args.grid)
    except OSError as exc:
        raise ConfigError(f"cannot write figures: {exc.strerror}", path=args.out) from None
    for p in paths:
        print(p)
    return 0


# ---------------------------------------------------------------------------------------------
def plot_run(result, controller, path: Path) -> None:
    """Plot tilt, mass position, yaw, input and the path of a run (like one column of Fig. 8)."""
    plt = _pyplot()
    t, x = result.t, result.x
    fig, ax = plt.subplots(5, 1, figsize=(8, 12))
    ax[0].plot(t, np.degrees(x[:, 3]))
    ax[0].set_ylabel("tilt theta [deg]")
    ax[1].plot(t, x[:, 5])
    ax[1].set_ylabel("mass position r [m]")
    ax[2].plot(t, np.degrees(x[:, 6]), label="psi")
    xr, yr, pr = reference_path(controller, t)
    ax[2].plot(t, np.degrees(pr), "k-.", label="psi_des")
    ax[2].set_ylabel("yaw psi [deg]")
    ax[2].legend(fontsize=8)
    ax[3].step(t[:-1], result.u, where="post")
    ax[3].set_ylabel("input u [N]")
    ax[3].set_xlabel("time [s]")
    ax[4].plot(x[:, 8], x[:, 9], label="wheel centre G")
    ax[4].plot(xr, yr, "k-.", label="reference")
    ax[4].set(xlabel="x0 [m]", ylabel="y0 [m]", aspect="equal")
    ax[4].legend(fontsize=8)
    fig.suptitle(f"{controller.maneuver} at {controller.speed:g} m/s ({result.status})")
    save_figure(fig, path)


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
