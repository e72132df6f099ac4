"""`euc-ros simulate-ride`: synthetic OptiTrack recordings of a ridden EUC with known truth.

Example::

    euc-ros simulate-ride --maneuver deceleration --runs 3 --effect ground_slope \
        --param alpha_deg=3 --seed 7 --out DIR

writes DIR/session.yaml (nominal), DIR/deceleration_0N.csv (Motive CSV, Y-up), with --bag MCAP bags,
and the hidden truth apart in DIR/truth/ (truth.json, deceleration_0N_truth.csv), so `DIR/*.csv`
holds only recordings. DIR must be new or empty; --overwrite replaces a previous simulated ride
(and nothing else). See docs/ridesim.md.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import ConfigError
from euc_ros.core.session import load_session

HELP = "generate synthetic OptiTrack recordings of a ridden EUC with known truth"


def _effects_epilog() -> str:
    from euc_ros.core.ridesim.effects import EFFECTS

    lines = ["effects (each off by default; --effect NAME, parameters with --param NAME=VALUE):"]
    for e in EFFECTS.values():
        ps = ", ".join(f"{p.name}={p.default:g} [{p.unit}]" for p in e.params)
        lines.append(f"  {e.name:<21} {ps}")
        lines.append(f"  {'':<21} {e.formula}")
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``simulate-ride``."""
    from euc_ros.core.ridesim.maneuvers import MANEUVERS

    parser.epilog = _effects_epilog()
    parser.add_argument("--maneuver", default="deceleration",
                        help=f"one of {', '.join(MANEUVERS)} (hyphens accepted) [deceleration]")
    parser.add_argument("--runs", type=int, default=3, help="number of runs / recordings [3]")
    parser.add_argument("--seed", type=int, default=0, help="random seed; equal seeds give equal files [0]")
    parser.add_argument("--effect", action="append", default=[], metavar="NAME",
                        help="add a physical effect to the truth (repeatable)")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="effect parameter, e.g. alpha_deg=3 (repeatable)")
    parser.add_argument("--h", type=float, default=0.61, dest="cog_height",
                        help="true rider CoG height above the ankle hinge [m] [0.61]")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="recording duration per run [s] (default per maneuver)")
    parser.add_argument("--speed-scale", type=float, default=1.0, metavar="K",
                        help="multiply every planned speed (a more aggressive rider) [1]")
    parser.add_argument("--path-scale", type=float, default=1.0, metavar="K",
                        help="multiply the figure-eight's length (wider turns) [1]")
    parser.add_argument("--session", default=None, metavar="FILE",
                        help="nominal session YAML (default: the EUC paper's EUC, Table 3, and a 65 kg, 1.75 m male "
                             "rider from the anthropometric table of session init)")
    parser.add_argument("--out", required=True, metavar="DIR",
                        help="output folder: new or empty (the truth goes to DIR/truth/, apart from the recordings)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace a previous simulated ride in DIR (nothing else is ever deleted)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars on stderr")
    parser.add_argument("--bag", action="store_true", help="also write one MCAP bag per run")
    parser.add_argument("--no-noise", action="store_true", help="noise-free poses")
    parser.add_argument("--noise-pos-mm", type=float, default=0.2, help="position noise sigma per axis [mm] [0.2]")
    parser.add_argument("--noise-rot-deg", type=float, default=0.5, help="rotation noise rms angle [deg] [0.5]")
    parser.add_argument("--gaps", type=int, default=0, help="occlusion gaps per run [0]")
    parser.add_argument("--drop-rate", type=float, default=0.0, help="fraction of dropped frames [0]")
    parser.add_argument("--method", choices=("compiled", "reference"), default="compiled",
                        help="integration: compiled right-hand side and DOP853, or the Python right-hand side "
                             "through scipy's solve_ivp (same steps, ~30x slower) [compiled]")


def _progress_bar(args):
    """``bar(desc, unit)`` -> a wrapper of iterables drawing a progress bar on stderr (or None)."""
    if args.no_progress:
        return lambda desc, unit: None
    from tqdm import tqdm

    return lambda desc, unit: (lambda it: tqdm(it, desc=desc, unit=unit, file=sys.stderr, delay=0.5, disable=None))


def main(args: argparse.Namespace) -> int:
    """Run the simulation and write the files; returns 0."""
    from euc_ros.core.ridesim import MocapNoise, RideConfig, make_effects, parse_param_assignments, simulate_ride
    from euc_ros.core.ridesim.writers import prepare_ride_dir, write_ride

    t0 = time.perf_counter()
    check_outputs([Output("--out", args.out, "dir")], [args.session])
    prepare_ride_dir(args.out, overwrite=args.overwrite, dry_run=True)   # refuse before the simulation runs
    effects = make_effects(args.effect, parse_param_assignments(args.param))
    if args.no_noise:
        noise = MocapNoise(pos_sigma_m=0.0, rot_rms_deg=0.0, marker_error_m=0.0, gaps=args.gaps,
                           drop_rate=args.drop_rate)
    else:
        noise = MocapNoise(pos_sigma_m=args.noise_pos_mm * 1e-3, rot_rms_deg=args.noise_rot_deg, gaps=args.gaps,
                           drop_rate=args.drop_rate)
    if args.duration is not None and not args.duration > 0:
        raise ConfigError(f"must be > 0, got {args.duration}", key="--duration")
    config = RideConfig(maneuver=args.maneuver.replace("-", "_"), runs=args.runs, seed=args.seed,
                        h=args.cog_height, effects=effects,
                        session=None if args.session is None else load_session(args.session),
                        duration_s=args.duration, speed_scale=args.speed_scale,
                        path_scale=args.path_scale, noise=noise, method=args.method)
    bar = _progress_bar(args)
    result = simulate_ride(config, progress=bar("simulate", "run"))
    written = write_ride(result, args.out, bag=args.bag, overwrite=args.overwrite, progress=bar("write", "run"))
    print(f"simulate-ride: {config.maneuver}, {len(result.runs)} run(s), effect {effects.label}, "
          f"h = {config.h:.3f} m, seed {config.seed}")
    for r in result.runs:
        print(f"  {r.name}: {r.t[-1] + 1 / result.session.rate_hz:.1f} s, x_dot {r.q_dot[0, 0]:.2f} -> "
              f"{r.q_dot[-1, 0]:.2f} m/s, max |phi| {math.degrees(abs(r.q[:, 2]).max()):.1f} deg, "
              f"max |M_d| {abs(r.M_d).max():.1f} N m, {r.mocap.n_frames} frames written")
    print(f"wrote {len(written)} files to {args.out} in {time.perf_counter() - t0:.1f} s")
    return 0
