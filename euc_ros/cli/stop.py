"""Stopping a long-running command by SIGINT or SIGTERM without an exception in the middle of its work."""
from __future__ import annotations

import signal
import threading


class StopSignals:
    """Within ``with StopSignals() as stop:``, SIGINT and SIGTERM set the event ``stop`` instead of raising.

    The previous handlers come back on exit. The command checks the event between steps.
    """

    def __init__(self) -> None:
        self.event = threading.Event()
        self._old = {}

    def __enter__(self) -> threading.Event:
        for sig in (signal.SIGINT, signal.SIGTERM):
            self._old[sig] = signal.signal(sig, lambda *_: self.event.set())
        return self.event

    def __exit__(self, *exc) -> None:
        for sig, handler in self._old.items():
            signal.signal(sig, handler)
