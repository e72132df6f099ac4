"""Motive's Capture Start Time, read and written (euc_ros.core.mocap.capture_time)."""
from datetime import datetime, timezone

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from euc_ros.core.mocap.capture_time import capture_start_ns, format_capture_start

MS = 1_000_000


def _utc_ns(*args) -> int:
    *whole, ms = args
    return int(datetime(*whole, tzinfo=timezone.utc).timestamp()) * 10**9 + ms * MS


@pytest.mark.parametrize("text, expected", [
    ("2024-05-02 10.15.00.000 AM", _utc_ns(2024, 5, 2, 10, 15, 0, 0)),
    ("2020-06-16 07.51.41.245 PM", _utc_ns(2020, 6, 16, 19, 51, 41, 245)),     # real export (rbm)
    ("2023-11-28 10.27.58.765 DU.", _utc_ns(2023, 11, 28, 22, 27, 58, 765)),   # Hungarian "du." = PM (ha5dzs)
    ("2020-01-16 07.07.59.330 ", _utc_ns(2020, 1, 16, 7, 7, 59, 330)),         # no marker (grvc)
    ("2020-01-16 12.30.00.000 AM", _utc_ns(2020, 1, 16, 0, 30, 0, 0)),
    ("2020-01-16 12.30.00.000 PM", _utc_ns(2020, 1, 16, 12, 30, 0, 0)),
    ("2020-01-16 19.30.00.5", _utc_ns(2020, 1, 16, 19, 30, 0, 500)),
])
def test_capture_start_time(text, expected):
    assert capture_start_ns(text) == expected


@pytest.mark.parametrize("text", ["", None, "yesterday", "2020-13-01 10.00.00.000", "2020-01-01 25.00.00.000"])
def test_unreadable_capture_start_is_none(text):
    assert capture_start_ns(text) is None


@settings(max_examples=200, deadline=None)
@given(st.integers(min_value=0, max_value=4_000_000_000_000))
def test_capture_start_round_trip_to_the_millisecond(ms):
    ns = ms * MS
    text = format_capture_start(ns)
    assert capture_start_ns(text) == ns
    assert text == datetime.fromtimestamp(ms / 1000, timezone.utc).strftime("%Y-%m-%d %I.%M.%S.") + \
        f"{ms % 1000:03d} " + ("PM" if (ms // 3_600_000) % 24 >= 12 else "AM")


def test_format_capture_start_rounds_to_the_millisecond_with_carry():
    ns = _utc_ns(2021, 12, 31, 23, 59, 59, 999) + 600_000          # 23:59:59.9996 -> next day
    assert format_capture_start(ns) == "2022-01-01 12.00.00.000 AM"
    assert format_capture_start(_utc_ns(2021, 6, 1, 12, 0, 0, 7) + 400_000) == "2021-06-01 12.00.00.007 PM"
