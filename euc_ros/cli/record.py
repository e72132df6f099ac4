"""`euc-ros record`: record topics into a rosbag2 MCAP bag (the recorder node as its own process)."""
from __future__ import annotations

import argparse

from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.ros import interfaces as itf
from euc_ros.ros.launcher import NodeSpec, run

HELP = "record topics into a rosbag2 bag with MCAP storage (Ctrl-C to stop; the bag is closed cleanly)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros record``."""
    parser.add_argument("output", help="bag directory to create (must not exist)")
    parser.add_argument("topics", nargs="*", help=f"topics to record (default: {' '.join(itf.PIPELINE_TOPICS)})")
    parser.add_argument("-a", "--all", action="store_true", help="record every topic that appears")
    parser.add_argument("--duration", type=float, default=None, metavar="S", help="stop after S seconds")
    parser.add_argument("--chunk-size", type=int, default=1 << 16, metavar="BYTES",
                        help="MCAP chunk size (smaller loses less if the recorder is killed)")


def main(args: argparse.Namespace) -> int:
    """Run the recorder until Ctrl-C or ``--duration``."""
    check_outputs([Output("output", args.output, "dir")])
    params = {"output": args.output, "all_topics": args.all, "chunk_size": args.chunk_size}
    if args.topics:
        params["topics"] = list(args.topics)
    return run([NodeSpec("recorder", parameters=params)], duration=args.duration)
