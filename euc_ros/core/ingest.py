"""Live ingest logic, ROS-free: assembling frames from per-body poses, and tracking statistics.

:class:`PoseSynchronizer` turns one pose stream per rigid body (vrpn_mocap convention) into whole
frames; :class:`TrackingStats` counts per-body tracking, dropped frames (gaps in the frame number)
and duplicate or out-of-order frames, for the diagnostics. Time is always an argument (``stamp_ns``).
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np


@dataclass
class Frame:
    """One assembled capture frame (Z-up world)."""

    stamp_ns: int
    frame_number: int
    bodies: list[str]
    position: np.ndarray          # (b, 3), NaN where untracked
    quat: np.ndarray              # (b, 4), NaN where untracked
    tracked: np.ndarray           # (b,) bool
    mean_marker_error: np.ndarray  # (b,) [m], NaN when unknown


class PoseSynchronizer:
    """Group per-body poses with (nearly) equal stamps into frames.

    A frame is emitted when every body has reported for its stamp, or when a newer stamp is more
    than ``timeout_s`` ahead (then the missing bodies are untracked in that frame: never a zero pose).

    Parameters
    ----------
    bodies : list of str
        Bodies that make a frame, in output order.
    tolerance_s : float
        Poses whose stamps differ by less than this belong to the same frame.
    timeout_s : float
        How long a partial frame may wait for its missing bodies.
    """

    def __init__(self, bodies: list[str], tolerance_s: float = 0.002, timeout_s: float = 0.05):
        self.bodies = list(bodies)
        self._index = {b: i for i, b in enumerate(self.bodies)}
        self.tol_ns = int(tolerance_s * 1e9)
        self.timeout_ns = int(timeout_s * 1e9)
        self._pending: dict[int, Frame] = {}
        self._reported: dict[int, np.ndarray] = {}
        self._last_emitted_ns: int | None = None
        self._count = 0
        self.late_dropped = 0

    def _new_frame(self, stamp_ns: int) -> Frame:
        b = len(self.bodies)
        return Frame(stamp_ns, -1, self.bodies, np.full((b, 3), np.nan), np.full((b, 4), np.nan),
                     np.zeros(b, bool), np.full(b, np.nan))

    def push(self, body: str, stamp_ns: int, position, quat) -> list[Frame]:
        """Add one pose; return the frames completed by it (oldest first)."""
        i = self._index.get(body)
        if i is None:
            return []
        if self._last_emitted_ns is not None and stamp_ns <= self._last_emitted_ns + self.tol_ns // 2:
            self.late_dropped += 1
            return []
        key = next((k for k in self._pending if abs(k - stamp_ns) <= self.tol_ns), None)
        if key is None:
            key = stamp_ns
            self._pending[key] = self._new_frame(stamp_ns)
            self._reported[key] = np.zeros(len(self.bodies), bool)
        frame = self._pending[key]
        self._reported[key][i] = True
        frame.position[i] = position
        frame.quat[i] = quat
        frame.tracked[i] = bool(np.all(np.isfinite(position)) and np.all(np.isfinite(quat)))
        out = []
        for k in sorted(self._pending):
            complete = bool(np.all(self._reported[k]))
            expired = stamp_ns - k > self.timeout_ns
            if complete or expired:
                out.append(self._emit(k))
            else:
                break
        return out

    def _emit(self, key: int) -> Frame:
        f = self._pending.pop(key)
        self._reported.pop(key)
        f.frame_number = self._count
        self._count += 1
        self._last_emitted_ns = f.stamp_ns
        # anything older than this frame can no longer be emitted in order
        for k in [k for k in self._pending if k < key]:
            self._pending.pop(k)
            self._reported.pop(k)
            self.late_dropped += 1
        return f

    def flush(self, now_ns: int) -> list[Frame]:
        """Emit partial frames older than the timeout (call from a timer)."""
        return [self._emit(k) for k in sorted(self._pending) if now_ns - k > self.timeout_ns]


@dataclass
class TrackingStats:
    """Per-body tracking counters and frame-number bookkeeping over a sliding window.

    Parameters
    ----------
    bodies : list of str
    window : int
        Number of recent frames the tracking rate is computed over.
    lost_after : int
        A body untracked for this many consecutive frames is reported as lost.
    """

    bodies: list[str]
    window: int = 120
    lost_after: int = 12
    frames: int = 0
    dropped: int = 0
    duplicates: int = 0
    out_of_order: int = 0
    malformed: int = 0
    last_frame_number: int | None = None
    _history: deque = field(default_factory=deque, repr=False)
    _untracked_run: np.ndarray | None = field(default=None, repr=False)
    _stamps: deque = field(default_factory=deque, repr=False)

    def accept(self, frame_number: int) -> bool:
        """Check a frame number; False (and counted) for duplicates and out-of-order frames."""
        if frame_number >= 0 and self.last_frame_number is not None:
            if frame_number == self.last_frame_number:
                self.duplicates += 1
                return False
            if frame_number < self.last_frame_number:
                self.out_of_order += 1
                return False
            self.dropped += frame_number - self.last_frame_number - 1
        if frame_number >= 0:
            self.last_frame_number = frame_number
        return True

    def update(self, tracked: np.ndarray, stamp_ns: int) -> None:
        """Add the tracked flags (b,) of an accepted frame."""
        tracked = np.asarray(tracked, bool)
        if self._untracked_run is None:
            self._untracked_run = np.zeros(len(self.bodies), int)
        self._untracked_run = np.where(tracked, 0, self._untracked_run + 1)
        self._history.append(tracked)
        self._stamps.append(stamp_ns)
        while len(self._history) > self.window:
            self._history.popleft()
            self._stamps.popleft()
        self.frames += 1

    def tracking_rate(self) -> np.ndarray:
        """Fraction of recent frames in which each body was tracked (b,)."""
        if not self._history:
            return np.zeros(len(self.bodies))
        return np.mean(np.array(self._history), axis=0)

    def lost(self) -> np.ndarray:
        """Bodies currently lost (untracked for ``lost_after`` consecutive frames)."""
        if self._untracked_run is None:
            return np.zeros(len(self.bodies), bool)
        return self._untracked_run >= self.lost_after

    def frame_rate_hz(self) -> float:
        """Measured frame rate over the window [Hz] (NaN with fewer than 2 frames)."""
        if len(self._stamps) < 2:
            return float("nan")
        span = (self._stamps[-1] - self._stamps[0]) * 1e-9
        return (len(self._stamps) - 1) / span if span > 0 else float("nan")


def replay_schedule(t: np.ndarray, rate_factor: float) -> np.ndarray:
    """Wall-clock offsets [s] at which recorded frames at times ``t`` are replayed (rate x factor)."""
    if rate_factor <= 0:
        raise ValueError("rate_factor must be > 0")
    t = np.asarray(t, dtype=float)
    return (t - t[0]) / rate_factor if t.size else t
