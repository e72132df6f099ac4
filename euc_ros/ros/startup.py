"""A node process stopped before it runs ends quietly: one line and exit code 0, no traceback.

``euc-ros launch`` stops its nodes with SIGINT (then SIGTERM). A node still importing its modules
(numpy, scipy, rclpy, the messages: about a second after it starts) would die inside an import, with
a KeyboardInterrupt traceback and exit code 1 for SIGINT, or killed with -15 for SIGTERM. The node
executables therefore call :func:`install` before their heavy imports (``euc_ros/nodes/__init__.py``
does, and the console scripts import it first): until :func:`running` is called, SIGINT and SIGTERM
end the process at once with one line on stderr and **exit code 0**, the code of a node stopped while
it spins (:func:`euc_ros.ros.runtime.run_nodes`). Nothing needs closing then: no context, no file.

:func:`running` is called once rclpy is initialised: rclpy's own handlers take the signals from then
on and call this one after theirs, which then does what Python's default would (a KeyboardInterrupt
for SIGINT; nothing more for SIGTERM, which rclpy turns into a shutdown). :func:`stopped` restores
Python's defaults when rclpy has shut down.

This module imports nothing heavy: it runs before numpy and rclpy are loaded.
"""
from __future__ import annotations

import os
import signal
import sys

#: The package's node executables (setup.py ``NODES``): the processes :func:`install_for` applies to.
NODE_EXECUTABLES = frozenset(("mocap_ingest", "rider_state", "torque_estimator", "monitor", "recorder",
                              "unicycle_sim", "steering_controller", "pipeline_container"))
#: Signals a starting node ends quietly on.
SIGNALS = (signal.SIGINT, signal.SIGTERM)

_state = {"installed": False, "running": False, "name": ""}


def install(name: str) -> bool:
    """Make SIGINT and SIGTERM end this process quietly with code 0 until :func:`running`; True if installed.

    Only the main thread can install signal handlers: from another one nothing is done (False).
    """
    try:
        for sig in SIGNALS:
            signal.signal(sig, _handler)
    except ValueError:                     # not the main thread
        return False
    _state.update(installed=True, running=False, name=name)
    return True


def install_for(argv: list[str]) -> bool:
    """:func:`install` when ``argv[0]`` is one of :data:`NODE_EXECUTABLES` (a console script or ``ros2 run``)."""
    name = os.path.basename(argv[0]) if argv else ""
    return install(name) if name in NODE_EXECUTABLES else False


def running() -> None:
    """After rclpy's initialisation: its handlers take the signals from now on."""
    _state["running"] = True


def stopped() -> None:
    """After rclpy's shutdown (its handlers are gone): Python's default handling of SIGINT and SIGTERM again."""
    if not _state["installed"]:
        return
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    except ValueError:
        return
    _state.update(installed=False, running=False)


def is_installed() -> bool:
    """Whether :func:`install` took effect in this process (and :func:`stopped` has not undone it)."""
    return _state["installed"]


def _handler(signum, frame) -> None:
    if _state["running"]:
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        return                                 # SIGTERM: rclpy's handler, called before this one, shut down
    try:
        os.write(2, f"{_state['name']}: {signal.Signals(signum).name} while starting: stopped\n".encode())
    except OSError:                            # no stderr (a closed terminal): the exit matters, not the line
        pass
    try:
        sys.stdout.flush()
    except Exception:                          # e.g. interrupted in the middle of a write to it
        pass
    os._exit(0)
