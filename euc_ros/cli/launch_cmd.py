"""`euc-ros launch`: start the nodes of a launch YAML as separate processes (``ros2 launch`` stand-in)."""
from __future__ import annotations

import argparse

from euc_ros import launch

HELP = "start nodes as separate processes from a launch YAML (the ros2 launch stand-in)"

EPILOG = """launch file format:
  nodes:
    - executable: mocap_ingest          # console script (ros2 run equivalent)
      name: mocap_ingest                # optional node name and log prefix
      params_file: ../config/mocap_ingest.yaml   # relative to the launch file
      parameters: {source: csv, csv_path: ride.csv}
      remaps: {mocap/frame: /lab/mocap/frame}
      required: true                    # its exit ends the launch
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros launch``."""
    parser.epilog = EPILOG
    parser.add_argument("launch_file", help="launch YAML listing the nodes")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop everything after S seconds (default: until Ctrl-C or a required node exits)")


def main(args: argparse.Namespace) -> int:
    """Run the launch file; non-zero if a required node died."""
    specs = launch.load_launch_file(args.launch_file)
    return launch.run(specs, duration=args.duration)
