"""`euc-ros launch`: start the nodes of a launch YAML as separate processes (``ros2 launch`` stand-in)."""
from __future__ import annotations

import argparse

from euc_ros import launch

HELP = "start nodes as separate processes from a launch YAML (the ros2 launch stand-in)"

EPILOG = """launch file format (the files in the package's launch/ directory are examples):
  arguments:                            # set on the command line as name:=value
    bag: {default: "", description: record here (empty - no recorder)}
    source: {default: csv, choices: [csv, topics, natnet], description: where poses come from}
  nodes:
    - executable: mocap_ingest          # console script (ros2 run equivalent)
      name: mocap_ingest                # optional node name and log prefix
      params_file: ../config/mocap_ingest.yaml   # relative to the launch file
      parameters: {source: csv, csv_path: ride.csv}
      remaps: {mocap/frame: /lab/mocap/frame}
      required: true                    # its exit ends the launch
      if: $(arg bag)                    # start only if non-empty and not false (also: unless)
  $(arg NAME) is replaced anywhere; a value that is only $(arg NAME) is read as YAML (1.0, true, [a, b]).
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros launch``."""
    parser.epilog = EPILOG
    parser.add_argument("launch_file", help="launch YAML listing the nodes")
    parser.add_argument("launch_args", nargs="*", metavar="NAME:=VALUE", help="launch arguments (ros2 launch syntax)")
    parser.add_argument("-s", "--show-args", action="store_true", help="list the file's launch arguments and exit")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop everything after S seconds (default: until Ctrl-C or a required node exits)")


def main(args: argparse.Namespace) -> int:
    """Run the launch file; non-zero if a required node died."""
    if args.show_args:
        for a in launch.launch_arguments(args.launch_file):
            default = "(required)" if a.default is None else f"(default: {a.default!r})"
            choices = f" one of {', '.join(a.choices)}" if a.choices else ""
            print(f"    '{a.name}':\n        {a.description}{choices} {default}")
        return 0
    specs = launch.load_launch_file(args.launch_file, launch.parse_launch_arguments(args.launch_args))
    return launch.run(specs, duration=args.duration)
