"""Sets of recordings as labs have them: of different lengths (a take stopped early), one of them too short
to use. identify and residual read them all; a recording without a single usable state (shorter than the
chosen filter's window) is left out and said, not a refusal of the whole set; alone it is refused, naming it.
What can go wrong: the takes of one rate handed to the filter choice as a ragged list (numpy refuses to
take its shape), which only takes of different lengths show."""
# covers: euc_ros/core/mocap/duplicates.py
from __future__ import annotations

import json

import pytest

from euc_ros.cli.main import main

H_TRUE = 0.61


def _take(src, dst, rows):
    """The first ``rows`` data rows of a Motive export (its 7 header lines kept): a take stopped early."""
    lines = src.read_text().splitlines(keepends=True)
    dst.write_text("".join(lines[:7 + rows]))
    return dst


@pytest.fixture(scope="module")
def takes(tmp_path_factory):
    d = tmp_path_factory.mktemp("takes")
    assert main(["simulate-ride", "--maneuver", "deceleration", "--runs", "3", "--seed", "11", "--out", str(d / "ride"),
                 "--no-progress"]) == 0
    ride = d / "ride"
    return {"session": ride / "session.yaml", "full": ride / "deceleration_01.csv",
            "early": _take(ride / "deceleration_02.csv", d / "stopped_early.csv", 700),
            "later": _take(ride / "deceleration_03.csv", d / "stopped_later.csv", 780),
            "short": _take(ride / "deceleration_03.csv", d / "false_start.csv", 100)}


def test_takes_of_different_lengths_are_analysed(takes, tmp_path):
    recs = [str(takes[k]) for k in ("full", "early", "later")]
    assert main(["identify", str(takes["session"]), *recs, "--json", str(tmp_path / "id.json"), "--no-progress"]) == 0
    out = json.loads((tmp_path / "id.json").read_text())
    assert [r["frames"] for r in out["per_recording"]] == [840, 700, 780]
    # 3 runs of 6-7 s: the per-run spread of h is ~4 mm (test_rates), so 2 cm is a 5-sigma bound
    assert abs(out["h_m"] - H_TRUE) < 0.02
    assert main(["residual", str(takes["session"]), *recs, "--json", str(tmp_path / "r.json"), "--no-progress"]) == 0
    assert json.loads((tmp_path / "r.json").read_text())["effect"] == "none"


def test_a_take_without_usable_states_is_left_out_and_said(takes, tmp_path, capsys):
    recs = [str(takes[k]) for k in ("full", "short", "early")]
    assert main(["identify", str(takes["session"]), *recs, "--json", str(tmp_path / "id.json"), "--no-progress"]) == 0
    out = json.loads((tmp_path / "id.json").read_text())
    skipped = [w for w in out["warnings"] if "skipped" in w]
    assert len(skipped) == 1 and "long enough to differentiate" in skipped[0], out["warnings"]
    assert [r["frames"] for r in out["per_recording"]] == [840, 700]
    assert "skipped" in capsys.readouterr().err


def test_alone_it_is_refused_naming_the_file(takes, capsys):
    assert main(["identify", str(takes["session"]), str(takes["short"]), "--no-progress"]) != 0
    err = capsys.readouterr().err
    assert "false_start.csv" in err and "long enough to differentiate" in err
    # and says why, and what would help: the take (99 frame periods at 120 Hz) is shorter than the window
    assert "the take lasts 0.82 s, less than the filter's" in err and "--window-s" in err


def test_a_take_given_twice_counts_once(takes, tmp_path, capsys):
    """A take's CSV and the bag converted from it, side by side: analysed twice it would count double (and
    narrow the intervals as if it were independent data); the second is left out and said."""
    bag = tmp_path / "full_bag"
    assert main(["convert", str(takes["full"]), str(bag), "--frames", "--no-progress"]) == 0
    recs = [str(takes["full"]), str(bag), str(takes["early"])]
    assert main(["identify", str(takes["session"]), *recs, "--json", str(tmp_path / "id.json"), "--no-progress"]) == 0
    out = json.loads((tmp_path / "id.json").read_text())
    assert [r["frames"] for r in out["per_recording"]] == [840, 700]
    assert any(w.startswith("full_bag: skipped: the same take as") for w in out["warnings"]), out["warnings"]


def test_two_takes_of_one_length_are_two_takes(takes):
    """Different takes of the same frame span and bodies are not taken for one (their poses differ by far more
    than the export's rounding)."""
    from euc_ros.core.io.recordings import load_recording
    from euc_ros.core.mocap.duplicates import TakeIndex

    ride = takes["full"].parent
    index = TakeIndex()
    for name in ("deceleration_01", "deceleration_02", "deceleration_03"):
        assert index.same_as(load_recording(str(ride / f"{name}.csv")), name) is None
    assert index.same_as(load_recording(str(ride / "deceleration_02.csv")), "again") == "deceleration_02"
