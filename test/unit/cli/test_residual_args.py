"""``euc-ros residual``'s filter options: a window in seconds (order 6 by default) or ``auto``."""
from __future__ import annotations

import argparse

import pytest

from euc_ros.cli import residual
from euc_ros.core.errors import ConfigError
from euc_ros.core.residual.pipeline import RESIDUAL_SETTINGS
from euc_ros.core.states.settings import ReconstructionSettings


@pytest.fixture
def parser():
    p = argparse.ArgumentParser()
    residual.add_arguments(p)
    return p


def _settings(args):
    return ReconstructionSettings(window_s=args.window_s, polyorder=args.polyorder)


def test_the_default_filter_is_the_residuals(parser):
    s = _settings(parser.parse_args(["s.yaml", "r.csv", "--json", "o.json"]))
    assert (s.window_s, s.polyorder) == (RESIDUAL_SETTINGS.window_s, RESIDUAL_SETTINGS.polyorder)


def test_auto_chooses_window_and_order_from_the_data(parser):
    s = _settings(parser.parse_args(["s.yaml", "r.csv", "--json", "o.json", "--window-s", "AUTO"]))
    assert s.is_auto and s.polyorder is None


def test_an_order_with_auto_is_refused_naming_the_option(parser):
    args = parser.parse_args(["s.yaml", "r.csv", "--json", "o.json", "--window-s", "auto", "--polyorder", "4"])
    with pytest.raises(ConfigError, match="--polyorder"):
        _settings(args)


def test_a_window_that_is_neither_is_a_usage_error(parser):
    with pytest.raises(SystemExit):
        parser.parse_args(["s.yaml", "r.csv", "--json", "o.json", "--window-s", "wide"])
