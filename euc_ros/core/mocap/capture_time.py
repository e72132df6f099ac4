"""Motive's ``Capture Start Time``.

:func:`capture_start_ns` / :func:`format_capture_start` convert its text to nanoseconds since the epoch and
back (offline stamps are ``start + frame / rate``).
"""
from __future__ import annotations

import calendar
import re
import time as _time

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

    Parameters
    ----------
    ns : int
        Time since the epoch, UTC [ns].

    Returns
    -------
    str
        The time as Motive writes it.
    """
    ns = (int(ns) + 500_000) // 1_000_000 * 1_000_000
    seconds, rest = divmod(ns, 1_000_000_000)
    st = _time.gmtime(seconds)
    hour12 = st.tm_hour % 12 or 12
    marker = "PM" if st.tm_hour >= 12 else "AM"
    return (f"{st.tm_year:04d}-{st.tm_mon:02d}-{st.tm_mday:02d} {hour12:02d}.{st.tm_min:02d}.{st.tm_sec:02d}."
            f"{rest // 1_000_000:03d} {marker}")
