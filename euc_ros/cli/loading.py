"""What the offline commands print of their recordings: the CoG line, the warnings, the progress bar.

Reading and reconstruction live in :mod:`euc_ros.core.states.load`.
"""
from __future__ import annotations

import sys
from typing import Callable, Iterable, Sequence


def progress_bar(desc: str, enabled: bool = True) -> Callable[[Sequence], Iterable] | None:
    """A tqdm bar over recordings for :func:`~euc_ros.core.states.load.load_states`'s ``progress``.

    No bar on a non-terminal stderr, none for fewer than two recordings, and none for work that ends (or
    fails) within 0.5 s, so a refusal stays one line. None when not ``enabled``.
    """
    if not enabled:
        return None

    def bar(paths: Sequence) -> Iterable:
        from tqdm import tqdm

        return tqdm(paths, desc=desc, unit="rec", file=sys.stderr, delay=0.5, disable=True if len(paths) < 2 else None)

    return bar


def format_cog_faults(info: dict) -> str:
    """One line: the CoG method and, for the skeleton, the bodies excluded from G."""
    if info["cog_method"] != "skeleton":
        return "rider CoG: per-segment centres of mass (no swap/flip detection)"
    bodies = ", ".join(f"{k} {v}" for k, v in sorted(info["per_body"].items())) or "none"
    return (f"rider CoG: fitted skeleton; body-frames excluded from G (swapped or flipped): "
            f"{info['excluded_body_frames']} ({bodies})")


def print_warnings(warnings, file=None) -> None:
    """Print warnings as ``warning: ...`` lines on stderr."""
    for w in warnings:
        print(f"warning: {w}", file=file or sys.stderr)
