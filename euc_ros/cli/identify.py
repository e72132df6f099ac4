"""`euc-ros identify SESSION.yaml RECORDING...`: identify the rider CoG height h (EUC paper, Section 4).

For every recording (Motive CSV, bag directory or .mcap file) the states of the planar model are
reconstructed from the rigid bodies (:func:`euc_ros.core.euc.kinematics.reconstruct_states`), then
the RMSE of ``M_d1 - M_d2`` is evaluated over a grid of h for the 3-DoF model (eqs (9)-(10)) and the
reduced 2-DoF model (eq (13)), per recording and pooled (Fig. 8), and the optimum is refined.

Output: a table on stdout; with ``--json OUT`` the analysis output of the recording-format spec
(section 5) plus both models' curves; with ``--plots DIR`` PNG figures: ``<recording>_states.png``
(Figs 6-7 layout at the recording's optimal h) and ``rmse_curves.png`` (Fig. 8).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from euc_ros.core.errors import ConfigError, InputError

HELP = "identify the rider CoG height h from recordings (RMSE of M_d1 - M_d2)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``euc-ros identify``."""
    from euc_ros.core.euc.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, PHI_DEFINITIONS

    parser.add_argument("session", metavar="SESSION.yaml", help="session file (spec section 4)")
    parser.add_argument("recordings", metavar="RECORDING", nargs="+",
                        help="Motive CSV export, rosbag2 directory or .mcap file")
    parser.add_argument("--json", metavar="OUT", default=None, help="write the results as JSON to OUT")
    parser.add_argument("--plots", metavar="DIR", default=None, help="write PNG figures (Figs 6-8 style) into DIR")
    parser.add_argument("--phi-definition", choices=PHI_DEFINITIONS, default="hinge",
                        help="rider pitch about the ankle hinge A (model, default) or about the wheel centre C (eq 3)")
    parser.add_argument("--h-min", type=float, default=0.1, metavar="M", help="smallest h of the grid [m] (0.1)")
    parser.add_argument("--h-max", type=float, default=1.2, metavar="M", help="largest h of the grid [m] (1.2)")
    parser.add_argument("--h-step", type=float, default=0.005, metavar="M", help="grid step [m] (0.005)")
    parser.add_argument("--window-s", type=float, default=DEFAULT_WINDOW_S, metavar="S",
                        help=f"Savitzky-Golay window [s] ({DEFAULT_WINDOW_S})")
    parser.add_argument("--polyorder", type=int, default=DEFAULT_SG_POLYORDER,
                        help=f"Savitzky-Golay polynomial order ({DEFAULT_SG_POLYORDER})")
    parser.add_argument("--model", choices=("3dof", "2dof"), default="3dof",
                        help="model heading the JSON output (both are always computed)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")


def h_grid_from_args(args: argparse.Namespace) -> np.ndarray:
    """Return the h grid [m] of ``--h-min/--h-max/--h-step``; ConfigError naming the option if invalid."""
    lo, hi, step = args.h_min, args.h_max, args.h_step
    for name, v in (("--h-min", lo), ("--h-max", hi), ("--h-step", step)):
        if not np.isfinite(v):
            raise ConfigError(f"must be a finite number, got {v}", key=name)
    if not 0 < lo < hi:
        raise ConfigError(f"need 0 < h-min < h-max, got {lo} and {hi}", key="--h-min")
    if not 0 < step <= (hi - lo) / 2:
        raise ConfigError(f"must be > 0 and at most half the range, got {step}", key="--h-step")
    n = int(np.floor((hi - lo) / step + 1e-9)) + 1
    return lo + step * np.arange(n)


def _fmt(v: float, digits: int) -> str:
    return "nan" if not np.isfinite(v) else f"{v:.{digits}f}"


def format_table(result) -> str:
    """The per-recording and pooled table printed by the command."""
    head = (f"{'recording':<28} {'samples':>8}  {'3-DoF h [m]':>11} {'RMSE [Nm]':>10}  "
            f"{'2-DoF h [m]':>11} {'RMSE [Nm]':>10}")
    lines = [head, "-" * len(head)]

    def row(name, n, fits):
        f3, f2 = fits.get("3dof"), fits.get("2dof")
        cells = []
        for f in (f3, f2):
            if f is None:
                cells += ["-", "-"]
            else:
                h = _fmt(f.h_m, 3) + ("*" if f.at_bound else " ")
                cells += [h, _fmt(f.rmse_nm, 3)]
        return f"{name[:28]:<28} {n:>8}  {cells[0]:>11} {cells[1]:>10}  {cells[2]:>11} {cells[3]:>10}"

    for rec in result.per_recording:
        lines.append(row(rec.recording, rec.n_samples, rec.fits))
    lines.append("-" * len(head))
    pooled_n = next(iter(result.pooled.values())).n_samples if result.pooled else 0
    lines.append(row("pooled", pooled_n, result.pooled))
    if any(f.at_bound for rec in result.per_recording for f in rec.fits.values()) or \
            any(f.at_bound for f in result.pooled.values()):
        lines.append("* optimum at the end of the h grid: widen --h-min/--h-max")
    return "\n".join(lines)


