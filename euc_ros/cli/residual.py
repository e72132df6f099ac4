"""`euc-ros residual SESSION.yaml RECORDING... --json OUT`: trace M_d1 - M_d2 to a missing physical effect.

1. identify h with the paper's 3-DoF model; 2. compute r(t) = M_d1 - M_d2; 3. for every candidate
effect of the library (check detectability first: a generalized force in span(b_d, b_h) cannot show
in r) fit its parameters jointly with h on training data and evaluate on held-out data (other runs, or
segments of a single run); 4. select by held-out error with a paired block test (max-T over the
candidates) and a minimum gain, greedily, until nothing significant remains; 5. report the extended
model, which ``identify --from-residual`` and the ``torque_estimator`` node (``effects``,
``effect_parameters``) use; 6. write JSON (docs/residual.md, JSON), a Markdown report and PNG figures.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from euc_ros.cli.figures import add_figure_arguments, configure_from_args, write_plots
from euc_ros.cli.identify import window_arg
from euc_ros.cli.loading import format_cog_faults, print_warnings, progress_bar
from euc_ros.cli.outputs import Output, check_outputs, write_output
from euc_ros.cli.residual_report import console_warnings, format_summary, headline_text, markdown_report
from euc_ros.core.model.effects import LIBRARY, parse_plausible
from euc_ros.core.residual.pipeline import ResidualOptions, trace_residual
from euc_ros.core.states.settings import ReconstructionSettings

HELP = "trace the M_d1 - M_d2 residual to a missing physical effect; report the error before and after"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros residual``."""
    from euc_ros.cli.identify import add_sliding_prior_argument
    from euc_ros.core.residual.analysis import RESIDUAL_POLYORDER, RESIDUAL_WINDOW_S
    from euc_ros.core.residual.selector import DEFAULT_ALPHA, DEFAULT_MIN_GAIN

    parser.add_argument("session", metavar="SESSION.yaml", help="session file (docs/session.md)")
    parser.add_argument("recordings", metavar="RECORDING", nargs="+",
                        help="Motive CSV export, rosbag2 directory or .mcap file")
    parser.add_argument("--json", metavar="OUT", required=True, help="write the analysis JSON (docs/residual.md, JSON)")
    parser.add_argument("--plots", metavar="DIR", default=None, help="write figures into DIR")
    add_figure_arguments(parser)
    parser.add_argument("--report", metavar="OUT.md", default=None, help="write a Markdown report")
    parser.add_argument("--alpha", type=float, default=DEFAULT_ALPHA,
                        help=f"significance level of each selection step ({DEFAULT_ALPHA})")
    parser.add_argument("--min-gain", type=float, default=DEFAULT_MIN_GAIN,
                        help=f"minimum relative cut of the held-out RMSE to select an effect ({DEFAULT_MIN_GAIN})")
    parser.add_argument("--candidates", nargs="+", default=None, metavar="EFFECT",
                        help=f"restrict the library (default: all: {', '.join(LIBRARY)})")
    parser.add_argument("--max-effects", type=int, default=3, help="most effects to select (3)")
    parser.add_argument("--window-s", type=window_arg, default=RESIDUAL_WINDOW_S, metavar="S|auto",
                        help=f"Savitzky-Golay window [s] ({RESIDUAL_WINDOW_S}: less bias of the accelerations "
                             "than identify's default; see README), or 'auto': window and order chosen from the "
                             "recordings' spectra as identify chooses them")
    parser.add_argument("--polyorder", type=int, default=None,
                        help=f"Savitzky-Golay order with a numeric --window-s ({RESIDUAL_POLYORDER})")
    parser.add_argument("--no-discovery", action="store_true",
                        help="skip the discovery step (group-sparse forces from function families for what no "
                             "named effect explains)")
    parser.add_argument("--no-geometry", action="store_true",
                        help="do not compare the wheel-centre height with the session's wheel radius (for recordings "
                             "whose world z is not height over the floor)")
    parser.add_argument("--cog-method", choices=("segments", "skeleton"), default="segments",
                        help="rider CoG from the measured segments (default) or from a kinematic chain fitted to "
                             "them (swapped/flipped bodies excluded; docs/cog_artefacts.md)")
    parser.add_argument("--phi-definition", choices=("hinge", "eq3"), default="hinge",
                        help="rider pitch about the ankle hinge A (the model's, default) or about the wheel centre C")
    parser.add_argument("--tolerance", action="append", default=[], metavar="KEY=VALUE",
                        help="tolerance of a nominal session value, e.g. rider.mass=2 or euc.body_inertia=20%%: adds "
                             "the h budget for these tolerances to the base model's uncertainty (repeatable)")
    parser.add_argument("--plausible", action="append", default=[], metavar="EFFECT.PARAM=LOW:HIGH",
                        help="plausible range of a library parameter instead of the library's (docs/effects.md), "
                             "e.g. aero_drag.cda_m2=0.2:1.4; a fit outside it is not named (repeatable)")
    add_sliding_prior_argument(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress output on stderr")


def main(args: argparse.Namespace) -> int:
    """Run the analysis; 0 on success (EucError: exit 2 through the dispatcher)."""
    from euc_ros.cli.identify_report import format_usage
    from euc_ros.core.identify.budget import parse_tolerances

    check_outputs([Output("--json", args.json), Output("--plots", args.plots, "dir"),
                   Output("--report", args.report)], [args.session, *args.recordings])
    configure_from_args(args)
    run = trace_residual(
        args.session, args.recordings,
        ReconstructionSettings(window_s=args.window_s, polyorder=args.polyorder, phi_definition=args.phi_definition,
                               cog_method=args.cog_method),
        options=ResidualOptions(candidates=args.candidates, alpha=args.alpha, min_gain=args.min_gain,
                                max_effects=args.max_effects, use_geometry=not args.no_geometry,
                                discover=not args.no_discovery, plausible=parse_plausible(args.plausible)),
        tolerances=parse_tolerances(args.tolerance) if args.tolerance else None,
        sliding_prior_mm=args.sliding_prior_mm, progress=progress_bar("read", not args.no_progress),
        say=None if args.no_progress else (lambda m: print(m, file=sys.stderr, flush=True)))
    result, data, states, params = run.result, run.data, run.states, run.params
    write_output(args.json, json.dumps(data, indent=2) + "\n", "--json")
    print(format_summary(data))
    print(format_usage(data["per_recording"]))
    print(format_cog_faults(data["cog"]))
    print_warnings(console_warnings(data))
    print(headline_text(data, args.json, args.session))
    figures = []
    if args.plots:
        figures = write_plots(result, states, params, Path(args.plots), data=data)
    if args.report:
        write_output(args.report, markdown_report(data, figures, Path(args.report).parent), "--report")
    return 0
