"""`euc-ros`: one console script carrying every subcommand.

Each subcommand lives in its own module ``euc_ros.cli.<module>`` exposing ``HELP`` (one line),
``add_arguments(parser)`` and ``main(args) -> int``. Modules are imported lazily, only for the
command being run, so ``euc-ros --help`` stays fast and ROS-free.
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import sys

from euc_ros.cli import outputs
from euc_ros.core.errors import EucError

#: command -> (module, one-line help shown when the module cannot be imported cheaply)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("demo", "run the main job end to end: simulate, stream live, record, identify, trace the residual"),
    "launch": ("launch_cmd", "start the nodes of a ROS 2 XML launch file (*.launch.xml) as separate processes"),
    "session": ("session_cmd", "write a session file from the rider's measurements and the EUC's (session init)"),
    "simulate-ride": ("simulate_ride", "generate synthetic OptiTrack recordings of a ridden EUC with known truth"),
    "inspect": ("inspect", "show what a Motive CSV or a bag holds (and check bags structurally)"),
    "play": ("play", "replay a bag onto live topics"),
    "record": ("record", "record topics into a rosbag2 MCAP bag"),
    "convert": ("convert", "convert Motive CSV <-> bag"),
    "recover": ("recover", "rebuild a readable bag from a truncated or metadata-less one (recorder killed)"),
    "identify": ("identify", "identify the rider CoG height h from recordings (RMSE of M_d1 - M_d2)"),
    "residual": ("residual", "trace the M_d1 - M_d2 residual to a missing physical effect"),
    "unicycle": ("unicycle", "autonomous unicycle: gains, steady states, stability maps"),
    "steer": ("steer", "run a steering maneuver in closed loop over topics"),
    "view": ("view", "serve the live topics to Foxglove over WebSocket (this machine only unless --address)"),
    "campaign": ("campaign", "run identify (and residual) over many sessions or simulated seeds on a Dask cluster"),
    "bench": ("bench", "benchmarks against their floors"),
}


def _load(command: str):
    module, _ = COMMANDS[command]
    return importlib.import_module(f"euc_ros.cli.{module}")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """Build the parser; only ``command``'s module is imported (all of them if None, none if ``""``)."""
    parser = argparse.ArgumentParser(
        prog="euc-ros",
        description="euc_ros: motion-capture processing and electric-unicycle monitoring (ROS 2 Jazzy).",
        epilog="Run 'euc-ros COMMAND --help' for a command's options.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (_, help_text) in COMMANDS.items():
        if command is not None and name != command:
            sub.add_parser(name, help=help_text, add_help=False)
            continue
        try:
            mod = _load(name)
        except ModuleNotFoundError as exc:
            if exc.name and exc.name.startswith("euc_ros.cli"):
                continue  # command not built yet
            raise
        p = sub.add_parser(name, help=getattr(mod, "HELP", help_text), description=getattr(mod, "HELP", help_text),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        p.set_defaults(_main=mod.main)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``euc-ros``; returns the exit code (2 for user errors, 130 on Ctrl-C)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    command = argv[0] if argv and argv[0] in COMMANDS else None
    if command is None:
        parser = build_parser_light()
        if not argv or argv[0] in ("-h", "--help"):
            parser.print_help()
            return 0
        parser.error(f"unknown command {argv[0]!r}")
    parser = build_parser(command)
    args = parser.parse_args(argv)
    if not hasattr(args, "_main"):
        parser.error(f"command {command!r} is not available in this build")
    to_stdout = any(outputs.is_stdout(v) for k, v in vars(args).items() if k in ("json", "report"))
    try:
        if to_stdout:   # the output goes to standard output: the command's messages go to standard error
            outputs.stdout_stream = sys.stdout
            with contextlib.redirect_stdout(sys.stderr):
                return int(args._main(args) or 0)
        return int(args._main(args) or 0)
    except EucError as exc:
        print(f"euc-ros {command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # output piped into head & co.
        sys.stderr.close()
        return 0
    finally:
        outputs.stdout_stream = None


def build_parser_light() -> argparse.ArgumentParser:
    """Top-level parser listing the commands without importing any of them."""
    return build_parser(command="")


if __name__ == "__main__":
    sys.exit(main())
