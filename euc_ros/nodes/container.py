r"""Node container ``pipeline_container``: several pipeline nodes in one process, linked in-process.

ROS 2's answer to hops that cost more than their work is composition: the nodes stay separate
nodes (own names, parameters, diagnostics, topics) but share a process, and a message from one
to another does not go through the middleware (rclcpp's intra-process communication). rclpy has
no intra-process path, so this container makes one for the pipeline's links:

========================  ==============  ====================  ==========================
publisher                 topic           subscriber            handed over as
========================  ==============  ====================  ==========================
mocap_ingest.frame_pub    mocap/frame     rider_state           the core Frame (not decoded)
rider_state.state_pub     rider/state     torque_estimator      the RiderState message
========================  ==============  ====================  ==========================

The links are :data:`euc_ros.ros.intra.LINKS` (made by :func:`euc_ros.ros.intra.link`). A linked
subscriber's DDS subscription is destroyed and the publisher calls its handler, then
publishes to the middleware (other processes, the recorder and the monitor, still receive every
message; ``get_subscription_count`` counts the in-process subscriber). In-process first, as rclcpp
does: a frame's torque is on the wire before the frame and the state are. The chain then runs
in one call: a frame's state and torque are out before the next frame is read. All nodes spin on
one :class:`~euc_ros.ros.executor.LeanExecutor`.

Usage (``--nodes`` before ``--ros-args``; one ``--params-file`` per node, as their sections are
keyed by node name)::

    pipeline_container --nodes mocap_ingest,rider_state,torque_estimator --ros-args \
        --params-file config/mocap_ingest.yaml --params-file config/rider_state.yaml \
        --params-file config/torque_estimator.yaml -p session_file:=session.yaml -p csv_path:=ride.csv

A ``-p`` override applies to every node that declares the parameter (``session_file`` to both
estimators). Any subset of the registered nodes may be composed; only the links above are made
in-process, everything else goes through DDS as between processes.
"""
from __future__ import annotations

import argparse
import sys

from euc_ros.ros.intra import link
from euc_ros.ros.registry import NODES, node_class
from euc_ros.ros.runtime import run_nodes

#: The composition a high-rate live set-up wants (the monitor and recorder stay separate processes).
DEFAULT_NODES = ("mocap_ingest", "rider_state", "torque_estimator")


def main(argv: list[str] | None = None) -> None:
    """Console script ``pipeline_container``."""
    argv = list(sys.argv if argv is None else argv)
    own, ros = (argv[1:argv.index("--ros-args")], argv[argv.index("--ros-args"):]) if "--ros-args" in argv \
        else (argv[1:], [])
    parser = argparse.ArgumentParser(
        prog="pipeline_container", description=__doc__.split("\n\n")[0],
        epilog="Then --ros-args with --params-file per node and -p overrides, as for a single node.")
    parser.add_argument("--nodes", default=",".join(DEFAULT_NODES),
                        help=f"comma-separated nodes to compose, in start order (default: {','.join(DEFAULT_NODES)}; "
                             f"known: {', '.join(NODES)})")
    opts = parser.parse_args(own)
    names = [n.strip() for n in opts.nodes.split(",") if n.strip()]
    unknown = [n for n in names if n not in NODES]
    if unknown or not names or len(set(names)) != len(names):
        parser.error(f"--nodes: {'unknown ' + ', '.join(unknown) if unknown else 'each node once, at least one'} "
                     f"(known: {', '.join(NODES)})")
    classes = [node_class(n) for n in names]

    def create(nodes):
        for cls in classes:
            nodes.append(cls())

    def after_create(nodes):
        for line in link(nodes):
            nodes[0].get_logger().info(f"in-process: {line}")

    sys.exit(run_nodes(create, [argv[0], *ros], label="pipeline_container",
                       specs=[(c.NAME, c.SPECS) for c in classes], after_create=after_create))


if __name__ == "__main__":
    main()
