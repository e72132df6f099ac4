"""Live ingest logic, ROS-free: frames from per-body poses, tracking statistics, replay timing, start stamps.

* :class:`PoseSynchronizer` turns one pose stream per rigid body (vrpn_mocap convention,
  ``<prefix>/<Body>/pose``) into whole frames, dropping and counting duplicate and out-of-order stamps
  and recognising a restarted stream (a large backwards jump of the stamps).
* :class:`TrackingStats` counts per-body tracking, dropped frames (gaps in the frame number, or in the
  stamps when there is no frame number), duplicate, out-of-order and restarted frame numbers, for
  the diagnostics of the ``mocap_ingest`` node.
* :func:`replay_schedule` gives the wall-clock offsets of a replay at a rate factor;
  :class:`ReplayClock` the frames a replay has due at a wall-clock time, with their stamps.
* :class:`ViewDecimator` picks the frames whose poses are shown at about a viewing rate.
* :class:`SilenceWatch` says when a stream has been silent long enough to warn, and when it is back.
* :func:`capture_start_ns` / :func:`format_capture_start` convert Motive's ``Capture Start Time``
  text to nanoseconds since the epoch and back (offline stamps are ``start + frame / rate``).

Time is always an argument (``stamp_ns``, ``arrival_ns``): nothing here reads a clock.
"""
from __future__ import annotations

import calendar
import re
import time as _time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

#: A quaternion whose norm differs from 1 by more than this is not a valid orientation.
QUAT_NORM_TOLERANCE = 1e-3


@dataclass
class Frame:
    """One assembled capture frame (Z-up world).

    Attributes
    ----------
    stamp_ns : int
        Capture time [ns] (meaning per the source: header stamp, capture time or file time).
    frame_number : int
        Motive frame number; -1 when unknown (per-body pose topics carry none).
    bodies : list of str
    position : ndarray (b, 3)
        Pivot positions [m]; NaN where untracked.
    quat : ndarray (b, 4)
        Body-to-world quaternions (x, y, z, w); NaN where untracked.
    tracked : ndarray (b,) of bool
    mean_marker_error : ndarray (b,)
        [m], NaN when unknown.
    """

    stamp_ns: int
    frame_number: int
    bodies: list[str]
    position: np.ndarray
    quat: np.ndarray
    tracked: np.ndarray
    mean_marker_error: np.ndarray


def empty_frame(stamp_ns: int, frame_number: int, bodies: list[str]) -> Frame:
    """A frame in which no body is tracked (NaN poses, never zeros)."""
    b = len(bodies)
    return Frame(int(stamp_ns), int(frame_number), list(bodies), np.full((b, 3), np.nan), np.full((b, 4), np.nan),
                 np.zeros(b, bool), np.full(b, np.nan))


def valid_pose(position, quat) -> bool:
    """True if the position is finite and the quaternion finite with unit norm (within 1e-3)."""
    p = np.asarray(position, float)
    q = np.asarray(quat, float)
    return bool(np.all(np.isfinite(p)) and np.all(np.isfinite(q))
                and abs(float(np.linalg.norm(q)) - 1.0) <= QUAT_NORM_TOLERANCE)


class _Pending:
    __slots__ = ("frame", "reported", "arrival_ns")

    def __init__(self, frame: Frame, arrival_ns: int) -> None:
        self.frame = frame
        self.reported = np.zeros(len(frame.bodies), bool)
        self.arrival_ns = arrival_ns


