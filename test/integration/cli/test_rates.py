"""360 Hz recordings give the right numbers; a session rate that contradicts
the data is a one-line refusal naming both rates (offline)."""
from __future__ import annotations

import json

import pytest

from euc_ros.cli.main import main
from euc_ros.core.session import load_session, save_session

H_TRUE = 0.61


def _ride(tmp_path_factory, rate_hz, runs=3, seed=5):
    import dataclasses

    from euc_ros.core.session import default_session

    d = tmp_path_factory.mktemp(f"ride{rate_hz}")
    save_session(dataclasses.replace(default_session("y"), rate_hz=float(rate_hz)), d / "nominal.yaml")
    assert main(["simulate-ride", "--runs", str(runs), "--seed", str(seed), "--session", str(d / "nominal.yaml"),
                 "--out", str(d / "ride")]) == 0
    return d / "ride"


@pytest.fixture(scope="module")
def ride360(tmp_path_factory):
    return _ride(tmp_path_factory, 360)


def test_identify_at_360hz_finds_h(ride360, tmp_path, capsys):
    """Before: h = 1.200 (the grid edge), RMSE ~3500 N m."""
    out = tmp_path / "id.json"
    rc = main(["identify", str(ride360 / "session.yaml"), *sorted(map(str, ride360.glob("deceleration_[0-9][0-9].csv"))),  # noqa: E501
               "--json", str(out), "--no-progress"])
    assert rc == 0
    js = json.loads(out.read_text())
    # 3 runs of 7 s: the per-run spread of h is ~4 mm (README table), so 2 cm is a 5-sigma bound
    assert abs(js["h_m"] - H_TRUE) < 0.02
    assert js["rmse_nm"] < 1.0


@pytest.mark.slow
def test_residual_at_360hz_reports_no_false_effect(ride360, tmp_path):
    """Before: `wheel_radius_error -0.2 m`."""
    out = tmp_path / "res.json"
    rc = main(["residual", str(ride360 / "session.yaml"), *sorted(map(str, ride360.glob("deceleration_[0-9][0-9].csv"))),  # noqa: E501
               "--json", str(out), "--no-progress"])
    assert rc == 0
    js = json.loads(out.read_text())
    assert js["effect"] == "none" and abs(js["h_m"] - H_TRUE) < 0.02


def test_session_rate_contradicting_the_data_is_a_one_line_refusal(ride360, tmp_path, capsys):
    s = load_session(ride360 / "session.yaml")
    import dataclasses

    save_session(dataclasses.replace(s, rate_hz=120.0), tmp_path / "s120.yaml")
    rec = sorted(ride360.glob("deceleration_[0-9][0-9].csv"))[0]
    for cmd in ("identify", "residual"):
        rc = main([cmd, str(tmp_path / "s120.yaml"), str(rec), "--no-progress", "--json", str(tmp_path / "o.json")])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 2 and len(err) == 1, err
        assert rec.name in err[0] and "rate_hz" in err[0] and "360" in err[0] and "120" in err[0]
        assert not (tmp_path / "o.json").exists()
