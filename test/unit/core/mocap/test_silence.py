"""Stream silence (euc_ros.core.mocap.silence), with time as an argument."""
from __future__ import annotations

import pytest

from euc_ros.core.mocap.silence import SilenceWatch


def test_silence_warns_after_the_delay_repeats_and_reports_the_return():
    w = SilenceWatch(3.0, 10.0)
    assert w.check(1.0) is None                             # not started
    w.start(0.0)
    assert w.check(2.9) is None
    assert w.check(3.0) == pytest.approx(3.0)
    assert w.check(5.0) is None and w.check(12.9) is None   # throttled
    assert w.check(13.0) == pytest.approx(13.0)
    assert w.data(14.0) == pytest.approx(14.0)              # back after a warned silence: news
    assert w.data(14.1) is None and w.check(16.0) is None
    assert w.check(17.2) == pytest.approx(3.1)              # a new silence


def test_first_data_is_news_even_without_a_warning():
    w = SilenceWatch(3.0, 10.0)
    w.start(10.0)
    assert w.data(10.5) == pytest.approx(0.5)
    assert w.data(10.6) is None and w.check(11.0) is None
