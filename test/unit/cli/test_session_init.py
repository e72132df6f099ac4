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


def test_init_and_the_simulators_default_rider_read_one_table(monkeypatch, capsys):
    """`session init` for the default rider's measures writes the simulator's rider: the same fractions,
    offsets and pitch inertia. Both read euc_ros.core.anthropometry when called, so a change of the table
    reaches both (neither holds a copy of its numbers)."""
    import dataclasses

    from euc_ros.core import anthropometry
    from euc_ros.core.ridesim.simulate import RideConfig
    from euc_ros.core.ridesim.skeleton import Skeleton
    from euc_ros.core.ridesim.truth_model import PlanarParams
    from euc_ros.core.session import DEFAULT_RIDER_HEIGHT, DEFAULT_RIDER_MASS, DEFAULT_RIDER_SEX, parse_session
    from euc_ros.core.yamlfile import parse_yaml

    measures = (DEFAULT_RIDER_MASS, DEFAULT_RIDER_HEIGHT, DEFAULT_RIDER_SEX)

    def written_and_simulated():
        assert main(["session", "init", "--mass", repr(measures[0]), "--height", repr(measures[1]), "--sex",
                     measures[2], "--out", "-"]) == 0
        written = parse_session(parse_yaml(capsys.readouterr().out, "init")).rider
        session = RideConfig().nominal_session()
        skeleton = Skeleton.for_session(session)
        simulated = dict(zip(skeleton.bodies, skeleton.fractions))
        assert PlanarParams.from_session(session).J == session.rider.inertia_pitch
        return written, session.rider, simulated

    written, rider, simulated = written_and_simulated()
    table = anthropometry.rider_segments(*measures)
    standing = anthropometry.standing_rider(*measures)
    assert sorted(written.segments) == sorted(simulated) == sorted(table) == sorted(anthropometry.BODIES)
    for body, seg in table.items():
        assert simulated[body] == rider.segments[body].mass_fraction == seg.mass_fraction, body
        assert written.segments[body].mass_fraction == pytest.approx(seg.mass_fraction, abs=5e-6), body   # 5 decimals
        assert written.segments[body].com_offset == rider.segments[body].com_offset == seg.com_offset, body
    assert rider.inertia_pitch == standing.inertia_pitch
    assert written.inertia_pitch == pytest.approx(rider.inertia_pitch, abs=5e-4)                        # 3 decimals
    assert sum(simulated.values()) == pytest.approx(1.0, abs=1e-3)

    thigh = anthropometry.TABLE[DEFAULT_RIDER_SEX]["thigh"]
    monkeypatch.setitem(anthropometry.TABLE[DEFAULT_RIDER_SEX], "thigh",
                        dataclasses.replace(thigh, mass_pct=thigh.mass_pct + 4.0, r_transverse_pct=40.0))
    written2, rider2, simulated2 = written_and_simulated()
    assert written2.segments["TR"].mass_fraction > written.segments["TR"].mass_fraction + 0.02
    assert simulated2["TR"] == pytest.approx(written2.segments["TR"].mass_fraction, abs=5e-6)
    assert rider2.inertia_pitch != rider.inertia_pitch
    assert written2.inertia_pitch == pytest.approx(rider2.inertia_pitch, abs=5e-4)
