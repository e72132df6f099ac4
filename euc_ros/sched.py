"""Real-time scheduling of a process (Linux SCHED_FIFO), for the latency-critical parts of a live set-up.

A node process started with ``EUC_ROS_REALTIME=<priority>`` in its environment (1-99; e.g. ``env:`` of a
launch file entry) switches itself to SCHED_FIFO at that priority before ``rclpy.init``, so the
middleware's threads, created afterwards, inherit the policy. It needs CAP_SYS_NICE (root, or an
``rtprio`` limit in /etc/security/limits.conf); without it the process says so and runs at normal
priority. ROS 2's real-time guidance does the same for its critical executors.
"""
from __future__ import annotations

import os
import sys

#: Environment variable holding the SCHED_FIFO priority of a node process.
REALTIME_ENV = "EUC_ROS_REALTIME"


def set_realtime(priority: int, what: str = "running") -> str:
    """Switch this process to SCHED_FIFO at ``priority``; return what happened (never raises)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(priority)))
    except (AttributeError, OSError, ValueError) as exc:
        return f"real-time priority not available ({exc}); {what} with normal priority"
    return f"real-time priority SCHED_FIFO {int(priority)}"


def realtime_from_env(label: str, environ=None) -> str | None:
    """Apply :data:`REALTIME_ENV` if set (one line on stderr saying what happened); None when unset."""
    value = (os.environ if environ is None else environ).get(REALTIME_ENV, "").strip()
    if not value:
        return None
    try:
        prio = int(value)
        if not 1 <= prio <= 99:
            raise ValueError("outside 1-99")
    except ValueError as exc:
        msg = f"{REALTIME_ENV}={value!r} is not a SCHED_FIFO priority 1-99 ({exc}); running with normal priority"
    else:
        msg = set_realtime(prio)
    print(f"{label}: {msg}", file=sys.stderr, flush=True)
    return msg
