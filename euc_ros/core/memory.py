"""Giving freed memory back to the operating system between the analyses' large steps.

numpy's arrays of a long recording are a few megabytes each; glibc's allocator serves such sizes from its
heap once a freed one has raised its mmap threshold, and keeps freed heap pages resident. A step that made
and dropped hundreds of megabytes of temporaries (the discovery's columns, a re-noised reconstruction) then
leaves the process that much larger for the rest of the run, and the next step's temporaries stack on top.
:func:`release_free_memory` returns the free pages (glibc ``malloc_trim``: the heap's free top and the
whole free pages inside it) between such steps. It changes no number; elsewhere than glibc it does nothing.

>>> release_free_memory() in (True, False)
True
"""
from __future__ import annotations

import ctypes
import ctypes.util
import functools


@functools.lru_cache(maxsize=1)
def _malloc_trim():
    name = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(name or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


def release_free_memory() -> bool:
    """Release of the allocator's free pages to the operating system (glibc); True when something was released.

    Returns
    -------
    bool
        True when ``malloc_trim`` released memory; False when it did not or is unavailable.
    """
    trim = _malloc_trim()
    return bool(trim(0)) if trim is not None else False
