"""`euc-ros launch`: start the processes of a ROS 2 XML launch file, each as its own OS process."""
from __future__ import annotations

import argparse

HELP = "start the nodes of a ROS 2 XML launch file (*.launch.xml) as separate processes"

EPILOG = """examples:
  euc-ros launch pipeline.launch.xml session:=session.yaml h:=0.58 source:=csv csv_path:=ride.csv bag:=out
  euc-ros launch euc_ros unicycle.launch.xml maneuver:=turn      (ros2 launch's PACKAGE FILE form)
  euc-ros launch ./my.launch.xml --show-args

A bare file name is looked up in the package's launch/ directory (pipeline, record, replay, unicycle);
a path is read as it is. The files are ROS 2 Jazzy launch XML, so `ros2 launch euc_ros FILE` reads
them too. euc-ros launch reads this subset and refuses anything else with the file, line and element:

  <launch>
    <arg name="bag" default="" description="..."/>         no default: required (name:=VALUE)
    <arg name="source" default="csv" description="...">    <choice value="..."/> limits the values
      <choice value="csv"/> <choice value="natnet"/>
    </arg>
    <node pkg="euc_ros" exec="mocap_ingest" name="mocap_ingest" namespace="lab"
          args="--nodes a,b" output="screen" on_exit="shutdown" if="$(var flag)">
      <param from="$(find-pkg-share euc_ros)/config/mocap_ingest.yaml"/>   files first
      <param name="rate_factor" value="$(var rate_factor)" type="float"/>
      <remap from="mocap/frame" to="/lab/mocap/frame"/>
      <env name="RCUTILS_COLORIZED_OUTPUT" value="0"/>
    </node>
    <executable cmd="euc-ros play $(var in_bag) --rate 2" name="play" output="screen"/>
  </launch>

  substitutions: $(var NAME), $(find-pkg-share euc_ros), $(eval 'EXPR') where EXPR compares quoted
    strings: if="$(eval '\\'$(var bag)\\' != \\'\\'')" starts a node only when bag is not empty
  if/unless: true, false, 1 or 0; unless= is the opposite of if=
  on_exit="shutdown": when that process ends, the launch ends (non-zero if its exit was not clean)
  output: "screen" (or "both"): every process' output is streamed, prefixed with its name
  param values: read as YAML (1 an int, 1.0 a double, [a, b] a list) unless type= says str, int,
    float, bool, list_of_str, list_of_int, list_of_float or list_of_bool; values of the package's
    nodes are then converted to the declared type where lossless (2 -> 2.0 for a double)
See docs/launch.md.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros launch``."""
    parser.epilog = EPILOG
    parser.add_argument("launch_file", metavar="[euc_ros] FILE",
                        help="launch file: a path, or a file name of the package's launch/ directory")
    parser.add_argument("launch_args", nargs="*", metavar="NAME:=VALUE", help="launch arguments (ros2 launch syntax)")
    parser.add_argument("-s", "--show-args", "--show-arguments", action="store_true",
                        help="show the arguments the launch file takes, and exit")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="stop everything after S seconds (default: until Ctrl-C or a required node exits)")


def print_arguments(arguments) -> None:
    """Print launch arguments as ``ros2 launch --show-args`` does."""
    print("Arguments (pass arguments as '<name>:=<value>'):")
    for a in arguments:
        description = a.description or "no description given"
        if a.choices:
            description += f" Valid choices are: {list(a.choices)}"
        default = "(required: no default)" if a.default is None else f"(default: '{a.default}')"
        print(f"\n    '{a.name}':\n        {description}\n        {default}")
    if not arguments:
        print("\n  No arguments.")


def main(args: argparse.Namespace) -> int:
    """Run the launch file; non-zero if a required node died."""
    from euc_ros.ros import launch_file
    from euc_ros.ros.launcher import run

    name, rest = args.launch_file, list(args.launch_args)
    if name == launch_file.PACKAGE and rest and ":=" not in rest[0]:
        name = rest.pop(0)            # ros2 launch's form: PACKAGE FILE
    path = launch_file.find_launch_file(name)
    if args.show_args:
        print_arguments(launch_file.launch_arguments(path))
        return 0
    specs = launch_file.load_launch_file(path, launch_file.parse_launch_arguments(rest))
    return run(specs, duration=args.duration)
