"""Pacing of a replayed recording.

:func:`replay_schedule` gives the wall-clock offsets of a replay at a rate factor; :class:`ReplayClock` the
frames a replay has due at a wall-clock time, with their stamps.

Time is always an argument (``now_s``): nothing here reads a clock.
"""
from __future__ import annotations

import numpy as np


def replay_schedule(t: np.ndarray, rate_factor: float) -> np.ndarray:
    """Wall-clock offsets [s] at which recorded frames at times ``t`` [s] are replayed (``rate_factor`` x real time).

    Parameters
    ----------
    t : numpy.ndarray
        Frame times (n,) [s].
    rate_factor : float
        Speed of the replay, > 0.

    Returns
    -------
    numpy.ndarray
        Offsets (n,) [s] from the first frame.

    Raises
    ------
    ValueError
        When ``rate_factor`` is not positive.
    """
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
        """Start the replay at wall-clock time ``now_s`` [s]; replay stamps start at ``stamp_ns``.

        Parameters
        ----------
        now_s : float
            Wall-clock time [s].
        stamp_ns : int
            Stamp of the first frame [ns].
        """
        self.start_s = float(now_s)
        self.start_stamp_ns = int(stamp_ns)

    def due(self, now_s: float) -> tuple[list[tuple[int, int]], str | None]:
        """The frames due by ``now_s`` and not handed out yet, and what happened after them.

        Parameters
        ----------
        now_s : float
            Wall-clock time [s].

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
