"""The small things of a user's first day: standard output, unwritable paths, swapped arguments,
missing bodies named with the ones the file has, bodies excluded by the skeleton said with counts."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from euc_ros.cli.main import main
from euc_ros.core.io.motive_csv import read_motive_csv, write_motive_csv


@pytest.fixture(scope="module")
def ride(short_ride):
    src, _ = short_ride
    return src / "session.yaml", src / "deceleration_01.csv"


def test_json_dash_goes_to_standard_output_and_messages_to_standard_error(ride, tmp_path, capsys, monkeypatch):
    session, csv = ride
    monkeypatch.chdir(tmp_path)
    assert main(["identify", str(session), str(csv), "--json", "-", "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["h_m"] > 0                 # only the JSON on standard output
    assert "3-DoF h [m]" in err and not (tmp_path / "-").exists()


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="no /proc on this system")
def test_an_output_on_a_virtual_file_system_is_refused_before_the_analysis(ride, capsys):
    session, csv = ride
    assert main(["identify", str(session), str(csv), "--json", "/proc/x.json", "--no-progress"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "/proc/x.json" in err[0] and "--json" in err[0], err
    assert "h = " not in captured.out                     # refused before any work


def test_swapped_session_and_recording_say_so(ride, capsys):
    session, csv = ride
    assert main(["identify", str(csv), str(session), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "not a session file" in err and "swapped" in err


@pytest.mark.parametrize("command, extra", [("identify", []), ("residual", ["--json", "out.json"])])
@pytest.mark.parametrize("recording", ["ride.csv", "ride.mcap"])
def test_swapped_arguments_name_the_command_that_was_run(command, extra, recording, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / recording).write_text("not read\n")
    (tmp_path / "session.yaml").write_text("not read\n")
    assert main([command, recording, "session.yaml", *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"euc-ros {command}: error: {recording}: ") and "swapped" in err, err
    other = {"identify": "residual", "residual": "identify"}[command]
    assert f"euc-ros {other}" not in err, err


def test_a_missing_body_lists_the_bodies_the_file_has(ride, tmp_path, capsys):
    session, csv = ride
    renamed = tmp_path / "session.yaml"
    renamed.write_text(session.read_text().replace("  CHR:", "  CHEST_R:"))
    assert main(["identify", str(renamed), str(csv), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "CHEST_R" in err and "has: H, CHR" in err and "does not name: CHR" in err


def test_renamed_bodies_with_the_skeleton_are_used_and_said(ride, tmp_path, capsys):
    session, csv = ride
    s = read_motive_csv(csv, world_up="y")
    s.bodies = [{"H": "Helmet", "CHR": "RShoulder"}.get(b, b) for b in s.bodies]
    ren = write_motive_csv(s, tmp_path / "ride.csv", world_up="y")
    sess = tmp_path / "session.yaml"
    sess.write_text(session.read_text().replace("    H:", "    Helmet:").replace("    CHR:", "    RShoulder:"))
    out = tmp_path / "h.json"
    assert main(["identify", str(sess), str(ren), "--cog-method", "skeleton", "--json", str(out),
                 "--no-progress"]) == 0
    data = json.loads(out.read_text())
    # bodies the chain does not know are not excluded (they were, in every frame), and that is said
    assert "Helmet" not in data["cog"]["per_body"] and "RShoulder" not in data["cog"]["per_body"]
    assert any("no link for Helmet, RShoulder" in w for w in data["warnings"]), data["warnings"]
    assert "no link for Helmet, RShoulder" in capsys.readouterr().err


def test_residual_takes_the_phi_definition_and_tolerances(ride, tmp_path):
    session, csv = ride
    out, base = tmp_path / "r.json", tmp_path / "base.json"
    assert main(["residual", str(session), str(csv), "--json", str(base), "--no-progress"]) == 0
    assert main(["residual", str(session), str(csv), "--json", str(out), "--no-progress", "--phi-definition", "eq3",
                 "--tolerance", "rider.mass=2"]) == 0
    data, plain = json.loads(out.read_text()), json.loads(base.read_text())
    assert data["settings"]["phi_definition"] == "eq3" and "phi_definition" not in plain["settings"]
    budget = data["uncertainty_budget"]
    assert budget["sensitivity"]["rider.mass"]["tolerance"] == 2.0, budget
    assert "uncertainty_budget" not in plain                 # the default output is unchanged
    assert data["rmse_before_nm"] != plain["rmse_before_nm"]  # another phi: other states, other residual
