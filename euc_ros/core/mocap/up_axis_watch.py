"""The up-axis check of :mod:`euc_ros.core.mocap.conventions` on a live stream of frames.

Offline, every analysis checks the recording's up axis against the session before it computes
anything. A live pipeline sees its data one frame at a time: :class:`UpAxisWatch` keeps a thinned
copy of the first frames (at most :data:`KEEP_RATE_HZ` of them per second) and runs the same check
when :data:`CHECK_AFTER_S` of data are in. A conclusive contradiction raises the same error as
offline (a :class:`~euc_ros.core.errors.ConfigError` on ``world_up`` for sources that apply the
session's ``world_up``, an :class:`~euc_ros.core.errors.InputError` for Z-up sources). An inconclusive
check is repeated on more data, up to the last entry of ``CHECK_AFTER_S``; after that the watch gives
up with a warning and keeps nothing.

Examples
--------
>>> import numpy as np
>>> w = UpAxisWatch(["E"], world_up="z")
>>> w.push(0, np.zeros((1, 3)), np.array([[0.0, 0.0, 0.0, 1.0]]), np.array([True]))
>>> w.due(), w.done
(False, False)
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.mocap.conventions import check_conventions, infer_up_axis
from euc_ros.core.mocap.series import MocapSeries

#: Data time after which the check runs, and is repeated while it is inconclusive [s].
CHECK_AFTER_S = (3.0, 10.0, 30.0)
#: Frames kept for the check per second of data (the tests are statistics over the ride).
KEEP_RATE_HZ = 60.0


class UpAxisWatch:
    """Collect the first seconds of a live stream and check its up axis.

    Parameters
    ----------
    bodies : list of str
        Body names of the frames pushed (their order).
    world_up : {"y", "z"} or None
        The up axis the source converted the poses with (Motive CSV, NatNet, rigid-body topics), or
        None for a source that is Z-up by contract (PoseStamped topics).
    session : Session, optional
        Gives the EUC geometry for the wheel-centre and EUC-axis tests (without it only the floor and
        upright-rider tests apply, which rarely conclude).
    label : str
        Where the frames come from, for messages (a file or a server address).
    check_after_s : tuple of float
        Data spans at which the check runs [s].
    keep_rate_hz : float
        Frames kept per second at most [Hz].

    Attributes
    ----------
    done : bool
        The check concluded, or gave up; nothing more is kept.
    result : dict or None
        The last :func:`~euc_ros.core.mocap.conventions.infer_up_axis` result.
    """

    def __init__(self, bodies: list[str], world_up: str | None, session=None, *, label: str = "the stream",
                 check_after_s: tuple[float, ...] = CHECK_AFTER_S, keep_rate_hz: float = KEEP_RATE_HZ):
        self.world_up = world_up
        self.session = session
        self.label = label
        self.check_after_s = tuple(sorted(check_after_s))
        self.keep_period_ns = int(1e9 / keep_rate_hz)
        self.done = False
        self.result: dict | None = None
        self._next_check = 0
        self.reset(bodies)

    def reset(self, bodies: list[str]) -> None:
        """Start again with ``bodies`` (the source named its bodies anew).

        Parameters
        ----------
        bodies : list of str
            Body names of the frames to come.
        """
        self.bodies = list(bodies)
        self._t: list[int] = []
        self._pos: list[np.ndarray] = []
        self._quat: list[np.ndarray] = []
        self._trk: list[np.ndarray] = []

    def push(self, stamp_ns: int, position: np.ndarray, quat: np.ndarray, tracked: np.ndarray) -> None:
        """Keep this frame if the check still needs data and it is due by :data:`KEEP_RATE_HZ`.

        Parameters
        ----------
        stamp_ns : int
            Frame stamp [ns].
        position : numpy.ndarray
            Pivot positions (b, 3) [m].
        quat : numpy.ndarray
            Quaternions (b, 4), (x, y, z, w).
        tracked : numpy.ndarray
            Tracked flags (b,).
        """
        if self.done or len(tracked) != len(self.bodies):
            return
        if self._t and (stamp_ns < self._t[-1] or stamp_ns - self._t[-1] < self.keep_period_ns):
            return
        self._t.append(int(stamp_ns))
        self._pos.append(np.array(position, float))
        self._quat.append(np.array(quat, float))
        self._trk.append(np.array(tracked, bool))

    def span_s(self) -> float:
        """Data time kept so far [s].

        Returns
        -------
        float
            The span [s].
        """
        return (self._t[-1] - self._t[0]) * 1e-9 if len(self._t) > 1 else 0.0

    def due(self) -> bool:
        """Whether enough data are in for the next check.

        Returns
        -------
        bool
            Whether a check is due.
        """
        return not self.done and self.span_s() >= self.check_after_s[self._next_check]

    def series(self) -> MocapSeries:
        """The frames kept, as a series read with ``world_up`` (what the offline check takes).

        Returns
        -------
        MocapSeries
            The kept frames, times from the first [s].
        """
        n = len(self._t)
        t = (np.asarray(self._t, np.int64) - (self._t[0] if n else 0)) * 1e-9
        meta = {"path": self.label}
        if self.world_up is not None:
            meta["world_up"] = self.world_up
        b = len(self.bodies)
        pos = np.stack(self._pos, axis=1) if n else np.zeros((b, 0, 3))
        quat = np.stack(self._quat, axis=1) if n else np.zeros((b, 0, 4))
        trk = np.stack(self._trk, axis=1) if n else np.zeros((b, 0), bool)
        return MocapSeries(t, np.arange(n, dtype=np.int64), list(self.bodies), pos, quat, trk,
                           np.full((b, n), np.nan), name=self.label, meta=meta)

    def check(self) -> list[str]:
        """Run the check on the frames kept.

        Returns
        -------
        list of str
            Warnings: the data fit neither axis, or the check gave up (inconclusive on all the data it
            waits for). Empty while a later check is still to come or when the data agree.

        Raises
        ------
        ConfigError
            The data fit only the other axis than ``world_up`` (names the value they suggest).
        InputError
            A Z-up source whose data say its y axis is vertical.
        """
        series = self.series()
        self.result = infer_up_axis(series, self.session)
        if self.session is not None:
            warnings = check_conventions(series, self.session, path=self.label)
        else:
            warnings = []
            inferred, read_as = self.result["inferred"], self.world_up or "z"
            if self.result["conclusive"] and inferred in ("y", "z") and inferred != read_as:
                warnings = [f"the data of {self.label} suggest the vertical is the {inferred} axis, not "
                            f"{read_as} ({self.result['evidence']}); give the node a session_file to stop on this"]
        conclusive = self.result["conclusive"] and self.result["inferred"] in ("y", "z")
        self._next_check += 1
        if conclusive or warnings or self._next_check >= len(self.check_after_s):
            self.done = True
            self.reset(self.bodies)
            if not conclusive and not warnings:
                warnings = [f"the up axis of {self.label} could not be checked from its first "
                            f"{self.check_after_s[-1]:g} s ({self.result['reason']})"]
        return warnings
