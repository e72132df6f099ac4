"""`euc-ros inspect` (euc_ros/cli/inspect.py): Motive CSV summaries, JSON output, bag dispatch."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.io.motive_csv import write_motive_csv
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.session import default_session, save_session

REAL = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "motive_real"
HAS_BAGS = importlib.util.find_spec("euc_ros.core.io.bags") is not None


@pytest.fixture(scope="module")
def ride(tmp_path_factory) -> tuple[Path, MocapSeries]:
    """A Y-up export of two bodies above the floor, frames 100..159 with frames 120-122 missing,
    body H untracked in 7 frames."""
    rng = np.random.default_rng(4)
    frames = np.r_[100:120, 123:163].astype(np.int64)
    n = frames.size
    pos = np.empty((2, n, 3))
    pos[0] = [2.0, 1.0, 0.45] + 0.01 * rng.normal(size=(n, 3))   # E, Z-up
    pos[1] = [2.0, 1.0, 1.70] + 0.01 * rng.normal(size=(n, 3))   # H
    q = np.zeros((2, n, 4))
    q[..., 3] = 1.0
    trk = np.ones((2, n), bool)
    trk[1, 10:17] = False
    pos[~trk] = np.nan
    q[~trk] = np.nan
    s = MocapSeries(frames / 240.0, frames, ["E", "H"], pos, q, trk, np.full((2, n), 2e-4), "decel_01",
                    {"rate_hz": 240.0})
    path = write_motive_csv(s, tmp_path_factory.mktemp("inspect") / "decel_01.csv")
    return path, s


def test_inspect_csv_prints_and_writes_json(ride, tmp_path, capsys):
    path, s = ride
    out = tmp_path / "summary.json"
    assert main(["inspect", str(path), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    d = json.loads(out.read_text())
    assert d["kind"] == "motive_csv" and d["bodies"] == ["E", "H"] and d["n_bodies"] == 2
    assert d["n_frames"] == 60 and d["first_frame"] == 100 and d["last_frame"] == 162
    assert d["n_dropped"] == 3 and d["n_duplicates_dropped"] == 0
    assert d["rate_hz"] == 240.0 and d["duration_s"] == pytest.approx(62 / 240)
    assert d["occlusions"] == {"E": 0, "H": 7}
    assert d["rotation_type"] == "Quaternion" and d["length_units"] == "Meters"
    assert d["up_axis"]["configured"] == "y" and d["up_axis"]["inferred"] == "y"
    assert "never" in d["up_axis"]["note"]
    for needle in ("decel_01", "E, H", "60 (first 100, last 162), 3 dropped", "240 Hz", "Quaternion", "never writes"):
        assert needle in text
    assert any(line.split() == ["H", "7", "(11.7", "%)"] for line in text.splitlines())


def test_inspect_world_up_from_option_and_session(ride, tmp_path, capsys):
    path, _ = ride
    out = tmp_path / "z.json"
    assert main(["inspect", str(path), "--world-up", "z", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["up_axis"]["configured"] == "z" and d["up_axis"]["source"] == "--world-up"
    assert d["up_axis"]["inferred"] == "y"  # the data still say Y is up: the configured value is suspicious
    session = tmp_path / "session.yaml"
    save_session(default_session("z"), session)
    assert main(["inspect", str(path), "--session", str(session), "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["up_axis"]["configured"] == "z" and d["up_axis"]["source"].startswith("session")
    capsys.readouterr()


def test_inspect_bad_csv_exits_2_and_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("Format Version,1.23,Export Frame Rate,120\n\n,Type,Rigid Body\n")
    out = tmp_path / "out.json"
    assert main(["inspect", str(bad), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert "bad.csv, line 3, column 1: missing header rows" in err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_inspect_missing_file_and_plain_directory(tmp_path, capsys):
    assert main(["inspect", str(tmp_path / "nope.csv")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["inspect", str(tmp_path)]) == 2
    assert "not a rosbag2 bag" in capsys.readouterr().err


@pytest.mark.skipif(not REAL.is_dir(), reason=f"real Motive exports not available ({REAL} is absent)")
@pytest.mark.shared
def test_inspect_real_export_with_occlusion(tmp_path, capsys):
    out = tmp_path / "g.json"
    assert main(["inspect", str(REAL / "grvc_1rb_120hz_m_quality_occlusion_v1.23.csv"), "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["occlusions"] == {"ernesto_body": 1} and d["n_frames"] == 499 and d["up_axis"]["inferred"] == "y"
    capsys.readouterr()


@pytest.mark.skipif(not HAS_BAGS, reason="euc_ros.core.io.bags is not in this tree yet")
def test_inspect_bag_dispatch_and_verdict(ride, tmp_path, capsys):
    from euc_ros.core.io.bags import write_mocap_bag

    _, s = ride
    bag = tmp_path / "bag"
    write_mocap_bag(s, bag)
    out = tmp_path / "bag.json"
    assert main(["inspect", str(bag), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "structural check: OK" in text
    d = json.loads(out.read_text())
    assert d["kind"] == "rosbag2" and d["check"] == {"ok": True, "problems": []}
    mcap = next(bag.glob("*.mcap"))
    assert main(["inspect", str(mcap)]) == 0  # an .mcap file dispatches to the bag inspector too
    capsys.readouterr()
    raw = mcap.read_bytes()
    mcap.write_bytes(raw[: len(raw) // 2])  # recorder killed: truncated MCAP
    assert main(["inspect", str(bag), "--json", str(out)]) == 1
    assert "structural check: FAILED" in capsys.readouterr().out
    assert json.loads(out.read_text())["check"]["ok"] is False
