"""Checks of a recording against its session, run by every offline analysis before any long work.

:func:`check_recording` gathers the independent checks (each in its own module) and returns the
warnings they raise; a contradiction the analysis cannot work around is an error
(:class:`~euc_ros.core.errors.InputError` / :class:`~euc_ros.core.errors.ConfigError`) naming the
file and the session key.
"""
from __future__ import annotations

from pathlib import Path

from euc_ros.core.mocap.length_scale import check_length_scale
from euc_ros.core.mocap.rate import check_rate


def check_recording(series, session, path: str | Path | None = None) -> list[str]:
    """Check a recording against its session.

    Parameters
    ----------
    series : MocapSeries
        The recording as read (Z-up world).
    session : Session
        The session it is analysed with.
    path : str or Path, optional
        Where the recording came from (for messages).

    Returns
    -------
    list of str
        Warnings (the analysis goes on); errors raise.
    """
    from euc_ros.core.mocap.conventions import check_conventions

    warnings: list[str] = []
    warnings += check_length_scale(series, session, path)   # first: a unit slip misleads every other check
    warnings += check_rate(series, session, path)
    warnings += check_conventions(series, session, path)
    return warnings
