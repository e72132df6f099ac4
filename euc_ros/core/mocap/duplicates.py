"""One take given twice (its Motive export and the bag converted from it, side by side in a session folder).

Analysed twice, a take would count double in every fit and its blocks would narrow the intervals as if they
were independent data. :class:`TakeIndex` remembers a small fingerprint of each recording it is shown (the
frame span, the bodies and three rows of positions) and names an earlier recording that holds the same take.
"""
from __future__ import annotations

import numpy as np

#: Positions of one take in two files agree to the export's rounding (Motive writes 6 decimals of a metre);
#: two different takes with the same frame span and bodies differ by far more [m].
SAME_TAKE_TOL_M = 1e-5


def _fingerprint(series) -> tuple:
    n = int(np.size(series.frame))
    rows = np.unique([0, n // 2, max(n - 1, 0)]) if n else np.zeros(0, int)
    key = (n, int(series.frame[0]) if n else 0, int(series.frame[-1]) if n else 0, tuple(series.bodies))
    return key, np.asarray(series.position)[:, rows, :].copy()


class TakeIndex:
    """The recordings seen so far, by fingerprint."""

    def __init__(self) -> None:
        self._seen: list[tuple[tuple, np.ndarray, str]] = []

    def same_as(self, series, name: str) -> str | None:
        """The name of an earlier recording holding the same take as ``series``.

        None: a new take, now remembered as ``name``.

        Parameters
        ----------
        series : MocapSeries
            The recording.
        name : str
            Its name.

        Returns
        -------
        str or None
            The earlier recording's name, or None.
        """
        key, rows = _fingerprint(series)
        for k, r, other in self._seen:
            if k == key and r.shape == rows.shape:
                both = np.isfinite(r) & np.isfinite(rows)
                if np.array_equal(np.isfinite(r), np.isfinite(rows)) and \
                        np.all(np.abs(r[both] - rows[both]) <= SAME_TAKE_TOL_M):
                    return other
        self._seen.append((key, rows, name))
        return None
