"""Shared fixtures of the node tests: ``ride`` and ``pipes``, from the node tests' helpers (helpers.py).

``ride`` is a module fixture (a 4 s deceleration run with losses, written once per test module);
``pipes(nodes)`` makes a :class:`Pipe` of the nodes under test, closed after the test.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

from euc_ros.testing import load_module

if importlib.util.find_spec("rclpy") is not None:      # without rclpy the node tests skip themselves
    _helpers = load_module(Path(__file__).with_name("helpers.py"), "node_helpers_fixtures")
    ride = _helpers.ride
    pipes = _helpers.pipes

#: helpers.py is not a test file, and pytest's --doctest-modules would import it even without rclpy
collect_ignore = ["helpers.py"]
