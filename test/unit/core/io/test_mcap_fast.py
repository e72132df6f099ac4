"""Fast bag reading (mcap_fast + fixed-layout CDR with numpy) against the rosbags route as the reference."""
# covers: euc_ros/core/io/bags/fast_mcap.py
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from euc_ros.core.io import bags
from euc_ros.core.io.bags import BagWriter, read_bag, read_mocap_bag, write_mocap_bag
from euc_ros.core.io.bags import mocap as mocap_bags
from euc_ros.core.io.bags.common import bag_info
from euc_ros.core.io.bags.fast_mcap import read_mocap_fast
from euc_ros.core.io.mcap_fast import McapFile, read_channels
from euc_ros.core.io.msgdefs import make_typestore
from euc_ros.core.mocap.series import MocapSeries

START_NS = 1_700_000_000_987_654_321


def make_series(n=400, b=5, seed=3, dropped=()) -> MocapSeries:
    rng = np.random.default_rng(seed)
    frame = 100 + np.arange(n + len(dropped), dtype=np.int64)
    frame = np.delete(frame, list(dropped))                  # dropped frames: gaps in numbers and times
    t = 0.5 + (frame - 100) / 120.0
    pos = rng.normal(size=(b, n, 3))
    q = rng.normal(size=(b, n, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    tracked = rng.random((b, n)) > 0.2
    tracked[2, 50:120] = False
    tracked[b - 1] = False                                   # never tracked
    err = np.where(tracked, rng.random((b, n)) * 1e-3, np.nan)
    bodies = ["E", "H", "TL", "LAR", "CHL", "UAL"][:b]
    return MocapSeries(t, frame, bodies, np.where(tracked[..., None], pos, np.nan),
                       np.where(tracked[..., None], q, np.nan), tracked, err, name="fast_01",
                       meta={"start_ns": START_NS, "rate_hz": 120.0})


def reference(bag: Path, **kw) -> MocapSeries:
    """read_mocap_bag through rosbags only (the fast path switched off for this call, where the reader looks
    it up)."""
    fast = mocap_bags.read_mocap_fast
    mocap_bags.read_mocap_fast = lambda *a, **k: None
    try:
        return read_mocap_bag(bag, **kw)
    finally:
        mocap_bags.read_mocap_fast = fast


def takes_fast_path(bag: Path, prefix="/vrpn_mocap", frame_topic=None) -> bool:
    return read_mocap_fast(Path(bag), bag_info(Path(bag)), prefix, frame_topic, 0.25) is not None


def assert_same(got: MocapSeries, want: MocapSeries) -> None:
    assert got.bodies == want.bodies and got.name == want.name and got.meta == want.meta
    for field in ("t", "frame", "position", "quat", "tracked", "mean_marker_error"):
        a, b = getattr(got, field), getattr(want, field)
        assert a.dtype == b.dtype and a.shape == b.shape, field
        np.testing.assert_array_equal(a, b, err_msg=field)          # NaN == NaN here


@pytest.fixture(scope="session")
def bag_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fast")


@pytest.fixture(scope="session")
def full_bag(bag_dir):
    series = make_series(dropped=(7, 8, 200))
    write_mocap_bag(series, bag_dir / "full", chunk_size=16 << 10)   # many chunks
    return bag_dir / "full", series


def test_mcap_reader_matches_rosbags_messages(full_bag):
    bag, _ = full_bag
    mcap = McapFile(bag / "full.mcap")
    assert mcap.summary is not None and len(mcap.summary.chunks) > 3
    by_topic = {c.topic: c.id for c in mcap.channels.values()}
    for topic in ("/mocap/frame", "/vrpn_mocap/H/pose"):
        want = [(stamp, data) for _, _, stamp, data in read_bag(bag, topics=[topic], raw=True)]
        got = read_channels(bag / "full.mcap", [by_topic[topic]])
        assert len(got) == len(want) > 0
        np.testing.assert_array_equal(got.log_time, [s for s, _ in want])
        assert [got.raw(i) for i in range(len(got))] == [d for _, d in want]
    # several channels merged in receive-time order, ties in file order, as rosbags yields them
    topics = ["/vrpn_mocap/E/pose", "/vrpn_mocap/TL/pose", "/mocap/frame"]
    want = [(stamp, data) for _, _, stamp, data in read_bag(bag, topics=topics, raw=True)]
    got = mcap.messages([by_topic[t] for t in topics])
    np.testing.assert_array_equal(got.log_time, [s for s, _ in want])
    assert [got.raw(i) for i in range(len(got))] == [d for _, d in want]


def test_frames_fast_equals_rosbags(full_bag):
    bag, series = full_bag
    assert takes_fast_path(bag)
    got = read_mocap_bag(bag)
    assert_same(got, reference(bag))
    np.testing.assert_array_equal(got.frame, series.frame)              # dropped frames kept as gaps
    np.testing.assert_array_equal(got.tracked, series.tracked)
    np.testing.assert_array_equal(got.position, series.position)
    assert got.meta["source"] == f"{bags.MOCAP_FRAME} /mocap/frame"
    sub = read_mocap_bag(bag, bodies=["TL", "E"], frame_topic="/mocap/frame")
    assert_same(sub, reference(bag, bodies=["TL", "E"], frame_topic="/mocap/frame"))


@pytest.mark.parametrize("frame_id", ["world", "map_frame_x"])
def test_poses_fast_equals_rosbags(bag_dir, frame_id):
    series = make_series(n=300, b=4, seed=9, dropped=(3, 150))
    bag = bag_dir / f"poses_{frame_id}"
    write_mocap_bag(series, bag, frame_topic=None, frame_id=frame_id, chunk_size=8 << 10)
    assert takes_fast_path(bag)
    got = read_mocap_bag(bag)
    assert got.bodies == ["E", "H", "TL"]                                # the never-tracked body has no topic
    assert_same(got, reference(bag))


def test_default_chunks_without_marker_errors(bag_dir):
    series = make_series(n=250, b=3, seed=4)
    series.mean_marker_error[:] = np.nan
    bag = bag_dir / "one_chunk"
    write_mocap_bag(series, bag, poses=False, frame_id="")
    assert takes_fast_path(bag)
    got = read_mocap_bag(bag)
    assert_same(got, reference(bag))
    assert np.isnan(got.mean_marker_error).all()


def _frame(ts, stamp_ns, names, rng, frame_number):
    T = ts.types
    Pose, Point, Quat = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    poses = [Pose(position=Point(x=float(a), y=float(b), z=float(c)), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0))
             for a, b, c in rng.normal(size=(len(names), 3))]
    return T[bags.MOCAP_FRAME](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9,
                                                                               nanosec=stamp_ns % 10**9),
                                        frame_id="world"),
        stamp_source=1, frame_number=frame_number, body_names=list(names), poses=poses,
        tracked=np.ones(len(names), bool), mean_marker_error=np.full(len(names), 1e-4, np.float32))