class PoseSynchronizer:
    """Group per-body poses with (nearly) equal stamps into frames, in stamp order.

    A frame is emitted when every body has reported for its stamp, or when it has waited too long:
    a pose more than ``timeout_s`` newer (stamp time) arrives, or :meth:`flush` is called more than
    ``timeout_s`` after its first pose arrived (arrival time). Bodies that did not report, or reported
    an invalid pose (NaN, non-unit quaternion), are untracked in that frame with a NaN pose: never a
    zero pose. Frames are emitted in increasing stamp order; the frame stamp is the stamp of the
    first pose of the frame.

    Dropped and counted (attributes):

    ``duplicates``
        a pose of a body with the stamp (within ``tolerance_s``) of that body's previous pose;
    ``out_of_order``
        a pose older than that body's previous pose, or too late for a frame already emitted
        without it (by less than ``restart_s``);
    ``restarts``
        not dropped: a pose more than ``restart_s`` older than the body's previous pose or the last
        emitted frame means the source restarted (a replay looped, a driver restarted); pending
        frames are emitted and the order checks start again from that pose;
    ``invalid``
        poses with a NaN or a non-unit quaternion (kept as untracked, counted).

    Parameters
    ----------
    bodies : list of str
        Bodies that make a frame, in output order.
    tolerance_s : float
        Poses whose stamps differ by at most this belong to the same frame [s].
    timeout_s : float
        How long a partial frame may wait for its missing bodies [s].
    restart_s : float
        A backwards jump of the stamps larger than this is a restart of the source [s].
    """

    def __init__(self, bodies: list[str], tolerance_s: float = 0.002, timeout_s: float = 0.05,
                 restart_s: float = 1.0) -> None:
        self.bodies = list(bodies)
        self._index = {b: i for i, b in enumerate(self.bodies)}
        self.tol_ns = int(round(tolerance_s * 1e9))
        self.timeout_ns = int(round(timeout_s * 1e9))
        self.restart_ns = int(round(restart_s * 1e9))
        self._pending: dict[int, _Pending] = {}
        self._last_ns: int | None = None
        self._body_last: list[int | None] = [None] * len(self.bodies)
        self.duplicates = 0
        self.out_of_order = 0
        self.restarts = 0
        self.invalid = 0
        self.unknown_body = 0

    @property
    def late_dropped(self) -> int:
        """Poses dropped for their stamp (duplicates + out of order)."""
        return self.duplicates + self.out_of_order

    @property
    def pending(self) -> int:
        """Number of frames waiting for bodies."""
        return len(self._pending)

    def push(self, body: str, stamp_ns: int, position, quat, arrival_ns: int | None = None) -> list[Frame]:
        """Add one pose; return the frames it completes or expires (oldest first).

        Parameters
        ----------
        body : str
        stamp_ns : int
            Header stamp of the pose [ns].
        position : array (3,)
            [m].
        quat : array (4,)
            (x, y, z, w).
        arrival_ns : int, optional
            When the pose arrived (any monotonic clock, the one :meth:`flush` is called with) [ns];
            default ``stamp_ns``.
        """
        i = self._index.get(body)
        if i is None:
            self.unknown_body += 1
            return []
        stamp_ns = int(stamp_ns)
        arrival_ns = stamp_ns if arrival_ns is None else int(arrival_ns)
        out: list[Frame] = []
        last_b = self._body_last[i]
        if ((last_b is not None and stamp_ns < last_b - self.restart_ns)
                or (self._last_ns is not None and stamp_ns < self._last_ns - self.restart_ns)):
            self.restarts += 1
            out += [self._emit(k) for k in sorted(self._pending)]
            self._last_ns = None
            self._body_last = [None] * len(self.bodies)
            last_b = None
        if last_b is not None and abs(stamp_ns - last_b) <= self.tol_ns:
            self.duplicates += 1
            return out
        if last_b is not None and stamp_ns < last_b:
            self.out_of_order += 1
            return out
        if self._last_ns is not None and stamp_ns <= self._last_ns + self.tol_ns:
            self.out_of_order += 1       # late for a frame already emitted without this body
            return out
        key = next((k for k in self._pending if abs(k - stamp_ns) <= self.tol_ns), None)
        if key is None:
            key = stamp_ns
            self._pending[key] = _Pending(empty_frame(stamp_ns, -1, self.bodies), arrival_ns)
        entry = self._pending[key]
        if entry.reported[i]:
            self.duplicates += 1
            return out
        self._body_last[i] = stamp_ns
        entry.reported[i] = True
        if valid_pose(position, quat):
            q = np.asarray(quat, float)
            entry.frame.position[i] = np.asarray(position, float)
            entry.frame.quat[i] = q / np.linalg.norm(q)
            entry.frame.tracked[i] = True
        else:
            self.invalid += 1
        out += self._drain(newest_stamp_ns=stamp_ns)
        return out

    def flush(self, now_ns: int) -> list[Frame]:
        """Emit the frames whose first pose arrived more than ``timeout_s`` before ``now_ns`` (call from a timer).

        ``now_ns`` is on the clock of the ``arrival_ns`` given to :meth:`push` (the stamps when none
        was given). Complete frames queued behind an expired one are emitted with it.
        """
        return self._drain(now_ns=int(now_ns))

    def _drain(self, newest_stamp_ns: int | None = None, now_ns: int | None = None) -> list[Frame]:
        out = []
        for k in sorted(self._pending):
            entry = self._pending[k]
            complete = bool(np.all(entry.reported))
            expired = ((newest_stamp_ns is not None and newest_stamp_ns - k > self.timeout_ns)
                       or (now_ns is not None and now_ns - entry.arrival_ns > self.timeout_ns))
            if not (complete or expired):
                break
            out.append(self._emit(k))
        return out

    def _emit(self, key: int) -> Frame:
        entry = self._pending.pop(key)
        self._last_ns = entry.frame.stamp_ns
        return entry.frame


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
    count, belong to :class:`PoseSynchronizer` upstream).

    Parameters
    ----------
    bodies : list of str
    window : int
        Number of recent frames the tracking and frame rates are computed over.
    lost_after : int
        A body untracked for this many consecutive frames is reported as lost.
    restart_frames : int
        Backwards frame-number jump beyond which the source is taken as restarted [frames].
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
        """Median stamp spacing over the window [ns] (NaN with fewer than 5 frames)."""
        if len(self._stamps) < 5:
            return float("nan")
        return float(np.median(np.diff(np.asarray(self._stamps, dtype=np.int64))))

    def set_bodies(self, bodies: list[str]) -> None:
        """Change the body list (e.g. after a new MODELDEF); per-body history restarts if it changed."""
        bodies = list(bodies)
        if bodies != self.bodies:
            self.bodies = bodies
            self._history.clear()
            self._untracked_run = None

    def update(self, tracked: np.ndarray, stamp_ns: int) -> None:
        """Add the tracked flags (b,) and stamp [ns] of an accepted frame."""
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
    """Wall-clock offsets [s] at which recorded frames at times ``t`` [s] are replayed (``rate_factor`` x real time)."""
    if not rate_factor > 0:
        raise ValueError("rate_factor must be > 0")
    t = np.asarray(t, dtype=float)
    return (t - t[0]) / rate_factor if t.size else t



