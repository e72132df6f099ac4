"""Which rigid bodies a live stream is missing: what the nodes name in their diagnostics.

A node that needs bodies (``rider_state``: the EUC body and every rider segment with mass) counts,
per diagnostics period, the frames in which each needed body was absent or untracked, and reports
them by name: "no pose for CHL (100 % of 120 frames), E (8 %)". Without this, a state without phi or
a missing torque says that something is wrong, not what.
"""
from __future__ import annotations

from typing import Iterable, Sequence


class BodyPresence:
    """Count, per needed body, the frames it was missing since the last report.

    Parameters
    ----------
    needed : sequence of str
        Body names the consumer needs.

    Examples
    --------
    >>> p = BodyPresence(["E", "H"])
    >>> for k in range(4):
    ...     p.update(["E", "H"], [True, k % 2 == 0])
    >>> p.report()
    'no pose for H (50 % of 4 frames)'
    >>> p.report()   # nothing since
    ''
    """

    def __init__(self, needed: Sequence[str]) -> None:
        self.needed = list(dict.fromkeys(needed))
        self.frames = 0
        self.missing = {b: 0 for b in self.needed}
        self.last_missing: list[str] = []

    def update(self, bodies: Sequence[str], tracked: Iterable[bool]) -> None:
        """Add one frame: the names of its bodies and whether each is tracked.

        Parameters
        ----------
        bodies : sequence of str
            Body names of the frame.
        tracked : iterable of bool
            Whether each is tracked.
        """
        present = {b for b, ok in zip(bodies, tracked) if ok}
        self.frames += 1
        for b in self.needed:
            if b not in present:
                self.missing[b] += 1

    def missing_bodies(self) -> list[str]:
        """Needed bodies missing in at least one frame since the last report, most missing first.

        Returns
        -------
        list of str
            The body names.
        """
        return sorted((b for b, n in self.missing.items() if n), key=lambda b: -self.missing[b])

    def report(self) -> str:
        """One line naming the missing bodies with their share of frames ('' when none); resets the counts.

        Returns
        -------
        str
            The line, or ``""``.
        """
        names = self.missing_bodies()
        self.last_missing = names
        text = ""
        if names and self.frames:
            text = "no pose for " + ", ".join(f"{b} ({100 * self.missing[b] / self.frames:.0f} % of "
                                               f"{self.frames} frames)" if i == 0 else
                                               f"{b} ({100 * self.missing[b] / self.frames:.0f} %)"
                                               for i, b in enumerate(names))
        self.frames = 0
        self.missing = {b: 0 for b in self.needed}
        return text
