"""``euc-ros residual --plausible EFFECT.PARAM=LOW:HIGH``: the ranges reach the analysis and the JSON; a
malformed or unknown one is refused before any work."""
from __future__ import annotations

import json

from euc_ros.cli.main import main


def test_plausible_ranges_go_into_the_settings(short_ride, tmp_path):
    src, _ = short_ride
    out = tmp_path / "r.json"
    assert main(["residual", str(src / "session.yaml"), str(src / "deceleration_01.csv"), "--json", str(out),
                 "--no-progress", "--candidates", "aero_drag", "rider_mass_error",
                 "--plausible", "aero_drag.cda_m2=0.3:0.9", "--plausible", "rider_mass_error.delta_m_kg=-5:5"]) == 0
    data = json.loads(out.read_text())
    assert data["settings"]["plausible"] == {"aero_drag.cda_m2": [0.3, 0.9], "rider_mass_error.delta_m_kg": [-5, 5]}
    assert isinstance(data["refused"], list) and isinstance(data["ties"], list)


def test_a_malformed_or_unknown_range_is_an_error(short_ride, tmp_path, capsys):
    src, _ = short_ride
    for bad in ("aero_drag.cda_m2=0.3", "aero_drag.cd=0.3:0.9"):
        assert main(["residual", str(src / "session.yaml"), str(src / "deceleration_01.csv"), "--json",
                     str(tmp_path / "r.json"), "--no-progress", "--plausible", bad]) == 2
        assert bad.split("=")[0] in capsys.readouterr().err
    assert not (tmp_path / "r.json").exists()
