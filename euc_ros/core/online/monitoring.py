"""Health rules of the ``monitor`` node (ROS-free): what a rider-assist or lab operator must see.

The monitor turns the pipeline's streams into a few statuses, each a :class:`Health` (a level, a
one-line message and key/value pairs) computed by a pure function of measured values and configured
limits:

=====================  =====================================================  ==========================
status                 rule                                                   levels
=====================  =====================================================  ==========================
mocap                  arrival rate against ``expected_rate_hz``; share of     WARN below (1 - tol) x
                       frames missing from the frame numbering (dropouts);     rate, ERROR below half;
                       bodies untracked in the window                          WARN above the dropout /
                                                                              untracked share, ERROR
                                                                              above 10x the dropout one
model consistency      sliding-window RMSE of M_d1 - M_d2 (EUC paper, eqs      WARN above the threshold,
                       (9)-(10)) against ``rmse_threshold_nm``: a rising       ERROR above twice it
                       residual means the model no longer explains the ride
rider lean             peak abs(phi) since the last report vs ``max_phi``      WARN above ``warn_fraction``
EUC attitude           peak abs(gamma) vs ``max_gamma``, abs(theta) vs         of a limit, ERROR above
                       ``max_tilt``                                            the limit
motor torque           peak abs(M_d1) vs ``motor_limit_nm``
any                    no message for longer than ``timeout_s``                STALE
=====================  =====================================================  ==========================

Peaks (not the latest values) are compared with the limits, so a short excursion between two reports
is not missed. Angles are radians in code; messages and values give degrees (reports).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

#: Levels, equal to ``diagnostic_msgs/DiagnosticStatus`` (OK, WARN, ERROR, STALE).
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR", STALE: "STALE"}
#: An error in the dropout share is this many times its warning threshold.
DROPOUT_ERROR_FACTOR = 10.0
#: A rate below this fraction of the expected one is an error.
RATE_ERROR_FRACTION = 0.5


@dataclass(frozen=True)
class Health:
    """One status: level (OK/WARN/ERROR/STALE), one-line message, key/value pairs (SI; angles in deg).

    Parameters
    ----------
    level : int
        ``OK``, ``WARN``, ``ERROR`` or ``STALE``.
    message : str
        One-line summary.
    values : dict
        Key/value pairs (SI; angles in deg).
    """

    level: int
    message: str
    values: dict = field(default_factory=dict)


def _worst(levels: Sequence[int]) -> int:
    """Most severe level (STALE only when nothing else is wrong: it is 'unknown', not 'bad')."""
    real = [lv for lv in levels if lv != STALE]
    if real and max(real) > OK:
        return max(real)
    return STALE if STALE in levels else OK


def stale_health(age_s: float | None, timeout_s: float, what: str) -> Health | None:
    """STALE when nothing has arrived (``age_s`` None) or the last message is older than ``timeout_s``.

    Returns None while the stream is fresh.

    Parameters
    ----------
    age_s : float or None
        Time since the last message [s]; None when none arrived.
    timeout_s : float
        Age beyond which the stream is stale [s].
    what : str
        What the stream carries, for the message.

    Returns
    -------
    Health or None
        The STALE status, or None while fresh.
    """
    if age_s is None:
        return Health(STALE, f"no {what} yet", {"age_s": float("nan"), "timeout_s": float(timeout_s)})
    if age_s > timeout_s:
        return Health(STALE, f"no {what} for {age_s:.1f} s", {"age_s": float(age_s), "timeout_s": float(timeout_s)})
    return None


class StreamWindow:
    """Arrivals of the mocap stream over the last ``window_s`` seconds: rate, dropouts, tracking.

    Parameters
    ----------
    window_s : float
        Length of the sliding window [s] (receive time).

    Notes
    -----
    A frame number that skips ahead counts the skipped numbers as missing frames (dropouts); one that
    goes back (a restarted source) or is unknown (``-1``) counts nothing.
    """

    def __init__(self, window_s: float = 2.0) -> None:
        if not window_s > 0:
            raise ValueError("window_s must be > 0")
        self.window_s = float(window_s)
        self._items: deque = deque()          # (arrival [s], missing before it, untracked body names)
        self._last_frame: int | None = None
        self._last_arrival: float | None = None
        self.total_frames = 0
        self.total_missing = 0
        self.restarts = 0

    def push(self, now_s: float, frame_number: int = -1, bodies: Sequence[str] = (),
             tracked: Sequence[bool] = ()) -> None:
        """Record one frame that arrived at ``now_s`` [s].

        Parameters
        ----------
        now_s : float
            Arrival time [s].
        frame_number : int
            Frame number; negative for none (no dropout count).
        bodies : sequence of str
            Body names of the frame.
        tracked : sequence of bool
            Whether each body was tracked.
        """
        missing = 0
        f = int(frame_number)
        if f >= 0 and self._last_frame is not None:
            if f > self._last_frame + 1:
                missing = f - self._last_frame - 1
            elif f <= self._last_frame:
                self.restarts += f < self._last_frame
        if f >= 0:
            self._last_frame = f
        lost = tuple(b for b, ok in zip(bodies, tracked) if not ok)
        self._items.append((float(now_s), missing, lost))
        self._last_arrival = float(now_s)
        self.total_frames += 1
        self.total_missing += missing
        self._trim(now_s)

    def _trim(self, now_s: float) -> None:
        while self._items and self._items[0][0] <= now_s - self.window_s:
            self._items.popleft()

    def age(self, now_s: float) -> float | None:
        """Time since the last frame [s] (None before the first).

        Parameters
        ----------
        now_s : float
            Current time [s].

        Returns
        -------
        float or None
            The age [s].
        """
        return None if self._last_arrival is None else float(now_s - self._last_arrival)

    def stats(self, now_s: float) -> dict:
        """Rate [Hz], dropouts and untracked shares over the window ending at ``now_s``.

        Parameters
        ----------
        now_s : float
            Current time [s]: the window's end.

        Returns
        -------
        dict
            ``frames`` (in the window), ``rate_hz`` (``(n - 1) / span`` of their arrivals, NaN with fewer
            than 2), ``missing`` and ``dropout_fraction`` (missing / (received + missing)),
            ``untracked`` (body -> share of the window's frames it was untracked in), and the totals.
        """
        self._trim(now_s)
        n = len(self._items)
        rate = float("nan")
        if n >= 2:
            span = self._items[-1][0] - self._items[0][0]
            rate = (n - 1) / span if span > 0 else float("inf")
        # the first frame's gap lies before the window
        missing = sum(m for _, m, _ in list(self._items)[1:]) if n else 0
        untracked: dict[str, float] = {}
        for _, _, lost in self._items:
            for b in lost:
                untracked[b] = untracked.get(b, 0.0) + 1.0
        untracked = {b: c / n for b, c in untracked.items()}
        return {"frames": n, "rate_hz": rate, "missing": int(missing),
                "dropout_fraction": missing / (n + missing) if n + missing else 0.0, "untracked": untracked,
                "total_frames": self.total_frames, "total_missing": self.total_missing, "restarts": self.restarts}


def mocap_health(stats: dict, expected_rate_hz: float, *, rate_tolerance: float = 0.1,
                 max_dropout_fraction: float = 0.01, max_untracked_fraction: float = 0.1) -> Health:
    """Rate, dropouts and tracking of the mocap stream (see the module table).

    Parameters
    ----------
    stats : dict
        :meth:`StreamWindow.stats`.
    expected_rate_hz : float
        Nominal frame rate [Hz].
    rate_tolerance : float
        Allowed relative shortfall of the rate before a warning.
    max_dropout_fraction : float
        Share of missing frames before a warning (ERROR at 10x).
    max_untracked_fraction : float
        Share of the window's frames a body may be untracked in before a warning.

    Returns
    -------
    Health
        OK, WARN or ERROR with the problems found.
    """
    levels, problems = [OK], []
    rate = float(stats["rate_hz"])
    if math.isfinite(rate) and expected_rate_hz > 0:
        if rate < RATE_ERROR_FRACTION * expected_rate_hz:
            levels.append(ERROR)
            problems.append(f"rate {rate:.1f} Hz < {RATE_ERROR_FRACTION:g} x {expected_rate_hz:g} Hz")
        elif rate < (1.0 - rate_tolerance) * expected_rate_hz:
            levels.append(WARN)
            problems.append(f"rate {rate:.1f} Hz below {expected_rate_hz:g} Hz")
    drop = float(stats["dropout_fraction"])
    if drop > DROPOUT_ERROR_FACTOR * max_dropout_fraction:
        levels.append(ERROR)
        problems.append(f"{100 * drop:.1f} % of frames dropped")
    elif drop > max_dropout_fraction:
        levels.append(WARN)
        problems.append(f"{100 * drop:.1f} % of frames dropped")
    lost = sorted(b for b, share in stats["untracked"].items() if share > max_untracked_fraction)
    if lost:
        levels.append(WARN)
        problems.append("untracked: " + ", ".join(lost))
    values = {"rate_hz": rate, "expected_rate_hz": float(expected_rate_hz), "frames_in_window": stats["frames"],
              "dropped_in_window": stats["missing"], "dropout_fraction": drop,
              "untracked_bodies": ",".join(lost) or "-", "total_frames": stats["total_frames"],
              "total_dropped": stats["total_missing"], "restarts": stats["restarts"]}
    level = max(levels)
    message = "; ".join(problems) if problems else f"{rate:.1f} Hz, no dropouts"
    return Health(level, message, values)


def consistency_health(rmse_nm: float, threshold_nm: float, *, residual_nm: float = float("nan"),
                       h_online_m: float = float("nan"), h_online_std_m: float = float("nan"),
                       model: str = "") -> Health:
    """Model consistency: the sliding-window RMSE of ``M_d1 - M_d2`` [N m] against ``threshold_nm``.

    WARN above the threshold, ERROR above twice it; WARN when the window holds no finite residual.

    Parameters
    ----------
    rmse_nm : float
        Sliding-window RMSE of ``M_d1 - M_d2`` [N m].
    threshold_nm : float
        RMSE above which the model is inconsistent [N m].
    residual_nm : float
        Latest ``M_d1 - M_d2`` [N m], reported.
    h_online_m, h_online_std_m : float
        Online h estimate and its standard deviation [m], reported.
    model : str
        Model label, reported.

    Returns
    -------
    Health
        OK, WARN or ERROR.
    """
    values = {"rmse_window_nm": float(rmse_nm), "threshold_nm": float(threshold_nm),
              "residual_nm": float(residual_nm), "h_online_m": float(h_online_m),
              "h_online_std_m": float(h_online_std_m), "model": model or "-"}
    if not math.isfinite(rmse_nm):
        return Health(WARN, "no finite residual in the window", values)
    if rmse_nm > 2.0 * threshold_nm:
        return Health(ERROR, f"RMSE(M_d1 - M_d2) {rmse_nm:.2f} N m > 2 x {threshold_nm:g} N m: "
                             "the model does not explain the ride", values)
    if rmse_nm > threshold_nm:
        return Health(WARN, f"RMSE(M_d1 - M_d2) {rmse_nm:.2f} N m > {threshold_nm:g} N m", values)
    return Health(OK, f"RMSE(M_d1 - M_d2) {rmse_nm:.2f} N m", values)


@dataclass(frozen=True)
class Limit:
    """One quantity against its limit: ``label``, peak magnitude, limit (same unit), unit for the text.

    Parameters
    ----------
    label : str
        Name of the quantity.
    peak : float
        Peak value since the last report (signed; compared by magnitude); NaN for none.
    limit : float
        Limit of its magnitude (same unit).
    unit : str
        Unit for the text.
    latest : float
        Latest value, reported.
    """

    label: str
    peak: float
    limit: float
    unit: str = ""
    latest: float = float("nan")


def limits_health(limits: Sequence[Limit], *, warn_fraction: float = 0.8, missing: str = "no value") -> Health:
    """Peak magnitudes against limits: WARN above ``warn_fraction`` x limit, ERROR above the limit.

    A quantity whose peak is NaN (no finite value since the last report) gives WARN with ``missing``.

    Parameters
    ----------
    limits : sequence of Limit
        The quantities.
    warn_fraction : float
        Fraction of a limit above which a peak warns.
    missing : str
        Message of a quantity without a finite peak.

    Returns
    -------
    Health
        OK, WARN or ERROR, with each quantity's peak, latest and limit in ``values``.
    """
    levels, problems, values = [OK], [], {}
    for q in limits:
        key = q.label.replace(" ", "_")
        values[f"{key}_peak"] = float(q.peak)
        values[f"{key}_latest"] = float(q.latest)
        values[f"{key}_limit"] = float(q.limit)
        if not math.isfinite(q.peak):
            levels.append(WARN)
            problems.append(f"{q.label}: {missing}")
        elif abs(q.peak) > q.limit:
            levels.append(ERROR)
            problems.append(f"|{q.label}| {abs(q.peak):.1f} {q.unit} > limit {q.limit:g} {q.unit}".replace("  ", " "))
        elif abs(q.peak) > warn_fraction * q.limit:
            levels.append(WARN)
            problems.append(f"|{q.label}| {abs(q.peak):.1f} {q.unit} near limit {q.limit:g} {q.unit}"
                            .replace("  ", " "))
    if problems:
        return Health(max(levels), "; ".join(problems), values)
    text = ", ".join(f"|{q.label}| {abs(q.peak):.1f} {q.unit}".rstrip() for q in limits)
    return Health(OK, text + " within limits", values)


class PeakAbs:
    """Largest magnitude, latest value and counts of a signal since the last :meth:`take`.

    NaN values are counted but never become the peak.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Start a new reporting period."""
        self.peak = float("nan")
        self.latest = float("nan")
        self.count = 0
        self.nan_count = 0

    def push(self, value: float) -> None:
        """Add one value.

        Parameters
        ----------
        value : float
            The value (NaN counted, not compared).
        """
        v = float(value)
        self.count += 1
        self.latest = v
        if not math.isfinite(v):
            self.nan_count += 1
            return
        if not math.isfinite(self.peak) or abs(v) > abs(self.peak):
            self.peak = v

    def take(self) -> tuple[float, float, int, int]:
        """``(peak, latest, count, nan_count)`` of the period, which starts anew (peak keeps its sign).

        Returns
        -------
        peak : float
            Value of largest magnitude (NaN when none was finite).
        latest : float
            Last value.
        count, nan_count : int
            Values added, and how many were not finite.
        """
        out = (self.peak, self.latest, self.count, self.nan_count)
        self.reset()
        return out


def degrees(x: float) -> float:
    """Radians -> degrees for reports (NaN stays NaN).

    Parameters
    ----------
    x : float
        Angle [rad].

    Returns
    -------
    float
        Angle [deg].
    """
    return float(np.degrees(x))