class ReplayClock:
    """The frames of a recording a replay has due at a wall-clock time, and their stamps.

    Frame ``k`` is due ``replay_schedule(t, rate_factor)[k]`` seconds after the start; a looping replay
    starts again one frame period after the last frame. Stamps are either replay stamps (the stamp
    of the start plus the recorded time since the first frame, the loops' spans added, so they keep
    increasing) or file stamps (the capture start plus the recorded time).

    Parameters
    ----------
    t : (n,) array
        Recorded frame times [s].
    rate_factor : float
        Replay speed relative to real time.
    period_s : float
        One frame period [s] (0 when unknown): the seam between two loops.
    loop : bool
        Start again at the end.
    file_start_ns : int, optional
        Capture start [ns] for file stamps; None for replay stamps.
    """

    def __init__(self, t, rate_factor: float, period_s: float, *, loop: bool = False,
                 file_start_ns: int | None = None) -> None:
        self.t = np.asarray(t, dtype=float)
        self.n_frames = int(self.t.size)
        self.rate_factor = float(rate_factor)
        self.schedule = replay_schedule(self.t, rate_factor)
        #: recorded time one loop covers [s]
        self.loop_span_s = (float(self.t[-1] - self.t[0]) if self.n_frames else 0.0) + period_s
        self.loop = bool(loop)
        self.file_start_ns = file_start_ns
        self.start_s: float | None = None
        self.start_stamp_ns = 0
        self.loop_index = 0
        self.next = 0
        self.done = False

    @property
    def started(self) -> bool:
        """Whether :meth:`start` was called."""
        return self.start_s is not None

    def start(self, now_s: float, stamp_ns: int) -> None:
        """Start the replay at wall-clock time ``now_s`` [s]; replay stamps start at ``stamp_ns``."""
        self.start_s = float(now_s)
        self.start_stamp_ns = int(stamp_ns)

    def due(self, now_s: float) -> tuple[list[tuple[int, int]], str | None]:
        """The frames due by ``now_s`` and not handed out yet, and what happened after them.

        Returns
        -------
        frames : list of (int, int)
            ``(index into t, stamp [ns])``, in order.
        event : str or None
            ``"loop"`` when the replay started again after these frames (frame numbers restart),
            ``"end"`` when it ended, else None.
        """
        if self.start_s is None or self.done:
            return [], None
        t, n = self.t, self.n_frames
        t0 = float(t[0]) if n else 0.0
        elapsed = now_s - self.start_s - self.loop_index * self.loop_span_s / self.rate_factor
        out = []
        while self.next < n and self.schedule[self.next] <= elapsed:
            k = self.next
            if self.file_start_ns is not None:
                stamp = self.file_start_ns + int(round(float(t[k]) * 1e9))
            else:
                stamp = self.start_stamp_ns + int(round((float(t[k]) - t0 + self.loop_index * self.loop_span_s) * 1e9))
            out.append((k, stamp))
            self.next += 1
        if self.next < n:
            return out, None
        if self.loop and n:
            self.next = 0
            self.loop_index += 1
            return out, "loop"
        self.done = True
        return out, "end"


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
        """Whether this frame's poses are shown."""
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


