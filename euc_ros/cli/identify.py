"""`euc-ros identify SESSION.yaml RECORDING...`: identify the rider CoG height h (EUC paper, Section 4).

For every recording (Motive CSV, bag directory or .mcap file) the states of the planar model are
reconstructed from the rigid bodies (:func:`euc_ros.core.states.kinematics.reconstruct_states`), then
:func:`euc_ros.core.identify.cog_height.identify_h` evaluates the RMSE of ``M_d1 - M_d2`` over a grid of
h for the 3-DoF model (eqs (9)-(10)) and the reduced 2-DoF model (eq (13)), per recording and pooled
(Fig. 8), refines the optimum, and gives the interval of h. This module parses, calls and formats.

Output: a table on stdout; with ``--json OUT`` the analysis output of the recording-format spec
(docs/residual.md, JSON) plus both models' curves; with ``--plots DIR`` PNG figures: ``<recording>_states.png``
(Figs 6-7 layout at the recording's optimal h) and ``rmse_curves.png`` (Fig. 8).

Extended model. ``--effect NAME`` (repeatable) with ``--param EFFECT.NAME=VALUE``
(repeatable), or ``--from-residual residual.json`` (its ``effect`` and ``effect_parameters``), adds
the effects the residual analysis selected to the 3-DoF model
(:class:`~euc_ros.core.model.extended.Model`, parameters fixed at the given values). h is
then identified for that model too, on the same grid and with the same refinement, and the JSON is
headed by it: ``"model": "3dof+ground_slope"``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from euc_ros.cli.figures import add_figure_arguments, configure_from_args, plot_ride_states, plot_rmse_curves
from euc_ros.cli.identify_report import format_filter, format_table, format_uncertainty, format_usage
from euc_ros.cli.loading import format_cog_faults, print_warnings, progress_bar
from euc_ros.cli.outputs import Output, check_outputs, write_output
from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.identify.budget import parse_tolerances
from euc_ros.core.identify.pipeline import HGrid, identify_recordings
from euc_ros.core.model.extended import parse_effect_assignments
from euc_ros.core.model.torque import torques
from euc_ros.core.states.kinematics import DEFAULT_SG_POLYORDER, DEFAULT_WINDOW_S, PHI_DEFINITIONS
from euc_ros.core.states.load import usage_table
from euc_ros.core.states.settings import ReconstructionSettings
from euc_ros.core.states.skeleton import COG_METHODS

HELP = "identify the rider CoG height h from recordings (RMSE of M_d1 - M_d2)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``euc-ros identify``."""
    parser.add_argument("session", metavar="SESSION.yaml", help="session file (docs/session.md)")
    parser.add_argument("recordings", metavar="RECORDING", nargs="+",
                        help="Motive CSV export, rosbag2 directory or .mcap file")
    parser.add_argument("--json", metavar="OUT", default=None, help="write the results as JSON to OUT")
    parser.add_argument("--plots", metavar="DIR", default=None, help="write figures (Figs 6-8 style) into DIR")
    add_figure_arguments(parser)
    parser.add_argument("--phi-definition", choices=PHI_DEFINITIONS, default="hinge",
                        help="rider pitch about the ankle hinge A (model, default) or about the wheel centre C (eq 3)")
    parser.add_argument("--cog-method", choices=COG_METHODS, default="segments",
                        help="rider CoG from the measured segments (default) or from a kinematic chain fitted to "
                             "them (swapped/flipped bodies excluded; docs/cog_artefacts.md)")
    parser.add_argument("--no-sliding-bias", dest="sliding_bias", action="store_false",
                        help="leave the soft-tissue sliding's SIMEX bias out of the h interval (faster)")
    add_sliding_prior_argument(parser)
    parser.add_argument("--h-min", type=float, default=0.1, metavar="M", help="smallest h of the grid [m] (0.1)")
    parser.add_argument("--h-max", type=float, default=1.2, metavar="M", help="largest h of the grid [m] (1.2)")
    parser.add_argument("--h-step", type=float, default=0.005, metavar="M", help="grid step [m] (0.005)")
    parser.add_argument("--window-s", type=window_arg, default="auto", metavar="S|auto",
                        help="Savitzky-Golay window [s], or 'auto' (default): window and order chosen from the "
                             f"recordings' spectra; a number fixes the window (e.g. {DEFAULT_WINDOW_S})")
    parser.add_argument("--polyorder", type=int, default=None,
                        help=f"Savitzky-Golay polynomial order with a numeric --window-s ({DEFAULT_SG_POLYORDER})")
    parser.add_argument("--model", choices=("3dof", "2dof"), default=None,
                        help="model heading the JSON output (default: the extended model with --effect, else 3dof)")
    parser.add_argument("--effect", action="append", default=[], metavar="NAME",
                        help="add an effect of the residual analysis to the 3-DoF model (repeatable)")
    parser.add_argument("--param", action="append", default=[], metavar="EFFECT.NAME=VALUE",
                        help="a parameter of an added effect, in the residual report's units (repeatable)")
    parser.add_argument("--from-residual", metavar="RESIDUAL.json", default=None,
                        help="add the effect(s) and parameters selected by 'euc-ros residual --json'")
    parser.add_argument("--force", action="store_true",
                        help="apply --from-residual even to a session or recordings it was not made from (its "
                             "'inputs' name them; a mismatch is refused without this)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    parser.add_argument("--tolerance", action="append", default=[], metavar="KEY=VALUE",
                        help="tolerance of a nominal session value for the h range, e.g. rider.mass=2 or "
                             "euc.body_inertia=20%% (repeatable; defaults: 1 kg for masses, 10 %% for inertias, "
                             "5 mm for h0 and l0, 2 mm for the wheel radius, 1 cm for the segment CoM offsets, "
                             "rider.segments.mass_fraction_each=0.17: each segment's mass fraction, relative)")
    parser.add_argument("--no-uncertainty", action="store_true",
                        help="skip the confidence interval, the errors-in-variables bias and the budget (faster)")