def _unique_names(names: list[str]) -> list[str]:
    seen: dict[str, int] = {}
    out = []
    for nm in names:
        k = seen.get(nm, 0)
        seen[nm] = k + 1
        out.append(nm if k == 0 else f"{nm}_{k + 1}")
    return out


def main(args: argparse.Namespace) -> int:
    """Run the identification; returns 0 (EucError on bad input: exit code 2 via the dispatcher)."""
    from tqdm import tqdm

    from euc_ros.core.euc.identify import identify_h
    from euc_ros.core.euc.kinematics import reconstruct_states
    from euc_ros.core.euc.model import EucParams
    from euc_ros.core.io.recordings import load_recording, recording_kind
    from euc_ros.core.session import load_session

    grid = h_grid_from_args(args)
    session = load_session(args.session)
    for path in args.recordings:
        recording_kind(path)  # fail early, before any long read
    states = []
    bar = tqdm(args.recordings, desc="identify", unit="rec", file=sys.stderr,
               disable=args.no_progress or len(args.recordings) < 2)
    for path in bar:
        series = load_recording(path, session.world_up)
        st = reconstruct_states(series, session, phi_definition=args.phi_definition, window_s=args.window_s,
                                polyorder=args.polyorder)
        if not st.valid.any():
            raise InputError("no frame with the EUC and every rider segment tracked long enough to differentiate",
                             path=path)
        states.append(st)
    for st, name in zip(states, _unique_names([s.name or Path(p).stem for s, p in zip(states, args.recordings)])):
        st.name = name
    params = EucParams.from_session(session)
    settings = {"session": str(args.session), "recordings": [str(p) for p in args.recordings],
                "phi_definition": args.phi_definition, "window_s": args.window_s,
                "window_samples": states[0].window, "polyorder": args.polyorder,
                "h_grid": {"min_m": float(grid[0]), "max_m": float(grid[-1]), "step_m": args.h_step},
                "gravity_m_per_s2": float(params.g)}
    result = identify_h(states, params, grid, settings=settings)
    print(format_table(result))
    if args.json:
        out = Path(args.json)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(result.to_json(args.model), indent=2) + "\n", encoding="utf-8")
    if args.plots:
        write_plots(result, states, params, Path(args.plots))
    return 0


def write_plots(result, states, params, out_dir: Path) -> list[Path]:
    """Write ``<recording>_states.png`` per recording and ``rmse_curves.png`` into ``out_dir``."""
    from euc_ros.cli.plots import plot_ride_states, plot_rmse_curves
    from euc_ros.core.euc.torque import torques

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for rec, st in zip(result.per_recording, states):
        fit = rec.fits["3dof"]
        h = fit.h_m if np.isfinite(fit.h_m) else result.pooled["3dof"].h_m
        d1, d2 = torques(*st.torque_args(), params.with_h(h))
        d1 = np.where(st.valid, d1, np.nan)
        d2 = np.where(st.valid, d2, np.nan)
        title = f"{rec.recording}: 3 DoF, h = {h:.2f} m, RMSE(M_d1 - M_d2) = {fit.rmse_nm:.3f} N m"
        safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in rec.recording)
        written.append(plot_ride_states([st], [(d1, d2)], out_dir / f"{safe}_states.png", title=title))
    panels = {rec.recording: {m: (f.rmse_curve_nm, f.h_m, f.rmse_nm) for m, f in rec.fits.items()}
              for rec in result.per_recording}
    if len(result.per_recording) > 1:
        panels["pooled"] = {m: (f.rmse_curve_nm, f.h_m, f.rmse_nm) for m, f in result.pooled.items()}
    written.append(plot_rmse_curves(result.h_grid, panels, out_dir / "rmse_curves.png",
                                    title="RMSE of M_d1 - M_d2 against h (EUC paper, Fig. 8)"))
    return written
