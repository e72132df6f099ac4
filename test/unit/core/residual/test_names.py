"""The ``effect`` string of the residual JSON: library effects vs outcome markers (euc_ros.core.residual.names)."""
from __future__ import annotations

import pytest

from euc_ros.core.residual.names import OUTCOME_MARKERS, has_discovered, library_effects


@pytest.mark.parametrize("effect, expected", [
    ("ground_slope", ["ground_slope"]),
    ("ground_slope+aero_drag", ["ground_slope", "aero_drag"]),          # order kept
    ("aero_drag+ground_slope", ["aero_drag", "ground_slope"]),
    ("ground_slope+unexplained", ["ground_slope"]),
    ("rolling_resistance+discovered", ["rolling_resistance"]),
    (" ground_slope + aero_drag ", ["ground_slope", "aero_drag"]),      # spaces around '+'
    ("ground_slope++aero_drag", ["ground_slope", "aero_drag"]),         # empty parts dropped
    ("none", []),
    ("discovered", []),
    ("unexplained", []),
    ("", []),
])
def test_library_effects_drops_markers_and_keeps_order(effect, expected):
    assert library_effects(effect) == expected


def test_every_outcome_marker_is_dropped_and_only_those():
    assert library_effects("+".join(OUTCOME_MARKERS)) == []
    assert set(OUTCOME_MARKERS) == {"none", "discovered", "unexplained"}


@pytest.mark.parametrize("effect, expected", [
    ("discovered", True),
    ("rolling_resistance+discovered", True),
    ("ground_slope + discovered", True),
    ("ground_slope", False),
    ("none", False),
    ("undiscovered", False),            # a whole part, not a substring
    ("discovered_effect", False),
])
def test_has_discovered_looks_for_the_whole_part(effect, expected):
    assert has_discovered(effect) is expected
