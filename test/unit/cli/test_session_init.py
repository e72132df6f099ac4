"""`euc-ros session init` writes a commented session that validates, with the lab's body names."""
from __future__ import annotations

import pytest

from euc_ros.cli.main import main
from euc_ros.core.session import load_session

BASE = ["session", "init", "--mass", "72", "--height", "1.78", "--sex", "male"]


def test_init_writes_a_session_that_validates(tmp_path, capsys):
    out = tmp_path / "s" / "session.yaml"
    assert main([*BASE, "--world-up", "z", "--name", "H=Helmet", "--name", "CHR=RShoulder", "--wheel-radius",
                 "0.203", "--pivot-to-wheel-center", "0", "0", "-0.5", "--euc-body", "EUC", "--out", str(out)]) == 0
    s = load_session(out)
    assert s.world_up == "z" and s.rider.mass == 72.0 and s.euc.body == "EUC"
    assert s.euc.wheel_radius == 0.203 and s.euc.pivot_to_wheel_center == (0.0, 0.0, -0.5)
    assert "Helmet" in s.rider.segments and "RShoulder" in s.rider.segments and "H" not in s.rider.segments
    assert sum(seg.mass_fraction for seg in s.rider.segments.values()) == pytest.approx(1.0, abs=1e-3)
    text = out.read_text()
    assert "de Leva (1996)" in text
    # EUC values not given are the paper's, and the file and the console say so
    assert text.count("the EUC paper's value (Table 3): measure yours") == 6
    said = capsys.readouterr().out
    assert "wheel_mass" in said and "wheel_radius" not in said


def test_init_refuses_to_overwrite_and_names_bad_input(tmp_path, capsys):
    out = tmp_path / "session.yaml"
    out.write_text("keep me\n")
    assert main([*BASE, "--out", str(out)]) == 2
    assert "--force" in capsys.readouterr().err and out.read_text() == "keep me\n"
    assert main([*BASE, "--out", str(out), "--force"]) == 0
    assert main([*BASE, "--name", "HEAD=Helmet", "--out", "-"]) == 2
    assert "no rider body 'HEAD'" in capsys.readouterr().err
    assert main([*BASE, "--name", "H=X", "--name", "CHR=X", "--out", "-"]) == 2
    assert "given to two bodies" in capsys.readouterr().err


def test_init_to_standard_output(capsys):
    assert main([*BASE, "--out", "-"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("# euc_ros session") and "segments:" in text
