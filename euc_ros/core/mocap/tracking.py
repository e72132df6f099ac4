"""Tracking statistics of a live stream: :class:`TrackingStats`.

Per-body tracking, dropped frames (gaps in the frame number, or in the stamps when there is no frame
number), duplicate, out-of-order and restarted frame numbers, for the diagnostics of the ``mocap_ingest``
node. Time is always an argument (``stamp_ns``): nothing here reads a clock.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np


@dataclass
class TrackingStats:
    """Per-body tracking counters and frame bookkeeping over a sliding window.

    Frame numbers (when known, >= 0): a repeated number is a duplicate, a smaller one is out of
    order (both rejected by :meth:`accept`), a gap of ``d`` numbers is ``d - 1`` dropped frames. A
    backwards jump by more than ``restart_frames`` is a **restart** of the source (Motive restarted,
    a replay looped, the node upstream restarted): accepted, counted in ``restarts``, never as drops
    or as out of order, and the rate window starts again.

    Without frame numbers (``-1``, per-body pose topics) dropped frames are counted from gaps in the
    stamps: a gap of ``g`` nominal periods (the median spacing of the window) with ``g > 1.5`` adds
    ``round(g) - 1``; a stamp going backwards restarts the window (the stamp ordering, and the restart
    count, belong to :class:`~euc_ros.core.mocap.synchronizer.PoseSynchronizer` upstream).

    Parameters
    ----------
    bodies : list of str
    window : int
        Number of recent frames the tracking and frame rates are computed over.
    lost_after : int
        A body untracked for this many consecutive frames is reported as lost.
    restart_frames : int
        Backwards frame-number jump beyond which the source is taken as restarted [frames].
    frames : int
        Frames accepted (a counter; starts at 0).
    dropped : int
        Frames missing from the numbering or the stamps (counter).
    duplicates : int
        Repeated frame numbers rejected (counter).
    out_of_order : int
        Frame numbers below the last rejected (counter).
    restarts : int
        Restarts of the source (counter).
    malformed : int
        Malformed frames, counted by the caller (counter).
    last_frame_number : int, optional
        Last accepted frame number.
    """

    bodies: list[str]
    window: int = 120
    lost_after: int = 12
    restart_frames: int = 100
    frames: int = 0
    dropped: int = 0
    duplicates: int = 0
    out_of_order: int = 0
    restarts: int = 0
    malformed: int = 0
    last_frame_number: int | None = None
    _history: deque = field(default_factory=deque, repr=False)
    _untracked_run: np.ndarray | None = field(default=None, repr=False)
    _stamps: deque = field(default_factory=deque, repr=False)

    def accept(self, frame_number: int, stamp_ns: int | None = None) -> bool:
        """Check a frame; False (and counted) for duplicate and out-of-order frame numbers.

        Parameters
        ----------
        frame_number : int
            Motive frame number, -1 when unknown.
        stamp_ns : int, optional
            Frame stamp [ns]; used for the drop count when the frame number is unknown.

        Returns
        -------
        bool
            Whether the frame is accepted.
        """
        frame_number = int(frame_number)
        if frame_number >= 0:
            last = self.last_frame_number
            if last is not None:
                d = frame_number - last
                if d == 0:
                    self.duplicates += 1
                    return False
                if d < 0:
                    if -d <= self.restart_frames:
                        self.out_of_order += 1
                        return False
                    self._restart()
                elif d > 1:
                    self.dropped += d - 1
            self.last_frame_number = frame_number
        elif stamp_ns is not None and self._stamps:
            gap = int(stamp_ns) - self._stamps[-1]
            if gap < 0:
                self._stamps.clear()   # stamps went back: the synchronizer upstream counted the restart
            else:
                period = self.period_ns()
                if np.isfinite(period) and period > 0 and gap > 1.5 * period:
                    self.dropped += int(round(gap / period)) - 1
        return True

    def _restart(self) -> None:
        self.restarts += 1
        self._stamps.clear()

    def restart(self) -> None:
        """Declare a restart of the source (e.g. a replay that loops): counted, numbering starts again."""
        self._restart()
        self.last_frame_number = None

    def period_ns(self) -> float:
        """Median stamp spacing over the window [ns] (NaN with fewer than 5 frames).

        Returns
        -------
        float
            The spacing [ns].
        """
        if len(self._stamps) < 5:
            return float("nan")
        return float(np.median(np.diff(np.asarray(self._stamps, dtype=np.int64))))

    def set_bodies(self, bodies: list[str]) -> None:
        """Change the body list (e.g. after a new MODELDEF); per-body history restarts if it changed.

        Parameters
        ----------
        bodies : list of str
            The new body names.
        """
        bodies = list(bodies)
        if bodies != self.bodies:
            self.bodies = bodies
            self._history.clear()
            self._untracked_run = None

    def update(self, tracked: np.ndarray, stamp_ns: int) -> None:
        """Add the tracked flags (b,) and stamp [ns] of an accepted frame.

        Parameters
        ----------
        tracked : numpy.ndarray
            Tracked flags (b,).
        stamp_ns : int
            Frame stamp [ns].
        """
        tracked = np.asarray(tracked, bool)
        if self._untracked_run is None or self._untracked_run.shape != tracked.shape:
            self._untracked_run = np.zeros(tracked.shape[0], int)
            self._history.clear()
        self._untracked_run = np.where(tracked, 0, self._untracked_run + 1)
        self._history.append(tracked)
        self._stamps.append(int(stamp_ns))
        while len(self._history) > self.window:
            self._history.popleft()
        while len(self._stamps) > self.window:
            self._stamps.popleft()
        self.frames += 1

    def tracking_rate(self) -> np.ndarray:
        """Fraction of recent frames in which each body was tracked (b,).

        Returns
        -------
        numpy.ndarray
            Fractions (b,); zeros before the first frame.
        """
        if not self._history:
            return np.zeros(len(self.bodies))
        return np.mean(np.array(self._history), axis=0)

    def lost(self) -> np.ndarray:
        """Bodies currently lost (untracked for ``lost_after`` consecutive frames).

        Returns
        -------
        numpy.ndarray
            Lost flags (b,).
        """
        if self._untracked_run is None:
            return np.zeros(len(self.bodies), bool)
        return self._untracked_run >= self.lost_after

    def frame_rate_hz(self) -> float:
        """Measured frame rate over the window [Hz] (NaN with fewer than 2 frames).

        Returns
        -------
        float
            The rate [Hz].
        """
        if len(self._stamps) < 2:
            return float("nan")
        span = (self._stamps[-1] - self._stamps[0]) * 1e-9
        return (len(self._stamps) - 1) / span if span > 0 else float("nan")
