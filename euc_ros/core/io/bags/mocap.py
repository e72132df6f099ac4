"""Mocap series to and from bags: :func:`write_mocap_bag` and :func:`read_mocap_bag`.

The bags hold ``euc_msgs/msg/MocapFrame``, ``mocap4r2_msgs/msg/RigidBodies`` and/or one
``geometry_msgs/msg/PoseStamped`` per body (docs/bags.md). This module is also the general route of the
reader, through rosbags (the fast one is :mod:`euc_ros.core.io.bags.fast_mcap`).
"""
from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.io.bags.common import (
    MOCAP_FRAME,
    POSE_STAMPED,
    RIGID_BODIES,
    bag_info,
    has_end_magic,
    listed_in_metadata,
    require_readable_bag,
)
from euc_ros.core.io.bags.fast_mcap import read_mocap_fast
from euc_ros.core.io.bags.posestamped import merge_poses, posestamped_arrays, posestamped_cdr
from euc_ros.core.io.bags.recovery import recover_bag
from euc_ros.core.io.bags.writer import DEFAULT_CHUNK_SIZE, BagWriter
from euc_ros.core.io.cdr import split_stamp
from euc_ros.core.io.msgdefs import make_typestore
from euc_ros.core.mocap.message_frames import frame_from_named_poses
from euc_ros.core.mocap.series import MocapSeries

#: MocapFrame.stamp_source value for offline data (capture start + frame / rate).
STAMP_FILE_TIME = 1
#: custom_data keys write_mocap_bag stores in metadata.yaml to make the round trip exact.
CUSTOM_START_NS = "euc_ros.start_ns"
CUSTOM_RATE_HZ = "euc_ros.rate_hz"
CUSTOM_NAME = "euc_ros.name"


def write_mocap_bag(series: MocapSeries, path, *, prefix: str = "/vrpn_mocap", frame_topic: str | None = "/mocap/frame",
                    start_ns: int | None = None, frame_id: str = "world", poses: bool = True,
                    chunk_size: int = DEFAULT_CHUNK_SIZE) -> dict:
    """Write a mocap series as a bag: PoseStamped per body and/or MocapFrame messages.

    Stamps (header and bag receive time) are capture times ``start_ns + round(t * 1e9)``.

    Parameters
    ----------
    series : MocapSeries
        Z-up world, SI units.
    path : str or Path
        New bag directory.
    prefix : str
        PoseStamped topics are ``<prefix>/<Body>/pose`` (docs/bags.md).
    frame_topic : str or None
        Topic of ``euc_msgs/msg/MocapFrame`` messages (one per frame, every body, untracked ones
        with ``tracked=false`` and a NaN pose); None writes none.
    start_ns : int, optional
        Capture time of ``t = 0`` [ns since the epoch]; default ``series.meta['start_ns']`` or 0.
    frame_id : str
        World frame name in the headers.
    poses : bool
        Write the PoseStamped topics (untracked samples are skipped: gaps, never zeros).
    chunk_size : int
        MCAP chunk size [bytes] (see :class:`BagWriter`).

    Returns
    -------
    dict
        Messages written per topic.

    Raises
    ------
    InputError
        When the series' arrays disagree in shape.
    """
    if start_ns is None:
        start_ns = int(series.meta.get("start_ns", 0))
    n, b = series.n_frames, len(series.bodies)
    if series.position.shape != (b, n, 3) or series.quat.shape != (b, n, 4) or series.tracked.shape != (b, n):
        raise InputError(f"inconsistent MocapSeries shapes: position {series.position.shape}, quat "
                         f"{series.quat.shape}, tracked {series.tracked.shape} for {b} bodies x {n} frames")
    stamps = int(start_ns) + np.round(np.asarray(series.t, float) * 1e9).astype(np.int64)
    custom = {CUSTOM_START_NS: str(int(start_ns)), CUSTOM_NAME: series.name or ""}
    if "rate_hz" in series.meta:
        custom[CUSTOM_RATE_HZ] = repr(float(series.meta["rate_hz"]))
    tracked = np.asarray(series.tracked, bool)
    with BagWriter(path, chunk_size=chunk_size, custom_data=custom) as writer:
        ts = writer.typestore
        pose_cdr = []
        if poses:
            for j, body in enumerate(series.bodies):
                sel = np.flatnonzero(tracked[j])
                pose_cdr.append((f"{prefix}/{body}/pose", sel,
                                 posestamped_cdr(stamps[sel], series.position[j, sel], series.quat[j, sel], frame_id)))
        cursors = [0] * len(pose_cdr)
        if frame_topic:
            T = ts.types
            Frame, Header, Time = T[MOCAP_FRAME], T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
            Pose, Point, Quaternion = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"], \
                T["geometry_msgs/msg/Quaternion"]
            sec, nsec = split_stamp(stamps)
            pos = np.where(tracked[..., None], series.position, np.nan)
            quat = np.where(tracked[..., None], series.quat, np.nan)
            err = np.asarray(series.mean_marker_error, float)
            stamp_source = int(series.meta.get("stamp_source", STAMP_FILE_TIME))
        for i in range(n):
            for k, (topic, sel, cdrs) in enumerate(pose_cdr):
                c = cursors[k]
                if c < len(sel) and sel[c] == i:
                    writer.write_raw(topic, POSE_STAMPED, cdrs[c], stamps[i])
                    cursors[k] = c + 1
            if frame_topic:
                msg = Frame(
                    header=Header(stamp=Time(sec=int(sec[i]), nanosec=int(nsec[i])), frame_id=frame_id),
                    stamp_source=stamp_source, frame_number=int(series.frame[i]), body_names=list(series.bodies),
                    poses=[Pose(position=Point(x=p[0], y=p[1], z=p[2]),
                                orientation=Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))
                           for p, q in zip(pos[:, i].tolist(), quat[:, i].tolist())],
                    tracked=tracked[:, i].copy(), mean_marker_error=err[:, i].astype(np.float32))
                writer.write(frame_topic, MOCAP_FRAME, msg, stamps[i])
        return dict(writer.counts)


