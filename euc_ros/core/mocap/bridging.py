"""Bridge short gaps of each rigid body before the geometry, offline and live alike.

A marker set that flickers for a frame or two leaves one body untracked while every other body is
fine. Dropping the whole frame, or letting a NaN of that one body reach the derivatives, splits the
signal and costs a filter window around every blink (one blank frame of the EUC body cost 1.2 s of
states offline). Instead each body's pose is bridged on its own, before any geometry, across runs of
at most ``max_gap`` missing frames: the position linearly and the orientation by spherical linear
interpolation (slerp), both in the frame number. Longer runs stay missing (the interval is invalid
only where it must be).

* :func:`bridge_series` does a whole :class:`~euc_ros.core.mocap.series.MocapSeries` at once (vectorized);
* :class:`PoseBridge` does a live stream frame by frame and gives the same poses. A frame with every
  body present passes at once; a frame with a body missing waits until that body reappears (or
  ``max_gap`` frames have passed), so a clean stream has no delay and a blink delays the output by
  at most ``max_gap`` frames, once.

Both report which samples were bridged; the states computed from them are used (a one-frame slerp
of a body moving at 1 rad/s and 120 Hz errs by ~1e-5 rad, far below the mocap noise), and their
number is reported.
"""
from __future__ import annotations

from collections import deque
from dataclasses import replace
from typing import Sequence

import numpy as np


