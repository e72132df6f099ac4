"""Shared fixtures of the node tests: ``ride`` and ``pipes`` of the rider_state tests (test_rider_state.py).

``ride`` is a module fixture (a 4 s deceleration run with losses, written once per test module);
``pipes(nodes)`` makes a :class:`Pipe` of the nodes under test, closed after the test.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

from euc_ros.testing import load_module

if importlib.util.find_spec("rclpy") is not None:      # without rclpy the node tests skip themselves
    _rider_state = load_module(Path(__file__).with_name("test_rider_state.py"), "rider_state_fixtures")
    ride = _rider_state.ride
    pipes = _rider_state.pipes
