"""Start once the wanted DDS endpoints have matched, and a little later (discovery is asymmetric).

A node that must not lose its first messages (a replay, a lockstep simulation, its controller) waits
until its own publishers and subscriptions have matched the peers it needs. Counts are DDS matches of
the node's own endpoints, not graph entries: a subscriber listed in the graph may not be matched yet.
Matched on one side is not yet matched on the other, hence :data:`SETTLE_S` more.
"""
from __future__ import annotations

from typing import Callable, Iterable

#: Wait after the wanted endpoints matched before starting [s].
SETTLE_S = 0.3


class MatchGate:
    """Whether every wanted match is there, and :data:`SETTLE_S` has passed since they all were.

    Parameters
    ----------
    wants : callable
        ``wants()`` -> ``[(what, have, need), ...]``, e.g. ``("unicycle/state subscriptions",
        pub.get_subscription_count(), 1)``.
    settle_s : float
        Wait after the matches [s].
    """

    def __init__(self, wants: Callable[[], Iterable[tuple[str, int, int]]], settle_s: float = SETTLE_S) -> None:
        self.wants = wants
        self.settle_s = float(settle_s)
        self.matched_at: float | None = None

    def missing(self) -> list[str]:
        """What is still missing, as ``"<what> <have>/<need>"``."""
        return [f"{what} {have}/{need}" for what, have, need in self.wants() if have < need]

    def ready(self, now: float, on_missing: Callable[[list[str]], None] | None = None) -> bool:
        """True once everything matched and ``settle_s`` passed (monotonic ``now`` [s]).

        ``on_missing(missing)`` is called while something is missing.
        """
        if self.matched_at is None:
            missing = self.missing()
            if missing:
                if on_missing is not None:
                    on_missing(missing)
                return False
            self.matched_at = now
        return now >= self.matched_at + self.settle_s
