"""Frame rate of a recording, measured from its frames, and its agreement with the session."""
from __future__ import annotations


def check_rate(series, session, path=None) -> list[str]:
    """Return warnings about the recording's frame rate against ``session.rate_hz`` (errors raise)."""
    return []
