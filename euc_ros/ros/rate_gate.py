"""A node's input held until its frame rate is measured (:class:`euc_ros.core.rate.RateGate` on ROS).

The node builds its filters with the configured rate; once the first frames have measured the real
one, a rate more than 1 % off rebuilds them with the measured rate and logs an ERROR (the node's
diagnostics report it too). Held items are released in order, and a stream that pauses or ends
before the measurement is complete is released by a timer, so nothing is lost.
"""
from __future__ import annotations

import time
from typing import Callable

from euc_ros.core.mocap.rate import RateGate


class NodeRateGate:
    """Hold items until the rate is known, then hand them to ``process`` one by one.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner (logger and timer).
    nominal_hz : float
        Configured rate.
    rebuild : callable
        ``rebuild(rate_hz)``: rebuild the node's filters for a measured rate that disagrees.
    process : callable
        ``process(item)``: handle one item.
    idle_s : float
        Release held items after this long without new input [s].
    **meter_options
        ``min_span_s``, ``min_frames`` of :class:`euc_ros.core.rate.RateMeter`.
    """

    def __init__(self, node, nominal_hz: float, rebuild: Callable[[float], None], process: Callable,
                 idle_s: float = 0.3, **meter_options) -> None:
        self.gate = RateGate(nominal_hz, **meter_options)
        self._node, self._rebuild, self._process = node, rebuild, process
        self._applied = False
        self._idle_s = float(idle_s)
        self._last_wall = time.monotonic()
        node.create_timer(0.1, self._on_timer)

    @property
    def meter(self):
        """The :class:`~euc_ros.core.rate.RateMeter`."""
        return self.gate.meter

    @property
    def held(self) -> int:
        """Items waiting for the rate."""
        return self.gate.held

    def push(self, frame_number: int, stamp_ns: int, item) -> None:
        """Add one item (frame number ``-1`` when unknown)."""
        self._last_wall = time.monotonic()
        self._release(self.gate.push(frame_number, stamp_ns, item))

    def error_message(self) -> str | None:
        """The diagnostics ERROR text when the stream disagrees with the configured rate."""
        m = self.meter
        return f"{m.error}; using the measured {m.rate_hz:.4g} Hz" if m.error else None

    def _on_timer(self) -> None:
        if self.gate.held and time.monotonic() - self._last_wall > self._idle_s:
            self._release(self.gate.flush())

    def _release(self, ready: list) -> None:
        if ready and not self._applied:
            self._applied = True
            if self.meter.error:
                self._rebuild(self.meter.rate_hz)
                self._node.get_logger().error(self.error_message())
        for item in ready:
            self._process(item)
