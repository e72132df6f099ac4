"""Files of a simulated ride: Motive CSV per docs/motive_csv.md, session, truth, MCAP bag, CLI.

Tolerances come from what the files store, the same on every machine: the Motive CSV has 6 decimals
(a cell is within half a unit, 5e-7, of its value; +1e-8 for the ulps of the axis change), the truth
CSV 12 significant digits (relative 5e-12: rtol 1e-11), bags integer nanoseconds (times within
0.5e-9 s plus an ulp: atol 1e-9 s).
"""
from __future__ import annotations

import csv
import importlib.util
import json

import numpy as np
import pytest

from euc_ros.cli.main import main as cli_main
from euc_ros.core.ridesim import MocapNoise, RideConfig, make_effects, simulate_ride, write_ride
from euc_ros.core.ridesim.writers import TRUTH_COLUMNS
from euc_ros.core.session import load_session

GROUP = ["Rotation"] * 4 + ["Position"] * 3 + ["Mean Marker Error"]
AXES = ["X", "Y", "Z", "W", "X", "Y", "Z", ""]


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    ride = simulate_ride(RideConfig(maneuver="deceleration", runs=2, seed=4, duration_s=2.0,
                                    effects=make_effects(["rider_mass_error"], {"delta_m_kg": 8.0}),
                                    noise=MocapNoise(gaps=2, drop_rate=0.02)))
    out = tmp_path_factory.mktemp("ride")
    files = write_ride(ride, out, bag=True)
    return ride, out, files


