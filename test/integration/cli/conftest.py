"""Fixtures of the end-to-end command runs, shared with the core tests: ``symbolic`` and ``synth`` (the EUC
model's independent derivation, test/unit/core/conftest.py) and ``params`` (the unicycle's Table I,
test/unit/core/unicycle/conftest.py).

These tests run ``euc_ros.cli.main.main(argv)`` in process, on simulated rides: no ROS graph, so
test/conftest.py spreads them over the workers file by file, as the unit tests.
"""
from __future__ import annotations

from pathlib import Path

from euc_ros.testing import load_module

CORE_TESTS = Path(__file__).resolve().parents[2] / "unit" / "core"

_core = load_module(CORE_TESTS / "conftest.py", "core_fixtures")
symbolic = _core.symbolic
synth = _core.synth
params = load_module(CORE_TESTS / "unicycle" / "conftest.py", "unicycle_fixtures").params
