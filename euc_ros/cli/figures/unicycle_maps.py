"""Figures of ``euc-ros unicycle``: the stability maps and a simulated run.

:func:`stability_figures` (Figs 3, 5, 6 of the steering paper) and :func:`plot_run` (also used by
``euc-ros steer``).

Not re-exported by :mod:`euc_ros.cli.figures` (it imports the unicycle model).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from euc_ros.cli.figures.common import save_figure
from euc_ros.core.errors import ConfigError
from euc_ros.core.unicycle import steady as st
from euc_ros.core.unicycle.dynamics import UnicycleParams
from euc_ros.core.unicycle.simulate import reference_path

#: Point masses of the panels of the Fig. 6-like map [kg].
FIG6_MASSES = (0.0, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0)
#: Tilt range of the maps [deg] and yaw-rate range [rad/s].
MAP_TILT_DEG = 85.0
MAP_YAW_RATE = 15.0


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
