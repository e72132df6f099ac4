"""Decimation of a live stream for viewers.

:class:`ViewDecimator` picks the frames whose poses are shown at about a viewing rate.

Time is always an argument (``stamp_ns``): nothing here reads a clock.
"""
from __future__ import annotations

import numpy as np


class ViewDecimator:
    """Which frames' poses are shown when viewers need at most about ``view_rate_hz``.

    A source at a multiple of the view rate is decimated by a whole factor: at a source rate ``r``
    every ``ceil(0.75 r / view_rate_hz)``-th frame is shown (every frame up to the view rate, every
    3rd at 360 Hz for 120 Hz). The factor applies to **frame numbers** when the frames have them and
    the source rate is known (``source_rate_hz``) or measured from the numbered frames (over
    :attr:`MEASURE_S` of stamps, which averages their jitter out; every frame is shown meanwhile).
    Frames without numbers (-1) are decimated by stamp: a frame is shown when 3/4 of the view period
    has passed since the last one shown. Stamps that jitter (receive time minus latency) would fail
    the frame-number rule's promise on the stamp rule.

    Parameters
    ----------
    view_rate_hz : float
        Viewing rate [Hz]; 0 shows every frame.
    source_rate_hz : float, optional
        Frame rate of the source, when known [Hz].
    """

    #: Stamp span over which the frame rate of numbered frames is measured [s].
    MEASURE_S = 1.0
    #: Frames of the measurement, at least.
    MEASURE_FRAMES = 10
    #: A factor within this of a whole number is that number (a measured 480.2 Hz at 120 Hz: 3, not 4).
    FACTOR_TOLERANCE = 0.01

    def __init__(self, view_rate_hz: float, source_rate_hz: float | None = None) -> None:
        self.view_rate_hz = float(view_rate_hz)
        known = source_rate_hz is not None and np.isfinite(source_rate_hz) and source_rate_hz > 0
        self.known_rate_hz = float(source_rate_hz) if known else None
        self.factor: int | None = self._factor(self.known_rate_hz) if known and self.view_rate_hz > 0 else None
        self._measured: float | None = None
        self._first: tuple[int, int] | None = None      # (frame number, stamp) the measurement starts at
        self._last_number: int | None = None
        self._last_stamp_ns: int | None = None

    def _factor(self, rate_hz: float) -> int:
        return max(1, int(np.ceil(0.75 * rate_hz / self.view_rate_hz - self.FACTOR_TOLERANCE)))

    @property
    def source_rate_hz(self) -> float | None:
        """The source rate the frame-number rule uses (known or measured), None before it is."""
        return self.known_rate_hz if self.known_rate_hz is not None else self._measured

    def due(self, frame_number: int, stamp_ns: int) -> bool:
        """Whether this frame's poses are shown.

        Parameters
        ----------
        frame_number : int
            Frame number; negative when unknown.
        stamp_ns : int
            Frame stamp [ns].

        Returns
        -------
        bool
            Whether the frame is shown.
        """
        if self.view_rate_hz <= 0:
            return True
        if frame_number < 0:
            return self._due_by_stamp(int(stamp_ns))
        number = int(frame_number)
        last = self._last_number
        if last is not None and number < last:           # numbering restarted: start again
            self._first, last = None, None
            if self.known_rate_hz is None:
                self.factor, self._measured = None, None
        if self.factor is None:
            self._measure(number, int(stamp_ns))
        if last is None or self.factor is None or number - last >= self.factor:
            self._last_number = number
            return True
        return False

    def _measure(self, number: int, stamp_ns: int) -> None:
        if self._first is None:
            self._first = (number, stamp_ns)
            return
        n0, s0 = self._first
        span_s = (stamp_ns - s0) * 1e-9
        if span_s >= self.MEASURE_S and number - n0 >= self.MEASURE_FRAMES:
            self._measured = (number - n0) / span_s
            self.factor = self._factor(self._measured)

    def _due_by_stamp(self, stamp_ns: int) -> bool:
        last = self._last_stamp_ns
        if last is None or stamp_ns < last or stamp_ns - last >= 0.75e9 / self.view_rate_hz:
            self._last_stamp_ns = stamp_ns
            return True
        return False
