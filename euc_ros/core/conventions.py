"""Conventions of a recording checked against the data (world up axis, units)."""
from __future__ import annotations


def check_conventions(series, session, path=None) -> list[str]:
    """Return warnings about the recording's conventions against the session (errors raise)."""
    return []
