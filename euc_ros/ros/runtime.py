"""The Jazzy node lifecycle, written once: init, spin, clean shutdown on SIGINT/SIGTERM.

In rclpy 7.1 (Jazzy) both SIGINT and SIGTERM end ``spin`` with ``ExternalShutdownException``;
``rclpy.init`` returns None (no context manager, unlike rolling). A node stopped by a signal exits
with code 0, whether it was spinning or still starting (a node executable: :mod:`euc_ros.ros.startup`
until ``rclpy.init`` has returned). The nodes spin on :class:`~euc_ros.ros.executor.LeanExecutor`,
rclpy's public executor where :mod:`~euc_ros.ros.rclpy_compat` refuses rclpy's private API (said once
on the console).
"""
from __future__ import annotations

import gc
import sys
import warnings
from typing import Callable

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from euc_ros.core.errors import EucError
from euc_ros.ros import rclpy_compat, startup
from euc_ros.ros.executor import LeanExecutor, wait_for_context_shutdown
from euc_ros.ros.params import params_files_in, validate_params_file
from euc_ros.sched import realtime_from_env

#: How long an exception raised inside spin waits for a signal-triggered shutdown to complete [s].
SHUTDOWN_RACE_S = 0.5
#: Whether :func:`drain` takes messages itself (rclpy's private API allowed in this process).
_TAKE_DIRECTLY = rclpy_compat.private_api_problem() is None


def run_node(node_factory: Callable[[], Node], args: list[str] | None = None, *,
             node_name: str | None = None, specs=None) -> int:
    """Create the node, spin it until shutdown, then destroy it; returns the process exit code.

    ``--params-file`` files are validated against ``specs`` before rcl reads them. A configuration
    error (:class:`EucError`) is printed as one line naming the file and key, and the exit code is 2.
    """
    named = [(node_name, specs)] if specs is not None and node_name is not None else []
    return run_nodes(lambda nodes: nodes.append(node_factory()), args, label=node_name or "node", specs=named)


def run_nodes(create: Callable[[list[Node]], None], args: list[str] | None = None, *, label: str = "node",
              specs=(), after_create: Callable[[list[Node]], None] | None = None) -> int:
    """Create several nodes in one process and spin them on one :class:`LeanExecutor` until shutdown.

    ``create(nodes)`` appends each node to ``nodes`` as it makes it (a node made before a later one
    fails is destroyed too). ``specs`` is ``[(node name, ParamSpec table), ...]``: every
    ``--params-file`` is checked against each node's table (a file's sections for other nodes are
    ignored). ``after_create(nodes)`` runs before spinning (the container links its nodes there).
    Nodes are closed and destroyed in reverse order of creation.
    """
    argv = list(sys.argv if args is None else args)
    try:
        for path in params_files_in(argv):
            for name, table in specs:
                validate_params_file(path, name, table)
    except EucError as exc:
        print(f"{label}: error: {exc}", file=sys.stderr)
        return 2
    realtime_from_env(label)            # before rclpy.init: the middleware's threads inherit it
    # a stop signal that shuts the context down while a node is being created makes rclpy warn that it could
    # not finalise the half-made node's rosout publisher: the process is stopping as asked, nothing failed
    warnings.filterwarnings("ignore", message="Failed to fini rosout publisher", category=RuntimeWarning)
    rclpy.init(args=args)
    startup.running()                   # rclpy's signal handlers from now on (a quiet exit until here)
    nodes: list[Node] = []
    executor = None
    code = 0
    signalled = False
    try:
        # The outer handler takes the KeyboardInterrupt of a SIGINT wherever it lands, also inside the inner
        # handlers: rclpy's C handler shuts the context down at once, so the node being made or the message
        # being taken fails first (an rclpy error, or a parameter that cannot be published), and Python's
        # handler raises a moment later, while that failure is being handled.
        try:
            create(nodes)
            if after_create is not None:
                after_create(nodes)
            executor = LeanExecutor()
            for node in nodes:
                executor.add_node(node)
            if executor.public and nodes:
                nodes[0].get_logger().warning(f"rclpy's public executor ({executor.public_reason}): each message "
                                              "costs ~0.45 ms more")
            # the set-up's objects (modules, nodes, sessions, a replayed recording's arrays) leave the cyclic
            # collector's scans: a collection while spinning looks only at what the stream made since
            gc.collect()
            gc.freeze()
            executor.spin()
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except EucError as exc:
            if rclpy.ok():
                print(f"{label}: error: {exc}", file=sys.stderr)
                code = 2
            else:                       # a stop signal shut the context down while a node was being set up
                signalled = True
        except Exception:
            # A SIGINT/SIGTERM can land while rclpy is making a node or taking a message; that then fails (e.g.
            # an RCLError, a pybind RuntimeError) a moment before the signal handler has shut the context down.
            # Give the shutdown that moment; only an error with the context still up is a real one.
            if not wait_for_context_shutdown(rclpy.get_default_context(), SHUTDOWN_RACE_S):
                raise
            signalled = True
    except (KeyboardInterrupt, ExternalShutdownException):
        signalled = True
    finally:
        if signalled:
            # before the executor's signal guard condition is destroyed: rclpy's signal thread may still be
            # triggering it (a use after free: SIGSEGV at exit, about one exit in three here)
            wait_for_context_shutdown(rclpy.get_default_context())
        if executor is not None:
            executor.shutdown(timeout_sec=0.0)
        for node in reversed(nodes):
            close = getattr(node, "close", None)
            if callable(close):
                close()
            node.destroy_node()
        rclpy.try_shutdown()
        startup.stopped()
    return code


def main_for(node_class: type) -> Callable[[list[str] | None], None]:
    """Return a console-script ``main(args=None)`` for ``node_class``."""
    def main(args: list[str] | None = None) -> None:
        sys.exit(run_node(lambda: node_class(), args, node_name=node_class.NAME, specs=node_class.SPECS))
    main.__doc__ = f"Run the {node_class.__name__} node (``--ros-args --params-file FILE`` to configure)."
    return main


def drain(subscription, handler: Callable, limit: int = 256) -> int:
    """Hand ``handler`` the messages already waiting on ``subscription``; returns how many.

    Called at the end of the subscription's callback: a backlog (a starved node) is then taken in one
    executor wake-up instead of one spin per message, whose fixed cost (the Python executor rebuilds
    its wait set every spin) would otherwise keep the node behind. Order is kept: the messages come
    from the same queue, oldest first. ``limit`` bounds the time spent away from timers and services.
    Taking needs rclpy's private API: where :mod:`~euc_ros.ros.rclpy_compat` refuses it, nothing is
    taken here (the executor delivers each message).
    """
    if not _TAKE_DIRECTLY:
        return 0
    n = 0
    take = rclpy_compat.take
    while n < limit:
        info = take(subscription)
        if info is None:
            break
        handler(info[0])
        n += 1
    return n