def add_sliding_prior_argument(parser: argparse.ArgumentParser) -> None:
    """``--sliding-prior-mm``: the soft-tissue sliding all rider bodies share (identify and residual)."""
    parser.add_argument("--sliding-prior-mm", type=float, default=None, metavar="MM",
                        help="RMS of the soft-tissue sliding all the rider's bodies share, which no check can see "
                             "[mm]; its effect on h, found by re-simulation, widens the interval (0: none; "
                             "default: as large as the sliding the chain's links show; docs/cog_artefacts.md)")


def window_arg(text: str) -> float | str:
    """``--window-s``: ``auto`` or a number of seconds."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 'auto' or seconds, got {text!r}") from None


def h_grid_from_args(args: argparse.Namespace) -> np.ndarray:
    """Return the h grid [m] of ``--h-min/--h-max/--h-step``; ConfigError naming the option if invalid."""
    return HGrid(args.h_min, args.h_max, args.h_step).values()


def settings_from_args(args: argparse.Namespace) -> ReconstructionSettings:
    """The :class:`~euc_ros.core.states.settings.ReconstructionSettings` of the filter, pitch and CoG options."""
    return ReconstructionSettings(window_s=args.window_s, polyorder=args.polyorder,
                                  phi_definition=args.phi_definition, cog_method=args.cog_method)


def effects_from_args(args: argparse.Namespace) -> dict[str, dict[str, float]]:
    """The extended model's effects ``{name: {parameter: value}}`` of ``--from-residual``, ``--effect``, ``--param``.

    ``--from-residual`` contributes its ``effect`` (names joined by ``+``; the outcome markers of
    :data:`~euc_ros.core.residual.names.OUTCOME_MARKERS` add nothing) with
    its flat ``effect_parameters``; ``--effect`` adds effects and ``--param`` sets or overrides
    parameters of any of them.

    Raises
    ------
    InputError
        The residual JSON cannot be read or lacks ``effect`` / ``effect_parameters``.
    InputMismatch
        The residual JSON was made from another session or other recordings than the command's
        (unless ``--force``).
    ConfigError
        An unknown effect, a malformed ``--param`` or a parameter of an effect that is not added.
    """
    effects: dict[str, dict[str, float]] = {}
    path = getattr(args, "from_residual", None)
    if path:
        from euc_ros.core.identify.model_file import read_model_file

        applied = read_model_file(path)
        if applied.kind != "residual":
            raise InputError("expected the output of 'euc-ros residual --json' (this is an identify result)",
                             path=path, key="effect")
        for line in applied.check(session=args.session, recordings=args.recordings,
                                  force=bool(getattr(args, "force", False))):
            print(f"euc-ros identify: warning: {line}", file=sys.stderr)
        if applied.left_out:
            # the discovery's terms are functions fitted on the residual's own recordings: not a model here
            print(f"euc-ros identify: note: {path}: not refitted here: {'; '.join(applied.left_out)} (the "
                  "residual's h_after_m and h_after_ci95_m are the h of the model with them)", file=sys.stderr)
        effects.update({k: dict(v) for k, v in applied.effects.items()})
    added = [e for e in getattr(args, "effect", []) or [] if e]
    items = list(getattr(args, "param", []) or [])
    for item in items:  # name the option, and keep this error apart from a malformed assignment
        effect = item.split("=", 1)[0].split(".", 1)[0].strip()
        if "=" in item and "." in item.split("=", 1)[0] and effect not in list(effects) + added:
            raise ConfigError(f"effect {effect!r} is not in the list of effects (add --effect {effect})",
                              key=f"--param {item}")
    assigned = parse_effect_assignments(list(effects) + added, items)
    for name, vals in assigned.items():
        effects.setdefault(name, {}).update(vals)
    return effects


def main(args: argparse.Namespace) -> int:
    """Run the identification; returns 0 (EucError on bad input: exit code 2 via the dispatcher)."""
    check_outputs([Output("--json", args.json), Output("--plots", args.plots, "dir")],
                  [args.session, *args.recordings])
    configure_from_args(args)
    run = identify_recordings(
        args.session, args.recordings, settings_from_args(args), grid=HGrid(args.h_min, args.h_max, args.h_step),
        effects=effects_from_args(args), model=args.model, uncertainty=not args.no_uncertainty,
        sliding=args.sliding_bias, tolerances=parse_tolerances(args.tolerance), sliding_prior_mm=args.sliding_prior_mm,
        progress=progress_bar("identify", not args.no_progress))
    ident, data, states, params = run.identification, run.data, run.states, run.params
    if "filter" in data:
        print(format_filter(data["filter"]))
    print(format_table(ident.fits, identifiable=ident.identifiable))
    if ident.uncertainty is not None:
        print(format_uncertainty(ident))
    print(format_usage(usage_table(states)))
    print(format_cog_faults(data["cog"]))
    print_warnings(data["warnings"])
    if args.json:
        write_output(args.json, json.dumps(data, indent=2) + "\n", "--json")
    if args.plots:
        finite = ident.uncertainty is not None and all(np.isfinite(ident.interval))
        write_plots(ident.fits, states, params, Path(args.plots), interval=ident.interval if finite else None,
                    identifiable=ident.identifiable)
    return 0


def write_plots(result, states, params, out_dir: Path, *, interval=None,
                identifiable: bool | None = True) -> list[Path]:
    """Write ``<recording>_states.png`` per recording and ``rmse_curves.png`` into ``out_dir``.

    Parameters
    ----------
    result : IdentifyResult
        Per-recording and pooled fits (``HIdentification.fits``).
    states : sequence of RiderStates
        The recordings' states, in the order of ``result.per_recording``.
    params : EucParams
        The session's parameters.
    out_dir : Path
        Folder of the figures (created).
    interval : (float, float), optional
        The 95 % interval of the headline h [m] (``HIdentification.interval``: with a filter chosen from
        the data, that of h corrected for the pose noise and the filter's distortion), shaded on the
        pooled RMSE curves. The curves' optima are the uncorrected fits, so it need not contain them.
    identifiable : bool or None
        Whether the data identify h (``HIdentification.identifiable``): when not, the titles and labels give
        the h as a best fit not for use (:func:`~euc_ros.cli.figures.h_text`; None: not assessed).

    Returns
    -------
    list of Path
        The figures written (first configured format).
    """
    from euc_ros.cli.figures import h_text

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for rec, st in zip(result.per_recording, states):
        fit = rec.fits["3dof"]
        h = fit.h_m if np.isfinite(fit.h_m) else result.pooled["3dof"].h_m
        d1, d2 = torques(*st.torque_args(), params.with_h(h))
        d1 = np.where(st.valid, d1, np.nan)
        d2 = np.where(st.valid, d2, np.nan)
        title = f"{rec.recording}: 3 DoF, {h_text(h, identifiable)}\nRMSE(M_d1 - M_d2) = {fit.rmse_nm:.3f} N m"
        safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in rec.recording)
        written.append(plot_ride_states([st], [(d1, d2)], out_dir / f"{safe}_states.png", title=title))
    panels = {rec.recording: {m: (f.rmse_curve_nm, f.h_m, f.rmse_nm) for m, f in rec.fits.items()}
              for rec in result.per_recording}
    if len(result.per_recording) > 1:
        panels["pooled"] = {m: (f.rmse_curve_nm, f.h_m, f.rmse_nm) for m, f in result.pooled.items()}
    title = "RMSE of M_d1 - M_d2 against h (EUC paper, Fig. 8)"
    if identifiable is False:
        title += "\nh not identifiable from these recordings: the optima are best fits, not for use"
    written.append(plot_rmse_curves(result.h_grid, panels, out_dir / "rmse_curves.png", title=title,
                                    interval=None if interval is None or None in interval else tuple(interval),
                                    identifiable=identifiable))
    return written
