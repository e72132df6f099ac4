"""Which needed rigid bodies a live stream is missing, by name (euc_ros.core.mocap.presence)."""
from __future__ import annotations

from euc_ros.core.mocap.presence import BodyPresence


def test_nothing_missing_reports_nothing():
    p = BodyPresence(["E", "H"])
    for _ in range(3):
        p.update(["E", "H", "X"], [True, True, False])  # an unneeded body's loss is not reported
    assert p.missing_bodies() == []
    assert p.report() == ""


def test_report_names_the_most_missing_first_with_hand_computed_shares():
    p = BodyPresence(["E", "H", "CHL"])
    # 8 frames: CHL never present, H untracked in 2 frames, E absent from the frame list in 1
    for k in range(8):
        bodies = ["E", "H"] if k != 5 else ["H"]
        tracked = [True, k not in (1, 2)] if k != 5 else [True]
        p.update(bodies, tracked)
    assert p.missing == {"E": 1, "H": 2, "CHL": 8}
    assert p.missing_bodies() == ["CHL", "H", "E"]
    # 8/8 = 100 %, 2/8 = 25 %, 1/8 = 12.5 % -> "12" (format .0f, round half to even)
    assert p.report() == "no pose for CHL (100 % of 8 frames), H (25 %), E (12 %)"
    assert p.last_missing == ["CHL", "H", "E"]


def test_report_resets_the_counts():
    p = BodyPresence(["E"])
    p.update([], [])
    assert p.report() == "no pose for E (100 % of 1 frames)"
    assert p.frames == 0 and p.missing == {"E": 0}
    assert p.report() == ""
    assert p.last_missing == []
    p.update(["E"], [True])
    p.update(["E"], [False])
    assert p.report() == "no pose for E (50 % of 2 frames)"


def test_needed_names_are_deduplicated_in_order():
    p = BodyPresence(["H", "E", "H"])
    assert p.needed == ["H", "E"]
    p.update(["E"], [True])
    assert p.report() == "no pose for H (100 % of 1 frames)"


def test_a_body_tracked_under_one_entry_counts_as_present():
    p = BodyPresence(["E"])
    p.update(["E", "E"], [False, True])  # zip over names and flags: one tracked entry is enough
    assert p.missing_bodies() == []