@pytest.mark.parametrize("second", [["E", "H", "TL"], ["H", "E"], ["E", "X"]],
                         ids=["more_bodies", "swapped_same_length", "renamed_same_length"])
def test_varying_body_names_fall_back(bag_dir, second):
    ts = make_typestore()
    rng = np.random.default_rng(1)
    bag = bag_dir / ("vary_" + "_".join(second))
    with BagWriter(bag, ts, chunk_size=4096) as w:
        for i in range(60):
            names = ["E", "H"] if i < 30 else second
            stamp = START_NS + i * 10_000_000
            w.write("/mocap/frame", bags.MOCAP_FRAME, _frame(ts, stamp, names, rng, -1 if i == 5 else i), stamp)
    assert not takes_fast_path(bag)
    got = read_mocap_bag(bag)
    assert_same(got, reference(bag))
    assert set(got.bodies) == {"E", "H"} | set(second)
    col = got.bodies.index("H")
    assert got.tracked[col].sum() == (60 if "H" in second else 30)


def test_receive_times_out_of_order_match_rosbags(bag_dir):
    """Receive times not monotonic across chunks: both routes sort the same way (then by header stamp)."""
    ts = make_typestore()
    rng = np.random.default_rng(6)
    bag = bag_dir / "shuffled"
    recv = START_NS + rng.permutation(80) * 5_000_000
    with BagWriter(bag, ts, chunk_size=2048) as w:
        for i in range(80):
            stamp = START_NS + (i - (i % 10 == 9)) * 8_000_000  # some duplicate header stamps: ties kept stable
            w.write("/mocap/frame", bags.MOCAP_FRAME, _frame(ts, stamp, ["E", "H"], rng, i), int(recv[i]))
    assert takes_fast_path(bag)
    assert_same(read_mocap_bag(bag), reference(bag))