class SilenceWatch:
    """When a stream has been silent long enough to say so, and when it is back.

    Parameters
    ----------
    warn_after_s : float
        Silence (since the start, or since the last data) before the first warning [s].
    repeat_s : float
        Period of the warnings while the silence lasts [s].
    """

    def __init__(self, warn_after_s: float = 3.0, repeat_s: float = 10.0) -> None:
        self.warn_after_s = float(warn_after_s)
        self.repeat_s = float(repeat_s)
        self.started_s: float | None = None
        self.last_data_s: float | None = None
        self.warned_s: float | None = None
        self.ever = False

    def start(self, now_s: float) -> None:
        """Start watching at ``now_s`` [s]."""
        self.started_s = float(now_s)

    def data(self, now_s: float) -> float | None:
        """Data arrived at ``now_s``; returns how long the stream was silent when this is news
        (the first data, or the first after a warned silence) [s], else None."""
        since = self.last_data_s if self.last_data_s is not None else self.started_s
        news = not self.ever or self.warned_s is not None
        self.last_data_s = float(now_s)
        self.ever = True
        self.warned_s = None
        if not news:
            return None
        return 0.0 if since is None else max(0.0, float(now_s) - since)

    def check(self, now_s: float) -> float | None:
        """How long the stream has been silent when a warning is due at ``now_s`` [s], else None."""
        since = self.last_data_s if self.last_data_s is not None else self.started_s
        if since is None:
            return None
        silent = float(now_s) - since
        if silent < self.warn_after_s:
            return None
        if self.warned_s is not None and now_s - self.warned_s < self.repeat_s:
            return None
        self.warned_s = float(now_s)
        return silent

