"""Silence of a live stream.

:class:`SilenceWatch` says when a stream has been silent long enough to warn, and when it is back.

Time is always an argument (``now_s``): nothing here reads a clock.
"""
from __future__ import annotations


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
        """Start watching at ``now_s`` [s].

        Parameters
        ----------
        now_s : float
            Current time [s].
        """
        self.started_s = float(now_s)

    def data(self, now_s: float) -> float | None:
        """Data arrived at ``now_s``.

        Returns how long the stream was silent when this is news (the first data, or the first after a warned
        silence) [s], else None.

        Parameters
        ----------
        now_s : float
            Current time [s].

        Returns
        -------
        float or None
            The silence [s], or None.
        """
        since = self.last_data_s if self.last_data_s is not None else self.started_s
        news = not self.ever or self.warned_s is not None
        self.last_data_s = float(now_s)
        self.ever = True
        self.warned_s = None
        if not news:
            return None
        return 0.0 if since is None else max(0.0, float(now_s) - since)

    def check(self, now_s: float) -> float | None:
        """How long the stream has been silent when a warning is due at ``now_s`` [s], else None.

        Parameters
        ----------
        now_s : float
            Current time [s].

        Returns
        -------
        float or None
            The silence [s], or None.
        """
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