def test_unindexed_or_compressed_mcap_is_not_read_fast(full_bag, tmp_path):
    bag, _ = full_bag
    data = (bag / "full.mcap").read_bytes()
    # A footer saying "no summary" (as a writer without summary writes): the reader declines.
    footer_at = len(data) - 8 - 29
    broken = data[:footer_at + 9] + struct.pack("<QQI", 0, 0, 0) + data[footer_at + 29:]
    (tmp_path / "nosummary.mcap").write_bytes(broken)
    assert McapFile(tmp_path / "nosummary.mcap").summary is None
    assert read_channels(tmp_path / "nosummary.mcap", [1]) is None
    # Empty and truncated files.
    (tmp_path / "empty.mcap").write_bytes(b"")
    (tmp_path / "half.mcap").write_bytes(data[:len(data) // 2])
    for name in ("empty.mcap", "half.mcap", "missing.mcap"):
        assert read_channels(tmp_path / name, [1]) is None
    # A chunk marked compressed: declined for channels in that chunk.
    mcap = McapFile(bag / "full.mcap")
    chunk = mcap.summary.chunks[0]
    cid = next(iter(chunk.index_offsets))
    object.__setattr__(chunk, "compression", "zstd")
    assert mcap.messages([cid]) is None


def test_fast_path_errors_match(full_bag):
    bag, _ = full_bag
    from euc_ros.core.errors import InputError

    with pytest.raises(InputError, match="no euc_msgs/msg/MocapFrame topic /other"):
        read_mocap_bag(bag, frame_topic="/other")


@pytest.mark.ros
def test_rclpy_serialized_frames_take_the_fast_path(bag_dir):
    """Recorder-style bags: rclpy's serializer leaves padding bytes unset; the layout check ignores padding."""
    pytest.importorskip("rclpy")
    euc_msg = pytest.importorskip("euc_msgs.msg")
    from builtin_interfaces.msg import Time
    from geometry_msgs.msg import Point, Pose, Quaternion
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Header

    series = make_series(n=120, b=4, seed=12, dropped=(30,))
    stamps = START_NS + np.round(series.t * 1e9).astype(np.int64)
    bag = bag_dir / "rclpy"
    with BagWriter(bag, chunk_size=4096) as w:
        for i in range(series.n_frames):
            trk = series.tracked[:, i]
            msg = euc_msg.MocapFrame(
                header=Header(stamp=Time(sec=int(stamps[i] // 10**9), nanosec=int(stamps[i] % 10**9)),
                              frame_id="world"),
                stamp_source=0, frame_number=int(series.frame[i]), body_names=list(series.bodies),
                poses=[Pose(position=Point(x=float(p[0]), y=float(p[1]), z=float(p[2])),
                            orientation=Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])))
                       for p, q in zip(series.position[:, i], series.quat[:, i])],
                tracked=[bool(x) for x in trk], mean_marker_error=series.mean_marker_error[:, i].astype(np.float32))
            w.write_raw("/mocap/frame", bags.MOCAP_FRAME, bytes(serialize_message(msg)), int(stamps[i]))
    assert takes_fast_path(bag)
    got = read_mocap_bag(bag)
    assert_same(got, reference(bag))
    np.testing.assert_array_equal(got.position, series.position)
    np.testing.assert_array_equal(got.frame, series.frame)
