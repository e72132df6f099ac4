"""`euc_ros.identify` and `euc_ros.residual` give the commands' JSON, text for text."""
from __future__ import annotations

import euc_ros
from euc_ros.cli.main import main


def test_identify_api_is_the_command(short_ride, tmp_path):
    src, _ = short_ride
    session, csv = src / "session.yaml", src / "deceleration_01.csv"
    out = tmp_path / "h.json"
    assert main(["identify", str(session), str(csv), "--json", str(out), "--no-progress"]) == 0
    fit = euc_ros.identify(session, [csv])
    assert fit.to_json() == out.read_text()
    assert fit.h == fit.data["h_m"]
    assert [None if v != v else v for v in fit.interval] == list(fit.data.get("h_ci95_m") or [None, None])


def test_residual_api_is_the_command(short_ride, tmp_path):
    src, _ = short_ride
    session, csv = src / "session.yaml", src / "deceleration_01.csv"
    out = tmp_path / "r.json"
    assert main(["residual", str(session), str(csv), "--json", str(out), "--no-progress"]) == 0
    res = euc_ros.residual(session, [csv])
    assert res.to_json() == out.read_text()
    assert (res.effect, res.h_after, res.rmse_after) == (res.data["effect"], res.data["h_after_m"],
                                                          res.data["rmse_after_nm"])