# ------------------------------------------------------------------------------------------ start time
#: Afternoon markers Motive writes after the time, by locale (compared without case and dots).
_PM_MARKERS = {"pm", "p", "du", "nachm", "nm", "午後", "오후", "下午", "μμ", "pp"}
_AM_MARKERS = {"am", "a", "de", "vorm", "vm", "午前", "오전", "上午", "πμ", "ap"}
_START_RE = re.compile(r"^\s*(\d{4})-(\d{1,2})-(\d{1,2})[ T]+(\d{1,2})[.:](\d{2})[.:](\d{2})(?:[.,](\d{1,9}))?\s*(.*)$")


def capture_start_ns(text: str | None) -> int | None:
    """Parse Motive's ``Capture Start Time`` into nanoseconds since the epoch, or None if it cannot.

    Motive writes ``YYYY-MM-DD hh.mm.ss.fff`` followed by a localised AM/PM marker (``AM``, ``PM``,
    ``DU.``, ...) or none (24-hour clock). The time carries no zone: it is taken as **UTC**, so stamps
    do not depend on the zone of the machine that replays the file.

    Parameters
    ----------
    text : str or None

    Returns
    -------
    int or None
        [ns since 1970-01-01 UTC].

    Examples
    --------
    >>> capture_start_ns("2024-05-02 10.15.00.000 AM")
    1714644900000000000
    >>> capture_start_ns("2020-06-16 07.51.41.245 PM") % 86_400_000_000_000 // 1_000_000
    71501245
    """
    if not text:
        return None
    m = _START_RE.match(str(text))
    if not m:
        return None
    year, month, day, hour, minute, second = (int(m.group(k)) for k in range(1, 7))
    frac = (m.group(7) or "0").ljust(9, "0")[:9]
    marker = m.group(8).strip().lower().replace(".", "")
    if marker in _PM_MARKERS and hour < 12:
        hour += 12
    elif marker in _AM_MARKERS and hour == 12:
        hour = 0
    try:
        seconds = calendar.timegm((year, month, day, hour, minute, second, 0, 0, 0))
        if not (1 <= month <= 12 and 1 <= day <= 31 and hour < 24 and minute < 60 and second < 61):
            return None
    except (ValueError, OverflowError):
        return None
    return seconds * 1_000_000_000 + int(frac)


def format_capture_start(ns: int) -> str:
    """Format nanoseconds since the epoch (UTC) as Motive's ``Capture Start Time`` (``2024-05-02 10.15.00.000 AM``).

    Rounded to the millisecond, 12-hour clock with an English marker, as Motive writes it in an
    English locale; :func:`capture_start_ns` reads it back to the millisecond.
    """
    ns = (int(ns) + 500_000) // 1_000_000 * 1_000_000
    seconds, rest = divmod(ns, 1_000_000_000)
    st = _time.gmtime(seconds)
    hour12 = st.tm_hour % 12 or 12
    marker = "PM" if st.tm_hour >= 12 else "AM"
    return (f"{st.tm_year:04d}-{st.tm_mon:02d}-{st.tm_mday:02d} {hour12:02d}.{st.tm_min:02d}.{st.tm_sec:02d}."
            f"{rest // 1_000_000:03d} {marker}")


# ------------------------------------------------------------------------------------------ NatNet
def natnet_capture_stamp(receive_ns: int, latency_s: float, max_latency_s: float = 1.0) -> tuple[int, bool]:
    """Capture time of a NatNet frame: receive time minus the system latency the server reports.

    Parameters
    ----------
    receive_ns : int
        Client clock when the datagram arrived [ns].
    latency_s : float
        :func:`euc_ros.core.io.natnet.latency_s` (camera mid-exposure to transmission) [s]; NaN when
        unknown.
    max_latency_s : float
        Latencies outside ``[0, max_latency_s]`` are not trusted [s].

    Returns
    -------
    stamp_ns : int
        ``receive_ns - latency`` [ns], or ``receive_ns`` when the latency is unknown or implausible.
    corrected : bool
        True when the latency was subtracted (capture time), False for the receive time.
    """
    if np.isfinite(latency_s) and 0.0 <= latency_s <= max_latency_s:
        return int(receive_ns) - int(round(latency_s * 1e9)), True
    return int(receive_ns), False


