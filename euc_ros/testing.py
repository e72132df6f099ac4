"""Helpers for tests that talk to live nodes: bounded waits that never hang."""
from __future__ import annotations

import time
from typing import Callable


def wait_for(predicate: Callable[[], bool], timeout_s: float, period_s: float = 0.02) -> bool:
    """Poll ``predicate`` until it is true or ``timeout_s`` passes; return its last value."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period_s)
    return bool(predicate())


def spin_until(node, predicate: Callable[[], bool], timeout_s: float, executor=None) -> bool:
    """Spin ``node`` (in its own context) until ``predicate`` holds or ``timeout_s`` passes."""
    from rclpy.executors import SingleThreadedExecutor

    ex = executor or SingleThreadedExecutor(context=node.context)
    ex.add_node(node)
    try:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return True
            ex.spin_once(timeout_sec=0.02)
        return bool(predicate())
    finally:
        ex.remove_node(node)
