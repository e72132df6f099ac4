"""`euc-ros identify` in-process: CSV and bag recordings, JSON, figures, errors."""
from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from euc_ros.cli import identify as identify_cmd
from euc_ros.cli.main import main
from euc_ros.core.euc.model import EucParams
from euc_ros.core.session import default_session, save_session

H_TRUE = 0.61


@pytest.fixture(scope="module")
def recordings(tmp_path_factory, symbolic, synth):
    """Two model-consistent rides written as Motive CSV (Y-up) plus their session file."""
    motive_csv = pytest.importorskip("euc_ros.core.io.motive_csv", reason="Motive CSV reader not available")
    d = tmp_path_factory.mktemp("rec")
    session = default_session("y")
    save_session(session, d / "session.yaml")
    p = EucParams.from_session(session, H_TRUE)
    rng = np.random.default_rng(9)
    files, series = [], []
    for i, seed in enumerate((11, 12)):
        ride = synth.planar_ride(symbolic, p, duration=7.0, seed=seed, decel=0.05)
        n = ride["t"].size
        psi0 = 0.0 if i == 0 else np.pi
        C = np.column_stack([np.cos(psi0) * ride["x"], np.sin(psi0) * ride["x"], np.full(n, p.R)])
        s = synth.synthesize_mocap(session, t=ride["t"], C=C, psi=np.full(n, psi0), theta=np.zeros(n),
                                   gamma=ride["gamma"], phi=ride["phi"], h=H_TRUE, rng=rng, pos_noise=1e-4,
                                   rot_noise=np.radians(0.05), name=f"decel_{i + 1:02d}")
        files.append(motive_csv.write_motive_csv(s, d / f"decel_{i + 1:02d}.csv", world_up="y"))
        series.append(s)
    return d, files, series


def test_parser_defaults():
    p = argparse.ArgumentParser()
    identify_cmd.add_arguments(p)
    a = p.parse_args(["s.yaml", "a.csv", "b.csv"])
    assert a.recordings == ["a.csv", "b.csv"] and a.phi_definition == "hinge" and a.json is None
    g = identify_cmd.h_grid_from_args(a)
    assert g[0] == pytest.approx(0.1) and g[-1] == pytest.approx(1.2) and g.size == 221


def test_identify_csv_writes_table_json_and_figures(recordings, tmp_path, capsys):
    d, files, _ = recordings
    out = tmp_path / "out.json"
    plots = tmp_path / "fig"
    rc = main(["identify", str(d / "session.yaml"), *map(str, files), "--json", str(out), "--plots", str(plots),
               "--window-s", "0.3", "--no-progress"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "decel_01" in text and "decel_02" in text and "pooled" in text
    js = json.loads(out.read_text())
    assert js["model"] == "3dof" and abs(js["h_m"] - H_TRUE) < 0.015
    assert [r["recording"] for r in js["per_recording"]] == ["decel_01", "decel_02"]
    assert js["models"]["2dof"]["rmse_nm"] > js["rmse_nm"]
    assert js["settings"]["phi_definition"] == "hinge" and js["settings"]["window_s"] == 0.3
    for name in ("decel_01_states.png", "decel_02_states.png", "rmse_curves.png"):
        data = (plots / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_identify_reads_a_bag_like_the_csv(recordings, tmp_path, capsys):
    bags = pytest.importorskip("euc_ros.core.io.bags", reason="bag library not available")
    d, files, series = recordings
    bag = tmp_path / "decel_bag"
    bags.write_mocap_bag(series[0], bag)
    rc_b = main(["identify", str(d / "session.yaml"), str(bag), "--json", str(tmp_path / "b.json"),
                 "--window-s", "0.3"])
    rc_c = main(["identify", str(d / "session.yaml"), str(files[0]), "--json", str(tmp_path / "c.json"),
                 "--window-s", "0.3"])
    assert rc_b == rc_c == 0
    jb = json.loads((tmp_path / "b.json").read_text())
    jc = json.loads((tmp_path / "c.json").read_text())
    assert jb["h_m"] == pytest.approx(jc["h_m"], abs=2e-3)


def test_eq3_definition_is_selectable_and_differs(recordings, tmp_path):
    d, files, _ = recordings
    outs = {}
    for definition in ("hinge", "eq3"):
        out = tmp_path / f"{definition}.json"
        assert main(["identify", str(d / "session.yaml"), *map(str, files), "--json", str(out), "--window-s", "0.3",
                     "--phi-definition", definition]) == 0
        outs[definition] = json.loads(out.read_text())["h_m"]
    assert abs(outs["hinge"] - H_TRUE) < abs(outs["eq3"] - H_TRUE)


@pytest.mark.parametrize("extra, needle", [
    (["--h-step", "0"], "--h-step"),
    (["--h-min", "1.0", "--h-max", "0.5"], "--h-min"),
    (["--window-s", "0.01"], "window"),
])
def test_bad_options_exit_2_naming_the_option(recordings, capsys, extra, needle):
    d, files, _ = recordings
    assert main(["identify", str(d / "session.yaml"), str(files[0]), *extra]) == 2
    assert needle in capsys.readouterr().err


def test_bad_session_and_missing_recording_exit_2(recordings, tmp_path, capsys):
    d, files, _ = recordings
    bad = tmp_path / "bad.yaml"
    bad.write_text((d / "session.yaml").read_text().replace("wheel_radius", "wheel_radios"))
    assert main(["identify", str(bad), str(files[0])]) == 2
    assert "wheel_radios" in capsys.readouterr().err
    assert main(["identify", str(d / "session.yaml"), str(tmp_path / "nope.csv")]) == 2
    assert "nope.csv" in capsys.readouterr().err
    (tmp_path / "x.txt").write_text("hello")
    assert main(["identify", str(d / "session.yaml"), str(tmp_path / "x.txt")]) == 2
    assert "unknown recording type" in capsys.readouterr().err
