"""Nothing recorded is lost: output paths are checked before any work."""
from __future__ import annotations

import json
import os

import pytest

from euc_ros.cli.main import main
from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import ConfigError


@pytest.fixture(scope="module")
def ride(tmp_path_factory):
    d = tmp_path_factory.mktemp("ride") / "ride"
    assert main(["simulate-ride", "--runs", "1", "--seed", "5", "--duration", "3", "--out", str(d), "--bag",
                 "--no-progress"]) == 0
    return d


def _one_line_error(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


@pytest.mark.parametrize("target", ["recording", "session"])
def test_json_onto_an_input_is_refused_and_the_input_is_intact(ride, target, capsys):
    rec = ride / "deceleration_01.csv"
    victim = rec if target == "recording" else ride / "session.yaml"
    before = victim.read_bytes()
    for cmd in ("identify", "residual"):
        rc = main([cmd, str(ride / "session.yaml"), str(rec), "--json", str(victim), "--no-progress"])
        msg = _one_line_error(capsys)
        assert rc == 2 and "--json" in msg and victim.name in msg and "input" in msg
    assert victim.read_bytes() == before


def test_outputs_inside_an_input_bag_or_onto_a_directory_are_refused(ride, tmp_path, capsys):
    bag = ride / "deceleration_01_bag"
    rc = main(["identify", str(ride / "session.yaml"), str(bag), "--json", str(bag / "out.json"), "--no-progress"])
    assert rc == 2 and "inside the input bag" in _one_line_error(capsys)
    rc = main(["identify", str(ride / "session.yaml"), str(bag), "--json", str(tmp_path), "--no-progress"])
    assert rc == 2 and "existing directory" in _one_line_error(capsys)


def test_a_bad_path_fails_before_the_analysis(ride, tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    rc = main(["residual", str(ride / "session.yaml"), str(ride / "deceleration_01.csv"), "--json",
               str(tmp_path / "ok.json"), "--plots", str(tmp_path / "afile" / "figs"), "--no-progress"])
    msg = _one_line_error(capsys)
    assert rc == 2 and "--plots" in msg and "is a file" in msg
    assert not (tmp_path / "ok.json").exists()   # nothing was computed or written


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable_folder_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    with pytest.raises(ConfigError, match="permission"):
        check_outputs([Output("--json", ro / "x.json")])


def test_two_outputs_on_one_path_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="--report"):
        check_outputs([Output("--json", tmp_path / "a"), Output("--report", tmp_path / "a")])


def test_simulate_ride_refuses_a_non_empty_folder_and_overwrite_replaces_only_a_ride(tmp_path, capsys):
    out = tmp_path / "r"
    args = ["simulate-ride", "--runs", "1", "--duration", "2", "--no-progress", "--out", str(out)]
    assert main(args) == 0
    assert sorted(p.name for p in out.glob("*.csv")) == ["deceleration_01.csv"]     # truth apart
    assert (out / "truth" / "truth.json").exists() and (out / "truth" / "deceleration_01_truth.csv").exists()
    assert main(args) == 2 and "not empty" in _one_line_error(capsys)
    # --overwrite replaces the previous ride and leaves no stale file (3 runs then 1 run)
    assert main(["simulate-ride", "--runs", "3", "--duration", "2", "--no-progress", "--out", str(out),
                 "--overwrite"]) == 0
    assert len(list(out.glob("*.csv"))) == 3
    assert main(args + ["--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["deceleration_01.csv", "session.yaml", "truth"]
    assert json.loads((out / "truth" / "truth.json").read_text())["runs"][0]["run"] == "deceleration_01"
    # a folder with someone else's file is never cleared
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    rc = main(["simulate-ride", "--runs", "1", "--duration", "2", "--no-progress", "--out", str(other),
               "--overwrite"])
    assert rc == 2 and "not one" in _one_line_error(capsys)
    assert (other / "notes.txt").read_text() == "keep me"
