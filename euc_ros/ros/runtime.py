"""The Jazzy node lifecycle, written once: init, spin, clean shutdown on SIGINT/SIGTERM.

In rclpy 7.1 (Jazzy) both SIGINT and SIGTERM end ``spin`` with ``ExternalShutdownException``;
``rclpy.init`` returns None (no context manager, unlike rolling). A node stopped by a signal exits
with code 0, whether it was spinning or still starting (a node executable: :mod:`euc_ros.ros.startup`
until ``rclpy.init`` has returned). The nodes spin on :class:`~euc_ros.ros.executor.LeanExecutor`,
rclpy's public executor where :mod:`~euc_ros.ros.rclpy_compat` refuses rclpy's private API (said once
on the console). A callback that cannot use its input drops it through :class:`CallbackErrors` and the node
keeps running.
"""
from __future__ import annotations

import gc
import sys
import traceback
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
#: Throttle of the log lines of :class:`CallbackErrors` [s] (one for every node: rclpy refuses a call site's
#: throttle to change).
DROP_LOG_THROTTLE_S = 5.0


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


class CallbackErrors:
    """The callback boundary of a live node: what its callbacks drop is logged and counted, and the node runs on.

    Bad input (:class:`~euc_ros.core.errors.EucError`) is dropped with a warning. Any other exception is a
    bug: it is logged at ERROR with its traceback and counted apart, so that the diagnostics tell the two
    apart; the callback still returns, since a live node never dies on its input. A callback keeps the two
    clauses in this order::

        try:
            ...
        except EucError as exc:     # bad input: dropped, counted, warned
            self.drops.input_error(exc)
            return
        except Exception:           # a bug: logged with its traceback, counted apart; the node runs on
            self.drops.unexpected_error()
            return

    Both log lines are throttled (``throttle_duration_sec`` :data:`DROP_LOG_THROTTLE_S`, each kind on its own,
    shared by the callbacks of one node). While the node's context shuts down (a stop signal), an exception is
    the stop's doing, not a bug: it is logged at debug level only and not counted.

    Parameters
    ----------
    node : rclpy.node.Node
        The node whose logger reports the drops.
    what : str
        What a drop loses, at the start of each log line (``"frame dropped"``).
    counts : dict, optional
        The node's counters (published in its diagnostics) to count in; default a dict of its own.
    key, unexpected_key : str
        The names of the two counters in ``counts``: inputs dropped on an EucError, and on any other exception.

    Attributes
    ----------
    counts : dict
        The counters (``counts[key]`` and ``counts[unexpected_key]`` start at 0 unless present).
    """

    def __init__(self, node: Node, what: str, counts: dict | None = None, *, key: str = "errors",
                 unexpected_key: str = "unexpected_errors") -> None:
        self.node = node
        self.what = what
        self.counts = {} if counts is None else counts
        self.key, self.unexpected_key = key, unexpected_key
        self.counts.setdefault(key, 0)
        self.counts.setdefault(unexpected_key, 0)

    @property
    def errors(self) -> int:
        """Inputs dropped on an :class:`~euc_ros.core.errors.EucError`."""
        return self.counts[self.key]

    @property
    def unexpected(self) -> int:
        """Inputs dropped on any other exception (bugs)."""
        return self.counts[self.unexpected_key]

    def input_error(self, exc: EucError, what: str | None = None) -> None:
        """Count an input dropped on ``exc`` and warn with its message (throttled).

        Parameters
        ----------
        exc : EucError
            Why the input could not be used.
        what : str, optional
            What was dropped, instead of the instance's ``what``.
        """
        self.counts[self.key] += 1
        self.node.get_logger().warning(f"{what or self.what}: {type(exc).__name__}: {exc}",
                                       throttle_duration_sec=DROP_LOG_THROTTLE_S)

    def unexpected_error(self, what: str | None = None) -> None:
        """Count the exception being handled (call it in an ``except`` clause) and log it with its traceback.

        Parameters
        ----------
        what : str, optional
            What was dropped, instead of the instance's ``what``.
        """
        log = self.node.get_logger()
        what = what or self.what
        if not self.node.context.ok():      # stopping: publishing or taking on a shut-down context fails
            log.debug(f"{what} while stopping: {traceback.format_exc(limit=1).strip()}")
            return
        self.counts[self.unexpected_key] += 1
        log.error(f"{what}: unexpected error (a bug: please report it; the node keeps running)\n"
                  f"{traceback.format_exc().rstrip()}", throttle_duration_sec=DROP_LOG_THROTTLE_S)
