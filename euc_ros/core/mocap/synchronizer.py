"""Whole frames from one pose stream per rigid body: :class:`PoseSynchronizer`.

Per-body pose topics (vrpn_mocap convention, ``<prefix>/<Body>/pose``) are grouped into frames by stamp;
duplicate and out-of-order stamps are dropped and counted, and a restarted stream (a large backwards jump
of the stamps) is recognised.

Time is always an argument (``stamp_ns``, ``arrival_ns``, ``now_ns``): nothing here reads a clock.
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.mocap.frame import Frame, empty_frame, valid_pose


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

        Returns
        -------
        list of Frame
            The frames completed or expired, oldest first.
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

        Parameters
        ----------
        now_ns : int
            Current time [ns].

        Returns
        -------
        list of Frame
            The frames emitted, oldest first.
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