def _parse_csv(path):
    """Read a Motive CSV with the csv module only (independent of the project's reader)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    meta = dict(zip(rows[0][0::2], rows[0][1::2]))
    data = np.array([[float(c) if c != "" else np.nan for c in r] for r in rows[7:]])
    return rows, meta, data


def test_csv_header_is_the_spec_format(written):
    ride, out, _ = written
    run = ride.runs[0]
    rows, meta, data = _parse_csv(out / f"{run.name}.csv")
    assert meta["Format Version"] == "1.23" and meta["Take Name"] == run.name
    assert meta["Rotation Type"] == "Quaternion" and meta["Length Units"] == "Meters"
    assert meta["Coordinate Space"] == "Global" and float(meta["Export Frame Rate"]) == 120.0
    assert int(meta["Total Frames in Take"]) == run.t.size
    assert int(meta["Total Exported Frames"]) == run.mocap.n_frames == data.shape[0]
    assert all(c in ("", ",") for c in rows[1])
    bodies = run.mocap.bodies
    assert rows[2] == ["", "Type"] + ["Rigid Body"] * 8 * len(bodies)
    assert rows[3] == ["", "Name"] + [b for b in bodies for _ in range(8)]
    assert rows[4] == ["", "ID"] + [str(i + 1) for i in range(len(bodies)) for _ in range(8)]
    assert rows[5] == ["", ""] + GROUP * len(bodies)
    assert rows[6] == ["Frame", "Time (Seconds)"] + AXES * len(bodies)


def test_csv_values_are_the_recorded_poses_in_y_up(written):
    ride, out, _ = written
    for run in ride.runs:
        _, _, data = _parse_csv(out / f"{run.name}.csv")
        rec = run.mocap
        np.testing.assert_array_equal(data[:, 0].astype(int), rec.frame)
        np.testing.assert_allclose(data[:, 1], rec.frame / 120.0, atol=5e-7)   # k / 120 to 6 decimals: <= 3.4e-7
        block = data[:, 2:].reshape(rec.n_frames, len(rec.bodies), 8).transpose(1, 0, 2)
        # Motive Y-up (X, Y, Z) = Z-up (x, z, -y); quaternion (qx, qy, qz) = (qx, qz, -qy)
        pos = np.stack([block[..., 4], -block[..., 6], block[..., 5]], -1)
        quat = np.stack([block[..., 0], -block[..., 2], block[..., 1], block[..., 3]], -1)
        blank = np.isnan(block).all(axis=-1)
        np.testing.assert_array_equal(blank, ~rec.tracked)
        assert blank.any()  # the gaps made it into the file
        ok = rec.tracked
        np.testing.assert_allclose(pos[ok], rec.position[ok], atol=5.1e-7)
        np.testing.assert_allclose(quat[ok], rec.quat[ok], atol=5.1e-7)


def test_csv_round_trips_through_the_projects_reader(written):
    if importlib.util.find_spec("euc_ros.core.io.motive_csv") is None:
        pytest.skip("euc_ros.core.io.motive_csv not available yet")
    from euc_ros.core.io.motive_csv import read_motive_csv

    ride, out, _ = written
    for run in ride.runs:
        s = read_motive_csv(out / f"{run.name}.csv", world_up="y")
        rec = run.mocap
        assert s.bodies == rec.bodies
        np.testing.assert_array_equal(s.frame, rec.frame)
        np.testing.assert_array_equal(s.tracked, rec.tracked)
        np.testing.assert_allclose(s.t, rec.t, atol=1e-9)
        ok = rec.tracked
        np.testing.assert_allclose(s.position[ok], rec.position[ok], atol=1e-6)
        dots = np.abs(np.einsum("ij,ij->i", s.quat[ok], rec.quat[ok]))
        assert np.all(dots > 1 - 1e-9)


def test_session_file_holds_nominal_values(written):
    ride, out, _ = written
    s = load_session(out / "session.yaml")
    assert s.world_up == "y"
    assert s.rider.mass == 65.0  # nominal, not the true 73 kg
    assert s.euc == ride.session.euc and dict(s.rider.segments) == dict(ride.session.rider.segments)


def test_truth_files(written):
    ride, out, _ = written
    truth = json.loads((out / "truth" / "truth.json").read_text())
    assert truth["h_m"] == 0.61 and truth["seed"] == 4 and truth["effect"] == "rider_mass_error"
    assert truth["effect_parameters"] == {"delta_m_kg": 8.0}
    assert truth["true_parameters_that_differ"]["rider.mass"] == {"true": 73.0, "nominal": 65.0}
    assert [r["run"] for r in truth["runs"]] == ["deceleration_01", "deceleration_02"]
    run = ride.runs[1]
    with open(out / truth["runs"][1]["truth_csv"]) as f:
        header = f.readline().strip().split(",")
    table = np.loadtxt(out / truth["runs"][1]["truth_csv"], delimiter=",", skiprows=1)
    assert tuple(header) == TRUTH_COLUMNS
    assert table.shape == (run.t.size, len(TRUTH_COLUMNS))
    col = {c: table[:, i] for i, c in enumerate(header)}
    np.testing.assert_allclose(col["M_d"], run.M_d, rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(col["phi_ddot"], run.q_ddot[:, 2], rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(col["G_z"], run.G[:, 2], rtol=1e-11)
    np.testing.assert_array_equal(col["frame"], run.frame)


def test_bag_holds_posestamped_per_body(written):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    ride, out, _ = written
    run = ride.runs[0]
    rec = run.mocap
    bag = out / f"{run.name}_bag"
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        topics = {c.topic: c for c in reader.connections}
        assert set(topics) == {f"/vrpn_mocap/{b}/pose" for b in rec.bodies}
        assert {c.msgtype for c in reader.connections} == {"geometry_msgs/msg/PoseStamped"}
        i = rec.bodies.index("H")
        conn = topics["/vrpn_mocap/H/pose"]
        msgs = [(ts, reader.deserialize(raw, conn.msgtype)) for _, ts, raw in reader.messages(connections=[conn])]
    assert len(msgs) == int(rec.tracked[i].sum())  # untracked samples are not published
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in msgs])
    assert all(m.header.frame_id == "world" for _, m in msgs)
    np.testing.assert_array_equal(stamps, [ts for ts, _ in msgs])
    frames = rec.frame[rec.tracked[i]]
    np.testing.assert_allclose((stamps - stamps[0]) / 1e9, (frames - frames[0]) / 120.0, atol=1e-9)
    pos = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z] for _, m in msgs])
    np.testing.assert_array_equal(pos, rec.position[i][rec.tracked[i]])  # Z-up, exact


def test_cli_writes_a_deterministic_ride(tmp_path, capsys):
    argv = ["simulate-ride", "--maneuver", "deceleration", "--runs", "1", "--effect", "ground_slope",
            "--param", "alpha_deg=3", "--seed", "7", "--duration", "1.5"]
    assert cli_main(argv + ["--out", str(tmp_path / "a")]) == 0
    assert cli_main(argv + ["--out", str(tmp_path / "b")]) == 0
    assert "deceleration_01" in capsys.readouterr().out
    a, b = (tmp_path / d / "deceleration_01.csv" for d in "ab")
    assert a.read_bytes() == b.read_bytes()
    truth = json.loads((tmp_path / "a" / "truth" / "truth.json").read_text())
    assert truth["effect_parameters"] == {"alpha_deg": 3.0} and truth["seed"] == 7


def test_cli_method_option_is_recorded_in_the_truth(tmp_path):
    argv = ["simulate-ride", "--runs", "1", "--duration", "0.5", "--no-progress", "--method", "reference",
            "--out", str(tmp_path)]
    assert cli_main(argv) == 0
    truth = json.loads((tmp_path / "truth" / "truth.json").read_text())
    assert truth["runs"][0]["solver"]["method"] == "reference"


def test_cli_reports_user_errors_with_exit_code_2(tmp_path, capsys):
    assert cli_main(["simulate-ride", "--effect", "gravity_off", "--out", str(tmp_path)]) == 2
    assert cli_main(["simulate-ride", "--param", "c_rr=0.1", "--out", str(tmp_path)]) == 2
    assert cli_main(["simulate-ride", "--maneuver", "wheelie", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "gravity_off" in err and "c_rr" in err and "wheelie" in err


def test_bag_round_trips_through_the_projects_reader(written):
    if importlib.util.find_spec("euc_ros.core.io.bags") is None:
        pytest.skip("euc_ros.core.io.bags not available yet")
    from euc_ros.core.io.bags import read_mocap_bag

    ride, out, _ = written
    run = ride.runs[1]
    rec = run.mocap
    s = read_mocap_bag(out / f"{run.name}_bag", bodies=rec.bodies)
    np.testing.assert_allclose(s.t - s.t[0], rec.t - rec.t[0], atol=1e-9)
    np.testing.assert_array_equal(s.tracked, rec.tracked)
    ok = rec.tracked
    np.testing.assert_array_equal(s.position[ok], rec.position[ok])


def test_vectorized_cdr_equals_the_typestore_serializer():
    from rosbags.typesys import Stores, get_typestore

    from euc_ros.core.ridesim.writers import posestamped_cdr_block

    ts = get_typestore(Stores.ROS2_JAZZY)
    T = ts.types
    rng = np.random.default_rng(0)
    stamps = np.array([1714644900_123456789, 1714644901_000000001, 5], dtype=np.int64)
    pos, quat = rng.normal(size=(3, 3)), rng.normal(size=(3, 4))
    raw = posestamped_cdr_block(stamps, pos, quat)
    for k in range(3):
        msg = T["geometry_msgs/msg/PoseStamped"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                sec=int(stamps[k] // 10**9), nanosec=int(stamps[k] % 10**9)), frame_id="world"),
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=pos[k, 0], y=pos[k, 1], z=pos[k, 2]),
                orientation=T["geometry_msgs/msg/Quaternion"](x=quat[k, 0], y=quat[k, 1], z=quat[k, 2], w=quat[k, 3])))
        assert raw[k].tobytes() == bytes(ts.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped"))
