"""In-memory motion-capture series: what every reader (Motive CSV, bag, live buffer) returns.

Arrays are in the Z-up world of REP-103, SI units. Body-major layout ``(n_bodies, n_frames, ...)``
so a body's track is contiguous. Untracked samples are NaN with ``tracked == False``: never zeros.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.mocap.rate import measured_rate_hz


@dataclass
class MocapSeries:
    """Rigid-body poses over time.

    Parameters
    ----------
    t : ndarray (n,)
        Capture time of each frame [s] (spec: frame / export rate, plus start offset where known).
    frame : ndarray (n,) of int64
        Motive frame number (may have gaps: dropped frames).
    bodies : list of str
        Rigid-body names.
    position : ndarray (b, n, 3)
        Pivot positions [m], Z-up world.
    quat : ndarray (b, n, 4)
        Body-to-world quaternions (x, y, z, w), Z-up world.
    tracked : ndarray (b, n) of bool
    mean_marker_error : ndarray (b, n)
        [m], NaN when unknown.
    name : str
        Recording name (take name or file stem).
    meta : dict
        Free-form metadata (rate, units, source file...).
    """

    t: np.ndarray
    frame: np.ndarray
    bodies: list[str]
    position: np.ndarray
    quat: np.ndarray
    tracked: np.ndarray
    mean_marker_error: np.ndarray
    name: str = ""
    meta: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        """Number of frames."""
        return int(self.t.shape[0])

    @property
    def rate_hz(self) -> float:
        """Frame rate [Hz] measured from the frames (:func:`euc_ros.core.mocap.rate.measured_rate_hz`).

        The analysis uses this, not a rate a header or session states: the file's stated rate
        (``meta["rate_hz"]``) is returned only when the frames agree with it within 0.1 % (stamps
        carry round-off; the exact nominal value keeps window lengths in samples reproducible), and
        with fewer than two frames.
        """
        rate = self._measured_rate()
        stated = float(self.meta["rate_hz"]) if "rate_hz" in self.meta else float("nan")
        if np.isfinite(stated) and stated > 0 and (not np.isfinite(rate) or abs(rate / stated - 1.0) <= 1e-3):
            return stated
        return rate

    def _measured_rate(self) -> float:
        """:func:`measured_rate_hz` of the frames, kept for the arrays it was measured on.

        The analyses ask for the rate many times; a series given other ``t`` or ``frame`` arrays is measured
        again.
        """
        kept = self.__dict__.get("_rate_of")
        if kept is not None and kept[0] is self.t and kept[1] is self.frame:
            return kept[2]
        rate = measured_rate_hz(self.t, self.frame) if self.n_frames > 1 else float("nan")
        self.__dict__["_rate_of"] = (self.t, self.frame, rate)
        return rate

    def index(self, body: str) -> int:
        """The row of ``body``; InputError naming the body and the recording if absent.

        Parameters
        ----------
        body : str
            Body name.

        Returns
        -------
        int
            Its row.

        Raises
        ------
        InputError
            When the recording has no such body.
        """
        try:
            return self.bodies.index(body)
        except ValueError:
            raise InputError(f"rigid body {body!r} not in recording (has: {', '.join(self.bodies)})",
                             path=self.meta.get("path", self.name or None)) from None

    def select(self, bodies: list[str], *, missing_ok: bool = False) -> "MocapSeries":
        """A series with only ``bodies`` in that order (absent ones all-NaN if ``missing_ok``).

        Parameters
        ----------
        bodies : list of str
            Body names, in the order wanted.
        missing_ok : bool
            Give absent bodies all-NaN rows instead of raising.

        Returns
        -------
        MocapSeries
            The selection (copies).

        Raises
        ------
        InputError
            When a body is absent and not ``missing_ok``.
        """
        b, n = len(bodies), self.n_frames
        pos = np.full((b, n, 3), np.nan)
        quat = np.full((b, n, 4), np.nan)
        trk = np.zeros((b, n), bool)
        err = np.full((b, n), np.nan)
        for i, name in enumerate(bodies):
            if name not in self.bodies and missing_ok:
                continue
            j = self.index(name)
            pos[i], quat[i], trk[i], err[i] = self.position[j], self.quat[j], self.tracked[j], self.mean_marker_error[j]
        return MocapSeries(self.t, self.frame, list(bodies), pos, quat, trk, err, self.name, dict(self.meta))