def slerp(q0: np.ndarray, q1: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Spherical linear interpolation of unit quaternions (x, y, z, w), shortest arc.

    Parameters
    ----------
    q0, q1 : ndarray (..., 4)
    a : ndarray (...)
        Fraction from ``q0`` (0) to ``q1`` (1).

    Returns
    -------
    numpy.ndarray
        Unit quaternions (..., 4).

    Examples
    --------
    >>> z90 = np.array([0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    >>> np.round(slerp(np.array([0, 0, 0, 1.0]), z90, np.array(0.5)), 6)   # 45 deg about z
    array([0.      , 0.      , 0.382683, 0.92388 ])
    """
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    a = np.asarray(a, dtype=float)[..., None]
    d = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(d < 0, -q1, q1)
    d = np.abs(d)
    omega = np.arccos(np.clip(d, -1.0, 1.0))
    s = np.sin(omega)
    small = s < 1e-9
    with np.errstate(invalid="ignore", divide="ignore"):
        w0 = np.where(small, 1.0 - a, np.sin((1.0 - a) * omega) / np.where(small, 1.0, s))
        w1 = np.where(small, a, np.sin(a * omega) / np.where(small, 1.0, s))
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def bridge_series(series, max_gap: int):
    """Bridge every body's runs of at most ``max_gap`` missing frames (see the module docstring).

    Parameters
    ----------
    series : MocapSeries
        Z-up poses; a sample is missing when untracked or not finite. Frame numbers define the
        spacing (a skipped number is a frame missing for every body).
    max_gap : int
        Longest run of missing frames bridged [frames].

    Returns
    -------
    MocapSeries, ndarray of bool (b, n)
        A copy with the bridged samples filled and tracked, and the mask of those samples.
    """
    pos = np.array(series.position, dtype=float, copy=True)
    quat = np.array(series.quat, dtype=float, copy=True)
    tracked = np.array(series.tracked, dtype=bool, copy=True)
    b, n = tracked.shape
    bridged = np.zeros((b, n), dtype=bool)
    if n < 3 or max_gap <= 0:
        return replace(series, position=pos, quat=quat, tracked=tracked), bridged
    frame = np.asarray(series.frame, dtype=np.int64)
    ok = tracked & np.all(np.isfinite(pos), axis=-1) & np.all(np.isfinite(quat), axis=-1)
    idx = np.arange(n)
    for i in range(b):               # a loop over bodies (~14), vectorized over frames
        good = ok[i]
        if good.all() or not good.any():
            continue
        prev = np.maximum.accumulate(np.where(good, idx, -1))
        nxt = np.minimum.accumulate(np.where(good, idx, n)[::-1])[::-1]
        miss = ~good & (prev >= 0) & (nxt < n)
        if not miss.any():
            continue
        p, q = prev[miss], nxt[miss]
        span = frame[q] - frame[p]
        fill = span - 1 <= max_gap
        if not fill.any():
            continue
        rows = np.flatnonzero(miss)[fill]
        p, q = p[fill], q[fill]
        a = (frame[rows] - frame[p]) / (frame[q] - frame[p])
        pos[i, rows] = pos[i, p] + a[:, None] * (pos[i, q] - pos[i, p])
        quat[i, rows] = slerp(quat[i, p], quat[i, q], a)
        tracked[i, rows] = True
        bridged[i, rows] = True
    return replace(series, position=pos, quat=quat, tracked=tracked), bridged


class PoseBridge:
    """Live twin of :func:`bridge_series`: frames come out bridged, held only while a body is missing.

    Parameters
    ----------
    max_gap : int
        Longest run of missing frames of one body that is bridged [frames].

    Examples
    --------
    >>> br = PoseBridge(2)
    >>> q = np.array([[0, 0, 0, 1.0]])
    >>> outs = [br.push(k, 0.1 * k, np.array([[k, 0.0, 0.0]]) if k != 1 else np.full((1, 3), np.nan), q,
    ...                 np.array([k != 1]), ["E"]) for k in range(4)]
    >>> [[o[0] for o in out] for out in outs]
    [[0], [], [1, 2], [3]]
    >>> outs[2][0][2][0].tolist(), bool(outs[2][0][5][0])    # frame 1's position, bridged
    ([1.0, 0.0, 0.0], True)
    """

    def __init__(self, max_gap: int) -> None:
        self.max_gap = int(max_gap)
        self._line: deque = deque()      # [frame, t, pos, quat, ok, bridged]
        self._bodies: list[str] | None = None
        self._last_ok: list | None = None   # per body: (frame, pos, quat) of the last released valid pose

    def reset(self) -> list:
        """Release everything held (unbridged where the gap's end is not known) and start over.

        Returns
        -------
        list of tuple
            The frames released, each ``(frame, t, position, quat, tracked, bridged)``.
        """
        out = [self._release(row, final=True) for row in list(self._line)]
        self._line.clear()
        self._last_ok = None
        return out

    def push(self, frame: int, t: float, position, quat, tracked, bodies: Sequence[str]) -> list:
        """Add one frame; return the frames released, each ``(frame, t, position, quat, tracked, bridged)``.

        Parameters
        ----------
        frame : int
            Frame number (increasing; a number not above the last starts over).
        t : float
            Capture time [s].
        position : array_like
            Pivot positions (b, 3) [m].
        quat : array_like
            Quaternions (b, 4), (x, y, z, w).
        tracked : array_like
            Tracked flags (b,).
        bodies : sequence of str
            Body names of the rows; a new list starts over.

        Returns
        -------
        list of tuple
            The frames released, each ``(frame, t, position, quat, tracked, bridged)`` with ``bridged`` (b,)
            marking the poses filled across a gap.
        """
        bodies = list(bodies)
        out = []
        if self._bodies is not None and bodies != self._bodies:
            out += self.reset()
        self._bodies = bodies
        pos = np.array(position, dtype=float, copy=True).reshape(-1, 3)
        q = np.array(quat, dtype=float, copy=True).reshape(-1, 4)
        trk = np.asarray(tracked, dtype=bool).reshape(-1)
        ok = trk & np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(q), axis=1)
        if self._line and int(frame) <= self._line[-1][0]:
            out += self.reset()
        self._line.append([int(frame), float(t), pos, q, ok, np.zeros(len(bodies), bool)])
        if self._last_ok is None:
            self._last_ok = [None] * len(bodies)
        while self._line and self._ready(self._line[0]):
            out.append(self._release(self._line.popleft()))
        return out

    def _ready(self, row) -> bool:
        """Whether the oldest held frame can be released (every missing body's gap decided)."""
        if self._line[-1][0] - row[0] >= self.max_gap:
            return True
        return all(any(r[4][i] for r in self._line if r is not row) for i in np.flatnonzero(~row[4]))

    def _release(self, row, final: bool = False):
        frame, t, pos, q, ok, bridged = row
        for i in np.flatnonzero(~ok):
            last = self._last_ok[i] if self._last_ok is not None else None
            if last is None or final:
                continue
            nxt = next(((r[0], r[2][i], r[3][i]) for r in self._line if r[4][i]), None)
            if nxt is None or nxt[0] - last[0] - 1 > self.max_gap:
                continue
            a = (frame - last[0]) / (nxt[0] - last[0])
            pos[i] = last[1] + a * (nxt[1] - last[1])
            q[i] = slerp(last[2], nxt[2], np.array(a))
            ok[i] = True
            bridged[i] = True
        if self._last_ok is not None:
            for i in np.flatnonzero(ok & ~bridged):   # measured poses only, as bridge_series
                self._last_ok[i] = (frame, pos[i], q[i])
        return frame, t, pos, q, ok, bridged
