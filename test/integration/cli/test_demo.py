"""The main job closes the loop end to end (offline part): the residual's JSON, whatever outcome markers its
``effect`` carries, feeds ``identify --from-residual``."""
from __future__ import annotations

import json

import pytest

from euc_ros.cli.main import main


@pytest.mark.timeout(600)
def test_demo_closes_the_loop_offline(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--skip-live", "--skip-steer"]) == 0
    residual = json.loads((out / "residual.json").read_text())
    extended = json.loads((out / "identify_extended.json").read_text())
    truth = json.loads((out / "ride" / "truth" / "truth.json").read_text())
    # the hidden effect is found and the extended model is identified with it
    assert residual["effect"].split("+")[0] == truth["effect"]
    assert extended["model"] == f"3dof+{truth['effect']}"
    assert residual["rmse_after_nm"] < 0.2 * residual["rmse_before_nm"]
    assert "closing the loop" in capsys.readouterr().out
