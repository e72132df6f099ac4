"""`euc_ros.identify` and `euc_ros.residual` give the commands' JSON, text for text."""
from __future__ import annotations

import euc_ros
from euc_ros.cli.main import main


def _api_and_command(command, short_ride, out):
    """The API's result on the short ride, once its JSON has been checked against the command's."""
    src, _ = short_ride
    session, csv = src / "session.yaml", src / "deceleration_01.csv"
    assert main([command, str(session), str(csv), "--json", str(out), "--no-progress"]) == 0
    result = getattr(euc_ros, command)(session, [csv])
    assert result.to_json() == out.read_text()
    return result


def test_identify_api_is_the_command(short_ride, tmp_path):
    fit = _api_and_command("identify", short_ride, tmp_path / "h.json")
    assert fit.h == fit.data["h_m"]
    assert [None if v != v else v for v in fit.interval] == list(fit.data.get("h_ci95_m") or [None, None])


def test_residual_api_is_the_command(short_ride, tmp_path):
    res = _api_and_command("residual", short_ride, tmp_path / "r.json")
    assert (res.effect, res.h_after, res.rmse_after) == (res.data["effect"], res.data["h_after_m"],
                                                          res.data["rmse_after_nm"])