def frame_from_named_poses(stamp_ns: int, frame_number: int, names, position, quat, bodies: list[str],
                           world_up: str = "z") -> tuple[Frame, list[str]]:
    """Core :class:`Frame` from one message of named poses (mocap4r2_msgs/RigidBodies: one frame, every
    body by name), in the Z-up world of REP-103.

    Parameters
    ----------
    stamp_ns, frame_number : int
    names : sequence of str
        Body names in the message.
    position : array_like (n, 3)
    quat : array_like (n, 4)
        (x, y, z, w), body to world.
    bodies : list of str
        Bodies of the output frame, in order. One absent from the message, or with a non-finite
        position or a quaternion that is not of unit norm, is untracked (NaN pose, never zeros).
    world_up : {"y", "z"}
        Up axis of the poses' world; ``"y"`` (Motive's default axes) maps (X, Y, Z) -> (X, -Z, Y).

    Returns
    -------
    Frame, list of str
        The frame, and the names of the message that are not in ``bodies`` (or repeated).
    """
    from euc_ros.core.rotations import y_up_to_z_up_position, y_up_to_z_up_quat

    out = empty_frame(stamp_ns, frame_number, bodies)
    names = [str(n) for n in names]
    pos = np.asarray(position, float).reshape(len(names), 3)
    q = np.asarray(quat, float).reshape(len(names), 4)
    index = {name: i for i, name in enumerate(bodies)}
    rows = np.array([index.get(n, -1) for n in names], dtype=np.int64)
    first = np.zeros(len(names), bool)
    first[np.unique(rows, return_index=True)[1]] = True      # a name repeated in one message: its first pose
    use = (rows >= 0) & first
    norm = np.linalg.norm(q, axis=1)
    ok = use & np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(q), axis=1) & (
        np.abs(norm - 1.0) <= QUAT_NORM_TOLERANCE)
    p_ok, q_ok = pos[ok], q[ok] / norm[ok, None]
    if world_up == "y" and ok.any():
        p_ok, q_ok = y_up_to_z_up_position(p_ok), y_up_to_z_up_quat(q_ok)
    out.position[rows[ok]], out.quat[rows[ok]] = p_ok, q_ok
    out.tracked[rows[ok]] = True
    return out, [n for n, u in zip(names, use) if not u]


def frame_from_natnet(frame, names_by_id: dict, bodies: list[str], stamp_ns: int, world_up: str = "y") -> Frame:
    """Core :class:`Frame` from a decoded NatNet ``FrameOfData``, in the Z-up world of REP-103.

    Parameters
    ----------
    frame : euc_ros.core.io.natnet.FrameOfData
    names_by_id : dict of int to str
        Rigid-body streaming id -> name (from MODELDEF).
    bodies : list of str
        Bodies of the output frame, in order; bodies absent from the packet, without a name, or with
        the tracking-valid bit clear are untracked (NaN pose).
    stamp_ns : int
        Frame stamp [ns].
    world_up : {"y", "z"}
        Up axis of Motive's streaming world; ``"y"`` maps (X, Y, Z) -> (X, -Z, Y) (docs/motive_csv.md).
    """
    from euc_ros.core.rotations import y_up_to_z_up_position, y_up_to_z_up_quat

    out = empty_frame(stamp_ns, int(frame.frame_number), bodies)
    index = {name: i for i, name in enumerate(bodies)}
    for rb in frame.rigid_bodies:
        i = index.get(names_by_id.get(int(rb.id), None))
        if i is None or not rb.tracking_valid or not valid_pose(rb.position, rb.quat):
            continue
        pos = np.asarray(rb.position, float)
        quat = np.asarray(rb.quat, float)
        quat = quat / np.linalg.norm(quat)
        if world_up == "y":
            pos, quat = y_up_to_z_up_position(pos), y_up_to_z_up_quat(quat)
        out.position[i], out.quat[i] = pos, quat
        out.tracked[i] = True
        out.mean_marker_error[i] = float(rb.mean_error)
    return out