def _custom_data(bag: Path, info: dict | None = None) -> dict:
    info = bag_info(bag) if info is None else info
    try:
        return dict(info.get("custom_data") or {})
    except (TypeError, ValueError):
        return {}


def read_mocap_bag(path, *, prefix: str = "/vrpn_mocap", frame_topic: str | None = None, bodies=None,
                   merge_tolerance: float = 0.25) -> MocapSeries:
    """Read mocap from a bag into a :class:`~euc_ros.core.mocap.series.MocapSeries`.

    Source, in order: ``frame_topic`` (``euc_msgs/msg/MocapFrame``); else the first MocapFrame topic
    of the bag; else one ``geometry_msgs/msg/PoseStamped`` per body on ``<prefix>/<Body>/pose``
    (docs/bags.md), aligned on their header stamps.

    Parameters
    ----------
    path : str or Path
        Bag directory (or its .mcap file).
    prefix : str
        PoseStamped topic prefix.
    frame_topic : str, optional
        MocapFrame topic to use.
    bodies : list of str, optional
        Bodies to return, in this order (default: all, in the bag's order).
    merge_tolerance : float
        PoseStamped stamps closer than ``merge_tolerance / rate`` are one frame [frame periods].

    Returns
    -------
    MocapSeries
        ``t`` = header stamp minus ``start_ns`` [s], where ``start_ns`` is the one
        :func:`write_mocap_bag` stored in metadata.yaml, else the first stamp; ``meta['start_ns']``
        holds it. Frame numbers from MocapFrame (``-1`` ones, and PoseStamped data, get
        ``round(t * rate)``). Samples without data are NaN with ``tracked == False``.

    Raises
    ------
    InputError
        When the bag cannot be read (the message names ``euc-ros inspect`` and ``euc-ros recover``).

    Notes
    -----
    Bags with one uncompressed, indexed MCAP file are read by :mod:`euc_ros.core.io.mcap_fast`
    (message indexes, no per-message Python work) and, when every MocapFrame has the same CDR
    layout (same length, body names, counts), decoded with numpy at fixed offsets: ~0.15 s instead
    of ~6 s for 10 min x 14 bodies at 120 Hz. Anything else (several files, compression, varying
    body names...) takes the general rosbags route; both give identical series (see ``docs/mcap_fast.md``).
    """
    p = Path(path)
    if p.suffix.lower() == ".mcap" and p.is_file() and not listed_in_metadata(p):
        return _read_standalone_mcap(p, prefix=prefix, frame_topic=frame_topic, bodies=bodies,
                                     merge_tolerance=merge_tolerance)
    bag = require_readable_bag(path)
    info = bag_info(bag)
    custom = _custom_data(bag, info)
    try:
        series = read_mocap_fast(bag, info, prefix, frame_topic, merge_tolerance)
        if series is None:
            series = _read_mocap_rosbags(bag, prefix, frame_topic, merge_tolerance)
    except InputError:
        raise
    except Exception as exc:   # a damaged bag the checks above did not catch: one line, what to do
        raise InputError(f"cannot read the bag ({type(exc).__name__}: {exc}); `euc-ros inspect {bag}` lists its "
                         f"problems, `euc-ros recover {bag}` rebuilds what can be read", path=bag) from None
    start_ns = series.meta.pop("_first_ns")
    if CUSTOM_START_NS in custom:
        try:
            start_ns = int(custom[CUSTOM_START_NS])
        except ValueError:
            pass
    series.t = (series.meta.pop("_stamps") - start_ns) * 1e-9
    series.meta["start_ns"] = start_ns
    if CUSTOM_RATE_HZ in custom:
        series.meta["rate_hz"] = float(custom[CUSTOM_RATE_HZ])
    if custom.get(CUSTOM_NAME):
        series.name = custom[CUSTOM_NAME]
    rate = series.rate_hz if series.n_frames > 1 else np.nan
    unknown = series.frame < 0
    if unknown.any():
        frame = series.frame.copy()       # a new array: the series measures its rate again from it
        frame[unknown] = (np.round(series.t[unknown] * rate).astype(np.int64) if np.isfinite(rate)
                          else np.flatnonzero(unknown))
        series.frame = frame
    if bodies is not None:
        series = series.select(list(bodies))
    return series


