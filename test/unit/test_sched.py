"""euc_ros.sched: EUC_ROS_REALTIME switches a process to SCHED_FIFO before rclpy starts, or says why not.

Each case runs in a child interpreter (never the test process itself): what the child reports must match
the policy the kernel then gives it (SCHED_FIFO where CAP_SYS_NICE allows, normal otherwise)."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from euc_ros.sched import REALTIME_ENV, realtime_from_env

CHILD = ("import os; from euc_ros.sched import realtime_from_env; m = realtime_from_env('t'); "
         "print(repr(m)); print(os.sched_getscheduler(0) == os.SCHED_FIFO, os.sched_getparam(0).sched_priority)")


def _child(value: str | None):
    env = {k: v for k, v in os.environ.items() if k != REALTIME_ENV}
    if value is not None:
        env[REALTIME_ENV] = value
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    msg, state = out.stdout.strip().splitlines()[-2:]
    fifo, prio = state.split()
    return eval(msg), fifo == "True", int(prio), out.stderr


@pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="no sched_setscheduler on this OS")
def test_unset_leaves_the_policy_and_a_priority_switches_or_says_why_not():
    msg, fifo, _, err = _child(None)
    assert msg is None and not fifo and err == ""
    msg, fifo, prio, err = _child("7")
    if msg.startswith("real-time priority SCHED_FIFO 7"):
        assert fifo and prio == 7
    else:                                        # no CAP_SYS_NICE here: said, and the process runs normally
        assert "not available" in msg and "normal priority" in msg and not fifo
    assert msg in err                            # one line on stderr


@pytest.mark.parametrize("value", ["abc", "0", "100", "-3"])
def test_a_bad_priority_is_named_and_ignored(value):
    msg = realtime_from_env("t", environ={REALTIME_ENV: value})  # never reaches sched_setscheduler
    assert REALTIME_ENV in msg and repr(value) in msg and "normal priority" in msg
