"""Node container ``pipeline_container``: several pipeline nodes in one process, linked in-process.

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

A linked subscriber's DDS subscription is destroyed and the publisher calls its handler, then
publishes to the middleware (other processes, the recorder and the monitor, still receive every
message; ``get_subscription_count`` counts the in-process subscriber). In-process first, as rclcpp
does: a frame's torque is on the wire before the frame and the state are. The chain then runs
in one call: a frame's state and torque are out before the next frame is read. All nodes spin on
one :class:`~euc_ros.ros.executor.LeanExecutor`.

Usage (``--nodes`` before ``--ros-args``; one ``--params-file`` per node, as their sections are
keyed by node name)::

    pipeline_container --nodes mocap_ingest,rider_state,torque_estimator --ros-args \\
        --params-file config/mocap_ingest.yaml --params-file config/rider_state.yaml \\
        --params-file config/torque_estimator.yaml -p session_file:=session.yaml -p csv_path:=ride.csv

A ``-p`` override applies to every node that declares the parameter (``session_file`` to both
estimators). Any subset of the registered nodes may be composed; only the links above are made
in-process, everything else goes through DDS as between processes.
"""
from __future__ import annotations

import argparse
import sys

from euc_ros.ros.intra import LocalFanout
from euc_ros.ros.registry import NODES, node_class
from euc_ros.ros.runtime import run_nodes

#: In-process links: (publisher node, publisher attribute, subscriber node, DDS subscription
#: attribute, handler attribute taking one message as the subscription's callback would).
LINKS = (
    ("mocap_ingest", "frame_pub", "rider_state", "_frame_sub", "_on_frame_local"),
    ("rider_state", "state_pub", "torque_estimator", "_state_sub", "_on_state"),
)

#: The composition a high-rate live set-up wants (the monitor and recorder stay separate processes).
DEFAULT_NODES = ("mocap_ingest", "rider_state", "torque_estimator")


def link(nodes) -> list[str]:
    """Make the :data:`LINKS` whose both ends are among ``nodes`` (by node name) in-process.

    Returns one line per link made (``mocap_ingest -> rider_state on /mocap/frame``). A link is made
    only when the publisher's topic and the subscription's resolve to the same name (remaps and
    namespaces respected).
    """
    by_name = {}
    for node in nodes:
        by_name.setdefault(getattr(type(node), "NAME", node.get_name()), node)
    made = []
    for pub_name, pub_attr, sub_name, sub_attr, handler_attr in LINKS:
        pub_node, sub_node = by_name.get(pub_name), by_name.get(sub_name)
        if pub_node is None or sub_node is None:
            continue
        pub, sub = getattr(pub_node, pub_attr), getattr(sub_node, sub_attr, None)
        if sub is None:
            continue
        if pub.topic_name != sub.topic_name:
            continue
        if not isinstance(pub, LocalFanout):
            pub = LocalFanout(pub)
            setattr(pub_node, pub_attr, pub)
        pub.handlers.append(getattr(sub_node, handler_attr))
        sub_node.destroy_subscription(sub)
        setattr(sub_node, sub_attr, None)
        made.append(f"{pub_node.get_name()} -> {sub_node.get_name()} on {pub.topic_name}")
    return made


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