def _read_standalone_mcap(file: Path, **kw) -> MocapSeries:
    """Read an .mcap file without a bag directory: rebuilt into a temporary bag, then read."""
    if not has_end_magic(file):
        raise InputError(f"truncated MCAP (no footer): `euc-ros recover {file}` rebuilds a bag from its complete "
                         "chunks", path=file)
    with tempfile.TemporaryDirectory(prefix="euc_mcap_") as tmp:
        recover_bag(file, Path(tmp) / "bag")
        series = read_mocap_bag(Path(tmp) / "bag", **kw)
    series.meta["path"] = str(file)
    if not series.name or series.name == "bag":
        series.name = file.stem
    return series


def _read_mocap_rosbags(bag: Path, prefix: str, frame_topic: str | None, merge_tolerance: float) -> MocapSeries:
    """The general route of :func:`read_mocap_bag`: rosbags' reader and deserializer (any bag rosbags reads)."""
    from rosbags.highlevel import AnyReader

    with AnyReader([bag], default_typestore=make_typestore()) as reader:
        conns = reader.connections
        frame_conns = [c for c in conns if c.msgtype == MOCAP_FRAME]
        if frame_topic is not None:
            chosen = [c for c in frame_conns if c.topic == frame_topic]
            if not chosen:
                have = ", ".join(sorted({c.topic for c in frame_conns})) or "none"
                raise InputError(f"no {MOCAP_FRAME} topic {frame_topic} in the bag (MocapFrame topics: {have})",
                                 path=bag, key="frame_topic")
            frame_conns = chosen[:1]
        rigid = [c for c in conns if c.msgtype == RIGID_BODIES]
        if frame_conns:
            series = _series_from_frames(reader, frame_conns[0], bag)
        elif rigid:
            series = _series_from_rigid_bodies(reader, rigid[0], bag)
        else:
            series = _series_from_poses(reader, conns, prefix, bag, merge_tolerance)
    return series


def _series_from_frames(reader, conn, bag: Path) -> MocapSeries:
    stamps, numbers, names_per, pos_per, quat_per, trk_per, err_per = [], [], [], [], [], [], []
    for _, _, data in reader.messages(connections=[conn]):
        m = reader.deserialize(data, conn.msgtype)
        stamps.append(int(m.header.stamp.sec) * 10**9 + int(m.header.stamp.nanosec))
        numbers.append(int(m.frame_number))
        names_per.append(list(m.body_names))
        pos_per.append([(p.position.x, p.position.y, p.position.z) for p in m.poses])
        quat_per.append([(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) for p in m.poses])
        trk_per.append(np.asarray(m.tracked, bool))
        err_per.append(np.asarray(m.mean_marker_error, float))
    if not stamps:
        raise InputError(f"topic {conn.topic} holds no messages", path=bag)
    bodies: list[str] = []
    for names in names_per:
        for name in names:
            if name not in bodies:
                bodies.append(name)
    order = np.argsort(np.asarray(stamps, np.int64), kind="stable")
    n, b = len(stamps), len(bodies)
    col = {name: k for k, name in enumerate(bodies)}
    position, quat = np.full((b, n, 3), np.nan), np.full((b, n, 4), np.nan)
    tracked, err = np.zeros((b, n), bool), np.full((b, n), np.nan)
    for i, src in enumerate(order):
        names = names_per[src]
        rows = np.array([col[x] for x in names], dtype=np.int64)
        k = len(names)
        if not (len(pos_per[src]) == len(trk_per[src]) == k):
            raise InputError(f"MocapFrame {numbers[src]}: {k} names but {len(pos_per[src])} poses and "
                             f"{len(trk_per[src])} tracked flags", path=bag, key=conn.topic)
        trk = trk_per[src]
        position[rows, i] = np.where(trk[:, None], np.asarray(pos_per[src], float).reshape(k, 3), np.nan)
        quat[rows, i] = np.where(trk[:, None], np.asarray(quat_per[src], float).reshape(k, 4), np.nan)
        tracked[rows, i] = trk
        if len(err_per[src]) == k:
            err[rows, i] = err_per[src]
    stamps_arr = np.asarray(stamps, np.int64)[order]
    return MocapSeries(np.zeros(n), np.asarray(numbers, np.int64)[order], bodies, position, quat, tracked, err,
                       name=bag.name, meta={"path": str(bag), "source": f"{MOCAP_FRAME} {conn.topic}",
                                            "_stamps": stamps_arr, "_first_ns": int(stamps_arr[0])})


