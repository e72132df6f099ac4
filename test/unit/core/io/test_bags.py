"""Bags: BagWriter round trips read back by two independent readers, structural checks, recovery, mocap series.

Tolerances: stamps are stored in integer nanoseconds, so times read back differ by at most half a
nanosecond plus one ulp of the time: atol 1e-9 s.
"""
# covers: euc_ros/core/io/msgdefs.py
# covers: euc_ros/core/io/bags/writer.py
# covers: euc_ros/core/io/bags/reader.py
# covers: euc_ros/core/io/bags/check.py
# covers: euc_ros/core/io/bags/recovery.py
# covers: euc_ros/core/io/bags/inspection.py
# covers: euc_ros/core/io/bags/common.py
# covers: euc_ros/core/io/bags/mocap.py
# covers: euc_ros/core/io/bags/posestamped.py
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from euc_ros.core.errors import InputError
from euc_ros.core.io import bags
from euc_ros.core.io.bags import BagWriter, check_bag, inspect_bag, read_bag, read_mocap_bag, recover_bag
from euc_ros.core.io.bags.common import scan_mcap
from euc_ros.core.io.msgdefs import euc_msgs_definitions, make_typestore
from euc_ros.core.mocap.series import MocapSeries

START_NS = 1_700_000_000_123_456_789
REPO = Path(__file__).resolve().parents[4]


# ---------------------------------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------------------------------

def assert_msg_equal(expected, got, where="msg"):
    """Field-by-field equality of a rosbags message and a message read back (rosbags or mcap_ros2 object)."""
    fields = getattr(expected, "__dataclass_fields__", None)
    if fields is not None:
        for name in fields:
            if name.startswith("__") or name.isupper():
                continue                                     # __msgtype__, constants
            assert hasattr(got, name), f"{where}.{name} missing"
            assert_msg_equal(getattr(expected, name), getattr(got, name), f"{where}.{name}")
    elif isinstance(expected, np.ndarray) and expected.dtype.kind in "biuf":
        np.testing.assert_array_equal(np.asarray(got, dtype=expected.dtype), expected, err_msg=where)
    elif isinstance(expected, (list, tuple, np.ndarray)):
        assert len(got) == len(expected), where
        for k, (e, g) in enumerate(zip(expected, got)):
            assert_msg_equal(e, g, f"{where}[{k}]")
    elif isinstance(expected, float):
        assert (np.isnan(expected) and np.isnan(got)) or expected == got, f"{where}: {got} != {expected}"
    else:
        assert got == expected, f"{where}: {got!r} != {expected!r}"


def make_messages(ts, rng):
    """(topic, msgtype, msg, stamp_ns) of standard and euc_msgs types with varied, known content."""
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    Point, Quat, Pose = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"], T["geometry_msgs/msg/Pose"]
    out = []
    for i in range(40):
        stamp = START_NS + i * 8_333_333
        hdr = Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="world" if i % 3 else "w")
        p = rng.normal(size=7)
        pose = Pose(position=Point(x=p[0], y=p[1], z=p[2]), orientation=Quat(x=p[3], y=p[4], z=p[5], w=p[6]))
        out.append(("/vrpn_mocap/E/pose", "geometry_msgs/msg/PoseStamped",
                    T["geometry_msgs/msg/PoseStamped"](header=hdr, pose=pose), stamp))
        out.append(("/chatter", "std_msgs/msg/String", T["std_msgs/msg/String"](data=f"msg {i} \u00e9"), stamp + 1))
        names = ["E", "H", "TL"][: 1 + i % 3]
        trk = np.array([(i + k) % 4 != 0 for k in range(len(names))])
        poses = [Pose(position=Point(x=float(k), y=np.nan if not trk[k] else 0.5, z=-1.0),
                      orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0)) for k in range(len(names))]
        out.append(("/mocap/frame", "euc_msgs/msg/MocapFrame", T["euc_msgs/msg/MocapFrame"](
            header=hdr, stamp_source=1, frame_number=1000 + i, body_names=names, poses=poses, tracked=trk,
            mean_marker_error=rng.random(len(names)).astype(np.float32)), stamp + 2))
        out.append(("/torque", "euc_msgs/msg/TorqueEstimate", T["euc_msgs/msg/TorqueEstimate"](
            header=hdr, valid=bool(i % 2), m_d1=rng.normal(), m_d2=rng.normal(), m_d1_2dof=np.nan, m_d2_2dof=-0.0,
            h=0.61, residual=rng.normal(), rmse_window=1.5, window=2.0, h_online=0.6, h_online_std=np.inf,
            model="3dof+ground_slope", h_online_status="not yet (1.2 of 7.5 s of valid states)"), stamp + 3))
    rs = T["euc_msgs/msg/RiderState"]
    kw = {name: float(k) for k, name in enumerate(
        ["x", "x_dot", "x_ddot", "gamma", "gamma_dot", "gamma_ddot", "phi", "phi_dot", "phi_ddot", "phi_eq3",
         "phi_hinge", "psi", "theta", "filter_lag"])}
    out.append(("/rider_state", "euc_msgs/msg/RiderState", rs(
        header=Header(stamp=Time(sec=1, nanosec=2), frame_id="world"), has_rider=True, phi_definition="hinge",
        c=Point(x=1.0, y=2.0, z=3.0), g=Point(x=-1.0, y=-2.0, z=4.0), **kw), START_NS + 10**9))
    return out


