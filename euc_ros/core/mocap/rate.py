"""Frame rate of a recording, measured from its frames, and its agreement with the session.

The analysis runs at the rate the data were captured at, never at a number typed into a file: the
derivative filter's time step is ``1 / measured rate``. A session ``rate_hz`` that disagrees with
the data by more than :data:`RATE_TOLERANCE` is an error offline (:func:`check_rate`) and a
diagnostics ERROR live (:class:`RateMeter`, used by the nodes), both naming the two rates.

Measurement: with frame numbers, the least-squares slope of time against frame number (dropped
frames are skipped numbers, so they do not bias it); without them (topic sources stamped on
arrival), the median stamp spacing. The median per-frame spacing guards the slope against a
recording whose clock jumps (a pause): when the two disagree by more than 1 % the median wins.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from euc_ros.core.errors import ConfigError, InputError

#: Relative disagreement between the session's rate_hz and the measured rate that is an error.
RATE_TOLERANCE = 0.01


def measured_rate_hz(t, frame=None) -> float:
    """Frame rate [Hz] measured from capture times and, where known, frame numbers.

    Parameters
    ----------
    t : array_like (n,)
        Capture times [s].
    frame : array_like of int (n,), optional
        Frame numbers (negative: unknown). Skipped numbers are dropped frames. Without (two or
        more known) frame numbers the median stamp spacing is used.

    Returns
    -------
    float
        The rate [Hz]; NaN with fewer than two usable frames.

    Examples
    --------
    >>> frames = np.array([0, 1, 2, 4, 5, 8])          # frames 3, 6 and 7 dropped
    >>> round(measured_rate_hz(frames / 360.0, frames), 9)
    360.0
    """
    t = np.asarray(t, dtype=float)
    if t.size < 2:
        return math.nan
    k = None if frame is None else np.asarray(frame, dtype=float)
    if k is not None and np.count_nonzero(np.isfinite(t) & (k >= 0)) >= 2:
        ok = np.isfinite(t) & (k >= 0)
        t, k = t[ok], k[ok]
    else:   # no frame numbers (or fewer than two): the stamps alone
        t, k = t[np.isfinite(t)], None
    if t.size < 2:
        return math.nan
    dt = np.diff(t)
    if k is not None:
        dk = np.diff(k)
        use = (dk > 0) & (dt > 0)
        if not use.any():
            return math.nan
        spacing = float(np.median(dt[use] / dk[use]))
        if k[-1] > k[0]:
            kc = k - k.mean()
            slope = float(np.dot(kc, t - t.mean()) / np.dot(kc, kc))
            if slope > 0 and abs(slope / spacing - 1.0) < 0.01:
                spacing = slope
    else:
        use = dt > 0
        if not use.any():
            return math.nan
        spacing = float(np.median(dt[use]))
    return 1.0 / spacing if spacing > 0 else math.nan


def rate_mismatch(measured_hz: float, session_hz: float) -> bool:
    """True when the two rates differ by more than :data:`RATE_TOLERANCE` of the session's.

    Parameters
    ----------
    measured_hz : float
        Measured rate [Hz] (NaN: no mismatch).
    session_hz : float
        The session's rate [Hz].

    Returns
    -------
    bool
        Whether they disagree.
    """
    return bool(math.isfinite(measured_hz) and session_hz > 0
                and abs(measured_hz / session_hz - 1.0) > RATE_TOLERANCE)


def mismatch_message(measured_hz: float, session_hz: float, source: str = "the session") -> str:
    """One line naming both rates and what to do.

    Parameters
    ----------
    measured_hz : float
        Measured rate [Hz].
    session_hz : float
        Stated rate [Hz].
    source : str
        What states it.

    Returns
    -------
    str
        The message.
    """
    return (f"frames are {measured_hz:.4g} Hz apart but {source} says rate_hz = {session_hz:g} Hz "
            f"(more than {RATE_TOLERANCE:.0%} off): set rate_hz: {_suggest(measured_hz)} in the session file "
            f"(or check that this recording belongs to this session)")


def _suggest(rate: float) -> str:
    r = round(rate)
    return f"{r:d}" if abs(rate / r - 1.0) < 2e-3 else f"{rate:.4g}"


def check_rate(series, session, path: str | Path | None = None) -> list[str]:
    """Check the recording's measured frame rate against ``session.rate_hz``.

    Returns warnings (a header rate that disagrees with the frames: the frames are used); raises
    :class:`~euc_ros.core.errors.ConfigError` (key ``rate_hz``, naming both rates) when the session
    disagrees with the data by more than 1 %.

    Parameters
    ----------
    series : MocapSeries
        The recording.
    session : Session
        Gives ``rate_hz``.
    path : str or Path, optional
        File named in errors; default the recording's path or name.

    Returns
    -------
    list of str
        Warnings.

    Raises
    ------
    ConfigError
        The session's rate disagrees with the frames (key ``rate_hz``).
    InputError
        The frame rate cannot be measured (times and frame numbers do not increase).
    """
    where = str(path) if path is not None else (series.meta.get("path") or series.name or None)
    measured = measured_rate_hz(series.t, series.frame)
    if not math.isfinite(measured):
        if series.n_frames > 1:
            raise InputError("cannot measure the frame rate: times and frame numbers do not increase",
                             path=where)
        return []
    if rate_mismatch(measured, float(session.rate_hz)):
        src = getattr(session, "source", None)
        raise ConfigError(mismatch_message(measured, float(session.rate_hz),
                                           f"the session{f' ({src})' if src else ''}"),
                          path=where, key="rate_hz")
    warnings = []
    header = series.meta.get("rate_hz")
    if header is not None and rate_mismatch(measured, float(header)):
        warnings.append(f"{where}: the file says {float(header):g} Hz but its frames are {measured:.4g} Hz "
                        "apart; the analysis uses the measured rate")
    return warnings


class RateMeter:
    """Measure a live stream's frame rate from its first frames (nodes buffer until it is known).

    Parameters
    ----------
    nominal_hz : float
        The configured rate (session ``rate_hz`` or a node parameter).
    min_span_s : float
        Stamps must span at least this long before the rate is decided [s].
    min_frames : int
        ... and at least this many frames.

    Attributes
    ----------
    rate_hz : float or None
        The rate to use once decided: the nominal one when the measurement agrees within 1 %, else
        the measured one.
    measured_hz : float
        The measurement (NaN until decided).
    error : str or None
        The mismatch message (for a diagnostics ERROR) when the stream disagrees with the nominal rate.

    Raises
    ------
    ConfigError
        When the nominal rate is not positive (key ``rate_hz``).

    Examples
    --------
    >>> m = RateMeter(120.0, min_span_s=0.1, min_frames=5)
    >>> [m.add(k, int(k * 1e9 / 240)) for k in range(30)][-1]
    True
    >>> round(m.rate_hz, 6), m.error is not None
    (240.0, True)
    """

    def __init__(self, nominal_hz: float, *, min_span_s: float = 0.3, min_frames: int = 10) -> None:
        if not (math.isfinite(nominal_hz) and nominal_hz > 0):
            raise ConfigError(f"rate_hz must be > 0, got {nominal_hz!r}", key="rate_hz")
        self.nominal_hz = float(nominal_hz)
        self.min_span_s = float(min_span_s)
        self.min_frames = int(min_frames)
        self.rate_hz: float | None = None
        self.measured_hz = math.nan
        self.error: str | None = None
        self._frames: list[int] = []
        self._stamps: list[int] = []

    @property
    def decided(self) -> bool:
        """True once the rate is known."""
        return self.rate_hz is not None

    def restart(self) -> None:
        """Measure again (the source restarted; it may run at another rate)."""
        self.rate_hz = None
        self.measured_hz = math.nan
        self._frames.clear()
        self._stamps.clear()

    def add(self, frame_number: int, stamp_ns: int) -> bool:
        """Add one frame (number ``-1`` when unknown); True once the rate is decided.

        Parameters
        ----------
        frame_number : int
            Frame number; -1 when unknown.
        stamp_ns : int
            Frame stamp [ns]; a stamp not after the last is ignored.

        Returns
        -------
        bool
            Whether the rate is decided.
        """
        if self.decided:
            return True
        if self._stamps and int(stamp_ns) <= self._stamps[-1]:
            return False   # repeated / out of order: the sequencer drops it later
        self._frames.append(int(frame_number))
        self._stamps.append(int(stamp_ns))
        span = (self._stamps[-1] - self._stamps[0]) * 1e-9
        if len(self._stamps) < self.min_frames or span < self.min_span_s:
            return False
        self.decide()
        return True

    def decide(self) -> float:
        """Decide the rate from the frames seen so far (the nominal one with fewer than three).

        Returns
        -------
        float
            The rate used [Hz]: the measured one when it disagrees with the nominal one, else the nominal.
        """
        if self.decided:
            return self.rate_hz
        if len(self._stamps) < 3:
            self.rate_hz, self.error = self.nominal_hz, None
            return self.rate_hz
        t = (np.asarray(self._stamps, dtype=np.int64) - self._stamps[0]) * 1e-9
        k = np.asarray(self._frames)
        numbered = bool(np.all(k >= 0) and np.all(np.diff(k) > 0))
        self.measured_hz = measured_rate_hz(t, k if numbered else None)
        if rate_mismatch(self.measured_hz, self.nominal_hz):
            self.rate_hz = self.measured_hz
            self.error = mismatch_message(self.measured_hz, self.nominal_hz, "the configuration")
        else:
            self.rate_hz = self.nominal_hz
            self.error = None
        return self.rate_hz


class RateGate:
    """Hold a live stream's first items until its rate is measured, then release them in order.

    A node builds its filters only once the rate is known (:attr:`rate_hz`), so no item is
    processed with a wrong time step and none is lost: :meth:`push` returns the items to process
    now (nothing while measuring, then everything held, then each item as it comes).

    Parameters
    ----------
    nominal_hz : float
        The configured rate.
    **meter_options
        ``min_span_s`` and ``min_frames`` of :class:`RateMeter`.

    Examples
    --------
    >>> g = RateGate(100.0, min_span_s=0.02, min_frames=3)
    >>> [g.push(k, k * 10_000_000, f"item{k}") for k in range(4)]
    [[], [], ['item0', 'item1', 'item2'], ['item3']]
    >>> g.rate_hz
    100.0
    """

    def __init__(self, nominal_hz: float, **meter_options) -> None:
        self.meter = RateMeter(nominal_hz, **meter_options)
        self._held: list = []

    @property
    def rate_hz(self) -> float | None:
        """The rate to use (None while measuring)."""
        return self.meter.rate_hz

    @property
    def held(self) -> int:
        """Items waiting for the rate."""
        return len(self._held)

    def push(self, frame_number: int, stamp_ns: int, item) -> list:
        """Add one item with its frame number (``-1``: unknown) and stamp; return those to process now.

        Parameters
        ----------
        frame_number : int
            Frame number; -1 when unknown.
        stamp_ns : int
            Frame stamp [ns].
        item : Any
            What is held until the rate is decided.

        Returns
        -------
        list
            The items to process now, in order.
        """
        if self.meter.decided:
            return [item]
        self._held.append(item)
        if not self.meter.add(frame_number, stamp_ns):
            return []
        out, self._held = self._held, []
        return out

    def flush(self) -> list:
        """Decide the rate from what was seen (the stream paused or ended) and release the held items.

        Returns
        -------
        list
            The items held, in order.
        """
        self.meter.decide()
        out, self._held = self._held, []
        return out
