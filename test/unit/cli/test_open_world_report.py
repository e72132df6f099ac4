"""The open-world report of ``euc-ros campaign open-world``: the table's marks and the report's ride lines."""
from __future__ import annotations

import json
import math
from pathlib import Path

from euc_ros.cli import open_world as report
from euc_ros.core.openworld.judge import summarize


def _rows():
    base = {"status": "ok", "error": None, "artefact_mm": 0.5, "false_name": False, "library_names": [],
            "covered": True, "floor_nm": 1.0, "rmse_before_nm": 2.0, "before_predicted_nm": 2.0, "ratio_design": 0.4,
            "ratio_measured": 0.5, "effect": "none", "discovered_terms": 0, "seconds": 3.0, "h_true_m": 0.6,
            "h_after_m": 0.61, "point": None}
    return [{**base, "task": "none_000000", "family": "none", "explained": None, "width_mm": math.inf},
            {**base, "task": "drift_000000", "family": "drift", "explained": True, "width_mm": 12.0,
             "point": json.dumps({"kind": "cog_z"}), "effect": "rider_mass_error",
             "library_names": ["rider_mass_error"]},
            {**base, "task": "drift_000001", "family": "drift", "status": "failed", "error": "ConfigError: falls"}]


def test_table_marks_the_goals_and_unbounded_widths():
    lines = report.table_lines(summarize(_rows()))
    # the control's unbounded interval: a miss, and the widths' goals missed
    assert lines[2].startswith("| none | 1 (0) | - | - | 0 % ✓ | 100 % ✓ | 100 % ✓ | 100 % ✓ | unbounded | "
                               "unbounded ✗ (1) | unbounded ✗ (1) |")
    assert lines[3].startswith("| drift | 1 (1) | 100 % ✓ | 100 % ✓ (1) | 0 % ✓ | 0 % | - | 100 % ✓ | 12.0 | "
                               "12.0 ✓ (1) | 12.0 ✓ (1) |")


def test_markdown_holds_the_run_the_failures_and_every_ride(tmp_path):
    rows = _rows()
    meta = {"command": "euc-ros campaign open-world", "seed_set": "tuning", "per_family": 1,
            "seed_range": "seeds 0-0", "families": ["none", "drift"], "duration_s": 8.0, "rate_hz": 120.0,
            "rtol": 1e-6, "date": "2026-01-01", "machine": "m", "where": "serially", "wall_s": 60.0}
    md_path = tmp_path / "docs" / "open_world.md"
    md = report.markdown(summarize(rows), rows, meta, tmp_path / "figures" / "ow.png", md_path)
    assert "* command: `euc-ros campaign open-world`" in md and "3 rides in 1.0 min, median 3.0 s" in md
    assert f"![open-world study]({Path('..') / 'figures' / 'ow.png'})" in md
    assert "* drift_000001: ConfigError: falls" in md
    assert "| drift_000000 | cog_z | 0.5 | 0.40 | `rider_mass_error` | 0.50 | +10.0 | 12.0 |" in md