@pytest.fixture(scope="session")
def written(tmp_path_factory):
    """A bag written with BagWriter (small chunks) and the messages that went in."""
    ts = make_typestore()
    msgs = make_messages(ts, np.random.default_rng(3))
    path = tmp_path_factory.mktemp("bags") / "std_and_euc"
    with BagWriter(path, ts, chunk_size=2048) as w:
        for topic, msgtype, msg, stamp in msgs:
            w.write(topic, msgtype, msg, stamp)
    return path, msgs, dict(w.counts)


def mocap_series(n=500, b=4, seed=5) -> MocapSeries:
    rng = np.random.default_rng(seed)
    t = 0.25 + np.arange(n) / 120.0
    pos = rng.normal(size=(b, n, 3))
    q = rng.normal(size=(b, n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    tracked = rng.random((b, n)) > 0.15
    tracked[1, 100:180] = False                     # a long gap
    tracked[3, :] = False                           # a body never seen
    err = rng.random((b, n)) * 1e-3
    nan3 = np.where(tracked[..., None], pos, np.nan)
    nan4 = np.where(tracked[..., None], q, np.nan)
    return MocapSeries(t, 5000 + np.arange(n, dtype=np.int64), ["E", "H", "TL", "LL"], nan3, nan4, tracked,
                       np.where(tracked, err, np.nan), name="decel_01", meta={"start_ns": START_NS, "rate_hz": 120.0})


def copy_bag(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def mcap_of(bag: Path) -> Path:
    return next(bag.glob("*.mcap"))


def edit_metadata(bag: Path, edit) -> None:
    meta = bag / "metadata.yaml"
    doc = yaml.safe_load(meta.read_text())
    edit(doc["rosbag2_bagfile_information"])
    meta.write_text(yaml.safe_dump(doc))


# ---------------------------------------------------------------------------------------------------------------------
# Writing and reading back
# ---------------------------------------------------------------------------------------------------------------------

def test_roundtrip_with_rosbags_anyreader(written):
    path, msgs, counts = written
    got = list(read_bag(path))
    assert len(got) == len(msgs)
    expected = sorted(msgs, key=lambda m: m[3])
    for (topic, msgtype, msg, stamp), (gtopic, gtype, gstamp, gmsg) in zip(expected, got):
        assert (gtopic, gtype, gstamp) == (topic, msgtype, stamp)
        assert_msg_equal(msg, gmsg, topic)
    assert counts == {"/vrpn_mocap/E/pose": 40, "/chatter": 40, "/mocap/frame": 40, "/torque": 40,
                      "/rider_state": 1}
    only = list(read_bag(path, topics=["/torque"]))
    assert [m[0] for m in only] == ["/torque"] * 40


def test_roundtrip_with_mcap_ros2_reader(written):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    path, msgs, _ = written
    expected = sorted(msgs, key=lambda m: m[3])
    with open(mcap_of(path), "rb") as f:
        decoded = list(make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(log_time_order=True))
    assert len(decoded) == len(expected)
    for (topic, msgtype, msg, stamp), (schema, channel, message, ros_msg) in zip(expected, decoded):
        assert (channel.topic, schema.name, message.log_time) == (topic, msgtype, stamp)
        assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
        assert_msg_equal(msg, ros_msg, topic)


def test_metadata_hashes_equal_rosidl(written):
    """type_description_hash of euc_msgs in the bag = the hash rosidl generated for the built package."""
    path, _, _ = written
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    hashes = {t["topic_metadata"]["type"]: t["topic_metadata"]["type_description_hash"]
              for t in info["topics_with_message_count"]}
    share = Path(sys.prefix) / "share" / "euc_msgs" / "msg"
    if not share.is_dir():
        pytest.skip("euc_msgs not built into this environment")
    for name in ("MocapFrame", "TorqueEstimate", "RiderState"):
        doc = json.loads((share / f"{name}.json").read_text())
        rosidl = {h["type_name"]: h["hash_string"] for h in doc["type_hashes"]}
        assert hashes[f"euc_msgs/msg/{name}"] == rosidl[f"euc_msgs/msg/{name}"]


def test_msgdefs_fall_back_to_repository(monkeypatch, tmp_path):
    from euc_ros.core.io import msgdefs

    installed = euc_msgs_definitions()
    assert set(installed) >= {"euc_msgs/msg/MocapFrame", "euc_msgs/msg/RiderState"}
    monkeypatch.setattr(msgdefs.sys, "prefix", str(tmp_path))          # no share/ there
    repo = msgdefs.euc_msgs_definitions()
    assert repo == {k: (REPO / "msg_defs" / "msg" / f"{k.split('/')[-1]}.msg").read_text() for k in repo}
    monkeypatch.setattr(msgdefs, "REPO_MSG_DIR", tmp_path / "nothing")
    with pytest.raises(InputError, match="no euc_msgs"):
        msgdefs.euc_msgs_definitions()


def test_writer_keeps_everything_on_exception(tmp_path):
    ts = make_typestore()
    String = ts.types["std_msgs/msg/String"]
    with pytest.raises(RuntimeError, match="boom"):
        with BagWriter(tmp_path / "b", ts) as w:
            for i in range(5):
                w.write("/s", "std_msgs/msg/String", String(data=str(i)), START_NS + i)
            raise RuntimeError("boom")
    assert check_bag(tmp_path / "b") == []
    assert [m.data for _, _, _, m in read_bag(tmp_path / "b")] == ["0", "1", "2", "3", "4"]


def test_check_accepts_a_topic_that_received_nothing(tmp_path):
    # a recorder registers a topic when its subscription matches; if no message came before the
    # stop, the writer's statistics count that channel 0 and no record exists: a complete bag
    ts = make_typestore()
    String = ts.types["std_msgs/msg/String"]
    with BagWriter(tmp_path / "b", ts) as w:
        w.connection("/silent", "std_msgs/msg/String")
        for i in range(3):
            w.write("/s", "std_msgs/msg/String", String(data=str(i)), START_NS + i)
    assert check_bag(tmp_path / "b") == []
    counts = {t["name"]: t["count"] for t in inspect_bag(tmp_path / "b")["topics"]}
    assert counts == {"/silent": 0, "/s": 3}


def test_writer_errors(tmp_path):
    (tmp_path / "exists").mkdir()
    with pytest.raises(InputError, match="exists already"):
        BagWriter(tmp_path / "exists")
    with BagWriter(tmp_path / "b") as w:
        with pytest.raises(InputError, match="no definition for message type nope_msgs/msg/X"):
            w.write_raw("/x", "nope_msgs/msg/X", b"\x00\x01\x00\x00", START_NS)
        w.close()
        with pytest.raises(InputError, match="closed"):
            w.write_raw("/y", "std_msgs/msg/String", b"\x00\x01\x00\x00\x01\x00\x00\x00\x00", START_NS)
    assert w.closed


def _string_cdr(text: str) -> bytes:
    raw = text.encode() + b"\x00"
    return b"\x00\x01\x00\x00" + len(raw).to_bytes(4, "little") + raw


@pytest.mark.parametrize("chunk_size", [256, 4096, 1 << 20, 1 << 22])
def test_write_raw_many_writes_the_bytes_of_write_raw(tmp_path, chunk_size):
    """The batch path (records and chunks packed here) against write_raw (rosbags' writer): same file."""
    rng = np.random.default_rng(chunk_size)
    msgs = []
    for i in range(3000):
        topic = ("/a", "/b", "/c")[int(rng.integers(3))]
        size = 2000 if topic == "/c" and i % 7 == 0 else int(rng.integers(0, 60))   # some past small chunks
        msgs.append((topic, _string_cdr("x" * size + str(i)), START_NS + i // 3))
    with BagWriter(tmp_path / "one" / "bag", chunk_size=chunk_size) as w:
        for topic, data, stamp in msgs:
            w.write_raw(topic, "std_msgs/msg/String", data, stamp)
    with BagWriter(tmp_path / "many" / "bag", chunk_size=chunk_size) as w:
        i = 0
        while i < len(msgs):                       # runs of one topic, as a recorder's takes come
            j = i + 1
            while j < len(msgs) and msgs[j][0] == msgs[i][0] and j - i < 40:
                j += 1
            stamps = [m[2] for m in msgs[i:j]]
            stamp = stamps[0] if len(set(stamps)) == 1 else stamps
            w.write_raw_many(msgs[i][0], "std_msgs/msg/String", [m[1] for m in msgs[i:j]], stamp)
            i = j
        w.write_raw_many("/a", "std_msgs/msg/String", [], START_NS)
        assert w.counts == {t: sum(m[0] == t for m in msgs) for t in ("/a", "/b", "/c")}
    for name in ("bag.mcap", "metadata.yaml"):
        assert (tmp_path / "many" / "bag" / name).read_bytes() == (tmp_path / "one" / "bag" / name).read_bytes()
    assert check_bag(tmp_path / "many" / "bag") == []
    assert [m.data for _, _, _, m in read_bag(tmp_path / "many" / "bag", topics=["/b"])] == \
        [m[1][8:-1].decode() for m in msgs if m[0] == "/b"]


def test_write_raw_many_errors(tmp_path):
    with BagWriter(tmp_path / "b") as w:
        with pytest.raises(ValueError, match="2 messages but 1 stamps"):
            w.write_raw_many("/s", "std_msgs/msg/String", [_string_cdr("a")] * 2, [START_NS])
        w.close()
        with pytest.raises(InputError, match="closed"):
            w.write_raw_many("/y", "std_msgs/msg/String", [_string_cdr("a")], START_NS)


def test_small_chunks_are_used(written):
    path, _, _ = written
    scan, _ = scan_mcap(mcap_of(path))
    assert scan.n_chunks >= 10 and scan.footer and scan.error is None


def test_posestamped_cdr_matches_rosbags_serializer():
    """The vectorized PoseStamped codec against rosbags' general CDR serializer (independent route)."""
    ts = make_typestore()
    T = ts.types
    rng = np.random.default_rng(11)
    stamps = np.array([START_NS, -1_500_000_000, 0, 2**40 + 7])
    pos, quat = rng.normal(size=(4, 3)), rng.normal(size=(4, 4))
    for frame_id in ("", "w", "world", "map_frame_1234"):             # every alignment of the pose block
        ours = bags.posestamped_cdr(stamps, pos, quat, frame_id)
        for k in range(4):
            sec, nsec = divmod(int(stamps[k]), 10**9)
            msg = T["geometry_msgs/msg/PoseStamped"](
                header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                                frame_id=frame_id),
                pose=T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](x=pos[k, 0], y=pos[k, 1], z=pos[k, 2]),
                    orientation=T["geometry_msgs/msg/Quaternion"](x=quat[k, 0], y=quat[k, 1], z=quat[k, 2],
                                                                   w=quat[k, 3])))
            assert ours[k] == bytes(ts.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped")), frame_id
        s, p, q = bags.posestamped_arrays(ours)
        np.testing.assert_array_equal(s, stamps)
        np.testing.assert_array_equal(p, pos)
        np.testing.assert_array_equal(q, quat)


# ---------------------------------------------------------------------------------------------------------------------
# Structural check and recovery
# ---------------------------------------------------------------------------------------------------------------------

def test_check_passes_on_good_bag(written):
    assert check_bag(written[0]) == []
    assert check_bag(mcap_of(written[0])) == []          # the .mcap path works too


def test_check_reports_truncated_file(written, tmp_path):
    bag = copy_bag(written[0], tmp_path / "cut")
    f = mcap_of(bag)
    data = f.read_bytes()
    f.write_bytes(data[: len(data) * 2 // 3])
    problems = check_bag(bag)
    assert any("truncated" in p and "recover_bag" in p for p in problems), problems


@pytest.mark.parametrize("edit, expect", [
    (lambda i: i["topics_with_message_count"][0]["topic_metadata"].__setitem__("offered_qos_profiles", ""),
     "offered_qos_profiles' must be a list"),
    (lambda i: i.__setitem__("message_count", "many"), "'rosbag2_bagfile_information.message_count' must be"),
    (lambda i: i["duration"].__setitem__("nanoseconds", -5), "duration.nanoseconds' must be a non-negative"),
    (lambda i: i.pop("ros_distro"), "missing key 'rosbag2_bagfile_information.ros_distro'"),
    (lambda i: i["files"][0].pop("starting_time"), "files[0].starting_time"),
    (lambda i: i["topics_with_message_count"][0]["topic_metadata"].__setitem__("type_description_hash", None),
     "type_description_hash' must be a string"),
    (lambda i: i.__setitem__("custom_data", ["a"]), "custom_data' must be a mapping"),
    (lambda i: i.__setitem__("version", 10), "newer than ROS 2 Jazzy"),
])
def test_check_names_metadata_type_problems(written, tmp_path, edit, expect):
    bag = copy_bag(written[0], tmp_path / "meta")
    edit_metadata(bag, edit)
    problems = check_bag(bag)
    assert any(expect in p for p in problems), problems


def test_check_reports_count_mismatch(written, tmp_path):
    bag = copy_bag(written[0], tmp_path / "count")

    def bump(info):
        for t in info["topics_with_message_count"]:
            if t["topic_metadata"]["name"] == "/torque":
                t["message_count"] = 39
        info["message_count"] -= 1
    edit_metadata(bag, bump)
    problems = check_bag(bag)
    assert any("message count of /torque: metadata.yaml says 39" in p for p in problems), problems


def test_check_reports_wrong_type_and_missing_files(written, tmp_path):
    bag = copy_bag(written[0], tmp_path / "type")
    edit_metadata(bag, lambda i: i["topics_with_message_count"][0]["topic_metadata"].__setitem__(
        "type", "std_msgs/msg/Empty"))
    assert any("metadata.yaml says std_msgs/msg/Empty" in p for p in check_bag(bag))
    mcap_of(bag).unlink()
    assert any("missing" in p for p in check_bag(bag))
    assert check_bag(tmp_path / "none")[0].endswith("no such bag directory")


def test_recover_truncated_copy(written, tmp_path):
    path, msgs, _ = written
    bag = copy_bag(path, tmp_path / "cut")
    (bag / "metadata.yaml").unlink()
    f = mcap_of(bag)
    data = f.read_bytes()
    f.write_bytes(data[: len(data) // 2])
    scan, _ = scan_mcap(f)
    report = recover_bag(bag)
    assert report["messages"] == scan.n_messages > 0 and report["chunks"] == scan.n_chunks
    assert report["stopped_at"] is not None
    assert check_bag(report["output"]) == []
    expected = sorted(msgs, key=lambda m: m[3])
    got = list(read_bag(report["output"]))
    assert len(got) == report["messages"] < len(expected)
    for (topic, msgtype, msg, stamp), (gtopic, gtype, gstamp, gmsg) in zip(expected, got):
        assert (gtopic, gtype, gstamp) == (topic, msgtype, stamp)
        assert_msg_equal(msg, gmsg, topic)
    with pytest.raises(InputError, match="exists already"):
        recover_bag(bag)                                    # never overwrites


def test_recover_nothing_raises(tmp_path):
    bag = tmp_path / "empty"
    bag.mkdir()
    (bag / "empty.mcap").write_bytes(bags.MCAP_MAGIC + b"\x01\x00")
    with pytest.raises(InputError, match="nothing to recover"):
        recover_bag(bag)


SIGKILL_CHILD = textwrap.dedent("""
    import sys
    from euc_ros.core.io.bags import BagWriter
    from euc_ros.core.io.msgdefs import make_typestore
    ts = make_typestore()
    String = ts.types["std_msgs/msg/String"]
    w = BagWriter(sys.argv[1], ts, chunk_size=1024)
    flushed = 0
    for i in range(500):
        w.write("/s", "std_msgs/msg/String", String(data="payload %04d " % i + "x" * 40), 10**18 + i)
        if w._n_chunks != getattr(w, "_seen", 0):
            w._seen = w._n_chunks
            flushed = i + 1
    print(500, flushed, flush=True)
    sys.stdin.read()          # wait to be killed
""")


def test_sigkilled_writer_is_reported_and_recovered(tmp_path):
    """A real SIGKILL: completed chunks reached the OS and are recovered; the open chunk is lost."""
    bag = tmp_path / "killed"
    env = {k: v for k, v in os.environ.items()}
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.Popen([sys.executable, "-c", SIGKILL_CHILD, str(bag)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=env, cwd=REPO)
    try:
        written, flushed = map(int, proc.stdout.readline().split())
    finally:
        proc.kill()
        proc.wait(timeout=30)
    assert written == 500 and 0 < flushed < written
    problems = check_bag(bag)
    assert any("metadata.yaml missing" in p for p in problems)
    assert any("truncated" in p for p in problems), problems
    report = recover_bag(bag, tmp_path / "rescued")
    assert report["messages"] == flushed
    assert check_bag(tmp_path / "rescued") == []
    got = [m.data for _, _, _, m in read_bag(tmp_path / "rescued")]
    assert got == ["payload %04d " % i + "x" * 40 for i in range(flushed)]


def test_inspect(written, tmp_path):
    info = inspect_bag(written[0])
    assert info["problems"] == [] and info["metadata_version"] == 9 and info["storage"] == "mcap"
    topics = {t["name"]: t for t in info["topics"]}
    assert topics["/mocap/frame"]["type"] == "euc_msgs/msg/MocapFrame" and topics["/mocap/frame"]["count"] == 40
    assert info["message_count"] == 161 and info["start_ns"] == START_NS
    assert info["end_ns"] == START_NS + 10**9
    assert info["duration_s"] == pytest.approx(1.0)
    with pytest.raises(InputError, match="no such bag"):
        inspect_bag(tmp_path / "nothing")


def test_inspect_gives_each_topic_its_own_rate(written, capsys):
    """A topic's rate is over its own first-to-last span, not the bag's: the 40 frames at 120 Hz span
    0.325 s of a bag that lasts 1 s (the rider state is written 1 s after the start)."""
    from euc_ros.cli.main import main

    info = inspect_bag(written[0])
    rates = {t["name"]: t["rate_hz"] for t in info["topics"]}
    for topic in ("/mocap/frame", "/vrpn_mocap/E/pose", "/chatter", "/torque"):
        assert rates[topic] == pytest.approx(1e9 / 8_333_333, rel=1e-9), topic
    assert rates["/rider_state"] is None                      # one message: no rate
    assert main(["inspect", str(written[0])]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.strip().startswith("/mocap/frame"))
    assert "120.00 Hz" in line, line


# ---------------------------------------------------------------------------------------------------------------------
# Mocap series
# ---------------------------------------------------------------------------------------------------------------------

@pytest.fixture(scope="session")
def series():
    return mocap_series()


def assert_series_equal(got: MocapSeries, want: MocapSeries, *, marker_error: str):
    assert got.bodies == want.bodies
    np.testing.assert_allclose(got.t, want.t, rtol=0, atol=1e-9)            # ns rounding of the stamps
    np.testing.assert_array_equal(got.tracked, want.tracked)
    np.testing.assert_array_equal(got.position, want.position)             # float64 end to end, NaN gaps
    np.testing.assert_array_equal(got.quat, want.quat)
    if marker_error == "float32":
        np.testing.assert_array_equal(got.mean_marker_error,
                                      want.mean_marker_error.astype(np.float32).astype(float))
    else:
        assert np.all(np.isnan(got.mean_marker_error))


def test_mocap_roundtrip_through_mocap_frame(series, tmp_path):
    counts = bags.write_mocap_bag(series, tmp_path / "m")
    assert counts["/mocap/frame"] == series.n_frames
    assert counts["/vrpn_mocap/H/pose"] == int(series.tracked[1].sum()) and "/vrpn_mocap/LL/pose" not in counts
    assert check_bag(tmp_path / "m") == []
    got = read_mocap_bag(tmp_path / "m")
    assert_series_equal(got, series, marker_error="float32")
    np.testing.assert_array_equal(got.frame, series.frame)
    assert got.meta["start_ns"] == START_NS and got.rate_hz == 120.0 and got.name == "decel_01"
    first = next(read_bag(tmp_path / "m", topics=["/mocap/frame"]))
    assert first[2] == START_NS + 250_000_000 and first[3].header.frame_id == "world"


def test_mocap_roundtrip_through_posestamped(series, tmp_path):
    bags.write_mocap_bag(series, tmp_path / "p", frame_topic=None)
    got = read_mocap_bag(tmp_path / "p")
    want = series.select(["E", "H", "TL"])                                   # LL never tracked: no topic
    seen = want.tracked.any(axis=0)             # a frame with no tracked body leaves no PoseStamped at all
    assert 0 < (~seen).sum() < 20
    want = MocapSeries(want.t[seen], want.frame[seen], want.bodies, want.position[:, seen], want.quat[:, seen],
                       want.tracked[:, seen], want.mean_marker_error[:, seen])
    assert_series_equal(got, want, marker_error="nan")
    np.testing.assert_array_equal(got.frame, np.round(got.t * 120.0).astype(np.int64))
    sub = read_mocap_bag(tmp_path / "p", bodies=["TL", "E"])
    assert sub.bodies == ["TL", "E"]
    np.testing.assert_array_equal(sub.position[0], want.position[2])
    with pytest.raises(InputError, match="'HL' not in recording"):
        read_mocap_bag(tmp_path / "p", bodies=["HL"])
    with pytest.raises(InputError, match="no euc_msgs/msg/MocapFrame topic /mocap/frame"):
        read_mocap_bag(tmp_path / "p", frame_topic="/mocap/frame")


def test_posestamped_stamps_with_jitter_are_merged(tmp_path):
    """vrpn-style bags: each body stamped with a few microseconds of jitter still lands in one frame."""
    ts = make_typestore()
    rng = np.random.default_rng(2)
    n = 40                                          # frames 3, 10, ... lack E; 5, 13, ... lack H; none lacks both
    base = START_NS + (np.arange(n) * 1e9 / 100).astype(np.int64)
    with BagWriter(tmp_path / "j", ts) as w:
        for body, shift in (("E", 0), ("H", 1)):
            stamps = base + rng.integers(-20_000, 20_000, n) if shift else base
            keep = np.arange(n) % (7 + shift) != 3 + 2 * shift
            cdr = bags.posestamped_cdr(stamps[keep], np.full((keep.sum(), 3), shift), np.tile([0, 0, 0, 1.0],
                                                                                               (keep.sum(), 1)))
            for s, c in zip(stamps[keep], cdr):
                w.write_raw(f"/vrpn_mocap/{body}/pose", "geometry_msgs/msg/PoseStamped", c, s)
    got = read_mocap_bag(tmp_path / "j")
    assert got.n_frames == n and got.bodies == ["E", "H"]
    np.testing.assert_array_equal(got.tracked[0], np.arange(n) % 7 != 3)
    np.testing.assert_array_equal(got.tracked[1], np.arange(n) % 8 != 5)
    assert got.rate_hz == pytest.approx(100.0, rel=1e-3)


def test_read_mocap_bag_errors(written, tmp_path):
    with pytest.raises(InputError, match="no metadata.yaml"):
        read_mocap_bag(tmp_path)
    bag = tmp_path / "s"
    with BagWriter(bag) as w:
        w.write_raw("/chatter", "std_msgs/msg/String", b"\x00\x01\x00\x00\x01\x00\x00\x00\x00", START_NS)
    with pytest.raises(InputError, match="no euc_msgs/msg/MocapFrame topic and no"):
        read_mocap_bag(bag)


# ---------------------------------------------------------------------------------------------------------------------
# rclpy agrees with what we write
# ---------------------------------------------------------------------------------------------------------------------

@pytest.mark.ros
def test_rclpy_deserializes_our_mocap_frames(series, tmp_path):
    pytest.importorskip("rclpy")
    euc_msg = pytest.importorskip("euc_msgs.msg")
    from geometry_msgs.msg import Point, Pose, Quaternion
    from rclpy.serialization import deserialize_message, serialize_message

    bags.write_mocap_bag(series, tmp_path / "r")
    raws = [(m[2], m[3]) for m in read_bag(tmp_path / "r", topics=["/mocap/frame"], raw=True)]
    assert len(raws) == series.n_frames
    for i in (0, 101, series.n_frames - 1):
        stamp, raw = raws[i]
        msg = deserialize_message(raw, euc_msg.MocapFrame)
        assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == stamp
        assert msg.frame_number == series.frame[i] and list(msg.body_names) == series.bodies
        assert msg.stamp_source == euc_msg.MocapFrame.STAMP_FILE_TIME
        np.testing.assert_array_equal(np.asarray(msg.tracked, bool), series.tracked[:, i])
        pos = np.array([[p.position.x, p.position.y, p.position.z] for p in msg.poses])
        np.testing.assert_array_equal(pos, series.position[:, i])
        np.testing.assert_array_equal(np.asarray(msg.mean_marker_error, np.float32),
                                      series.mean_marker_error[:, i].astype(np.float32))
        # and rclpy's own serializer produces the same message
        again = euc_msg.MocapFrame(header=msg.header, stamp_source=msg.stamp_source, frame_number=msg.frame_number,
                                   body_names=list(msg.body_names),
                                   poses=[Pose(position=Point(x=p.position.x, y=p.position.y, z=p.position.z),
                                               orientation=Quaternion(x=p.orientation.x, y=p.orientation.y,
                                                                      z=p.orientation.z, w=p.orientation.w))
                                          for p in msg.poses],
                                   tracked=list(msg.tracked), mean_marker_error=msg.mean_marker_error)
        theirs = bytes(serialize_message(again))
        assert len(theirs) == len(raw)          # same layout; padding bytes differ (Fast-CDR leaves them unset)
        ts = make_typestore()
        assert_msg_equal(ts.deserialize_cdr(raw, "euc_msgs/msg/MocapFrame"),
                         ts.deserialize_cdr(theirs, "euc_msgs/msg/MocapFrame"), "rclpy")


def test_metadata_names_the_ros_distribution_as_rosbag2_does(tmp_path):
    """rosbag2 writes the ROS_DISTRO it runs on; rosbags' writer says "rosbags"."""
    import yaml

    from euc_ros.core.io.bags import BagWriter, check_bag

    with BagWriter(tmp_path / "b") as w:
        w.write_raw("/chatter", "std_msgs/msg/String", bytes([0, 1, 0, 0, 3, 0, 0, 0, 104, 105, 0, 0]), 5)
    info = yaml.safe_load((tmp_path / "b" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["ros_distro"] == "jazzy" and info["version"] == 9
    assert check_bag(tmp_path / "b") == []