def _series_from_rigid_bodies(reader, conn, bag: Path) -> MocapSeries:
    """mocap4r2_msgs/RigidBodies (one message per frame, bodies by name) as stored: the driver's axes.

    Bodies are taken in order of first appearance; a body missing from a message, or with a pose that
    is not finite with a unit quaternion, is a gap (NaN, untracked).
    """
    msgs = [reader.deserialize(data, conn.msgtype) for _, _, data in reader.messages(connections=[conn])]
    if not msgs:
        raise InputError(f"topic {conn.topic} holds no messages", path=bag)
    per = []
    for m in msgs:
        names = [b.rigid_body_name for b in m.rigidbodies]
        pos = np.array([(b.pose.position.x, b.pose.position.y, b.pose.position.z) for b in m.rigidbodies],
                       float).reshape(-1, 3)
        quat = np.array([(b.pose.orientation.x, b.pose.orientation.y, b.pose.orientation.z, b.pose.orientation.w)
                         for b in m.rigidbodies], float).reshape(-1, 4)
        per.append((int(m.header.stamp.sec) * 10**9 + int(m.header.stamp.nanosec), int(m.frame_number),
                    names, pos, quat))
    bodies = list(dict.fromkeys(name for p in per for name in p[2]))
    order = np.argsort(np.array([p[0] for p in per], np.int64), kind="stable")
    n, b = len(per), len(bodies)
    position, quat = np.full((b, n, 3), np.nan), np.full((b, n, 4), np.nan)
    tracked = np.zeros((b, n), bool)
    for i, src in enumerate(order):
        frame, _ = frame_from_named_poses(per[src][0], per[src][1], per[src][2], per[src][3], per[src][4], bodies,
                                          world_up="z")
        position[:, i], quat[:, i], tracked[:, i] = frame.position, frame.quat, frame.tracked
    stamps = np.array([per[k][0] for k in order], np.int64)
    numbers = np.array([per[k][1] for k in order], np.int64)
    return MocapSeries(np.zeros(n), numbers, bodies, position, quat, tracked, np.full((b, n), np.nan),
                       name=bag.name, meta={"path": str(bag), "source": f"{RIGID_BODIES} {conn.topic}",
                                            "_stamps": stamps, "_first_ns": int(stamps[0])})


def _series_from_poses(reader, conns, prefix: str, bag: Path, merge_tolerance: float) -> MocapSeries:
    pattern = re.compile("^" + re.escape(prefix.rstrip("/")) + r"/([^/]+)/pose$")
    body_conns: dict[str, list] = {}
    for c in conns:
        mt = pattern.match(c.topic)
        if mt and c.msgtype == POSE_STAMPED:
            body_conns.setdefault(mt.group(1), []).append(c)
    if not body_conns:
        topics = ", ".join(sorted({c.topic for c in conns})) or "none"
        raise InputError(f"no {MOCAP_FRAME} topic and no {POSE_STAMPED} topics {prefix}/<Body>/pose "
                         f"(bag has: {topics})", path=bag)
    bodies = list(body_conns)
    per_body = []
    for name in bodies:
        raws = [bytes(data) for _, _, data in reader.messages(connections=body_conns[name])]
        try:
            stamp, pos, quat = posestamped_arrays(raws)
        except InputError:   # big-endian or odd encodings: the slow, general route
            msgs = [reader.deserialize(r, POSE_STAMPED) for r in raws]
            stamp = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs], np.int64)
            pos = np.array([(m.pose.position.x, m.pose.position.y, m.pose.position.z) for m in msgs]).reshape(-1, 3)
            quat = np.array([(m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
                              m.pose.orientation.w) for m in msgs]).reshape(-1, 4)
        per_body.append((stamp, pos, quat))
    return merge_poses(bodies, per_body, prefix, bag, merge_tolerance)
