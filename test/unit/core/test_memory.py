"""Giving freed memory back to the operating system (euc_ros.core.memory)."""
from __future__ import annotations

import numpy as np

from euc_ros.core import memory


def test_release_returns_a_bool_and_changes_no_array():
    a = np.arange(1000, dtype=float)
    big = [np.ones(500_000) for _ in range(20)]  # ~80 MB of temporaries, then freed
    del big
    assert isinstance(memory.release_free_memory(), bool)
    np.testing.assert_array_equal(a, np.arange(1000, dtype=float))


def test_without_malloc_trim_nothing_is_released(monkeypatch):
    monkeypatch.setattr(memory, "_malloc_trim", lambda: None)
    assert memory.release_free_memory() is False


def test_the_trim_result_is_passed_through_with_a_zero_pad(monkeypatch):
    calls = []

    def trim(pad):
        calls.append(pad)
        return 1

    monkeypatch.setattr(memory, "_malloc_trim", lambda: trim)
    assert memory.release_free_memory() is True
    assert calls == [0]
    monkeypatch.setattr(memory, "_malloc_trim", lambda: lambda pad: 0)
    assert memory.release_free_memory() is False
