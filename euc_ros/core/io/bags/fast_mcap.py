"""The fast route of :func:`~euc_ros.core.io.bags.mocap.read_mocap_bag`.

The MCAP summary and message indexes are read by :mod:`euc_ros.core.io.mcap_fast`, and fixed-layout CDR
is decoded with numpy (docs/mcap_fast.md).

:func:`read_mocap_fast` returns None whenever a bag needs the general route (rosbags); both give identical
series.
"""
from __future__ import annotations

import re
import struct
from pathlib import Path

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.io.bags.common import MOCAP_FRAME, POSE_STAMPED, RIGID_BODIES
from euc_ros.core.io.bags.posestamped import merge_poses, posestamped_rows
from euc_ros.core.io.mcap_fast import McapFile
from euc_ros.core.mocap.series import MocapSeries


def _align(pos: int, n: int) -> int:
    return (pos + n - 1) // n * n


def _mocapframe_layout(msg: bytes) -> dict | None:
    """CDR layout of one little-endian ``euc_msgs/msg/MocapFrame`` message, or None if unsupported.

    Offsets are row offsets (the 4-byte encapsulation header included); CDR alignment is relative to
    the byte after that header. ``const`` lists the bytes that fix the layout (length and count
    fields, body names): equal in every message, they make all messages share these offsets.
    """
    base = 4
    if len(msg) < base + 12 or msg[0] != 0 or msg[1] != 1:
        return None
    const = [1, 0]                                 # encapsulation kind (checked separately), then fields

    def u32(rel: int) -> int:
        const.extend(range(base + rel, base + rel + 4))
        return struct.unpack_from("<I", msg, base + rel)[0]

    try:
        flen = u32(8)                              # header.stamp sec @0, nanosec @4; frame_id length @8
        pos = 12 + flen
        out = {"stamp_source": base + pos}
        pos = _align(pos + 1, 8)
        out["frame_number"] = base + pos
        pos = _align(pos + 8, 4)
        k = u32(pos)
        pos += 4
        names = []
        for _ in range(k):
            pos = _align(pos, 4)
            n = u32(pos)
            const.extend(range(base + pos + 4, base + pos + 4 + n))
            names.append(msg[base + pos + 4:base + pos + 4 + n].rstrip(b"\0").decode("utf-8"))
            pos += 4 + n
        pos = _align(pos, 4)
        if u32(pos) != k or k == 0:
            return None
        pos = _align(pos + 4, 8)
        out["poses"] = base + pos
        pos = _align(pos + 56 * k, 4)
        if u32(pos) != k:
            return None
        out["tracked"] = base + pos + 4
        pos = _align(pos + 4 + k, 4)
        n_err = u32(pos)
        if n_err not in (0, k):
            n_err = 0                              # the general route ignores errors of another length
            out["err"] = None
        else:
            out["err"] = base + pos + 4 if n_err else None
        pos += 4 + 4 * n_err
    except (struct.error, UnicodeDecodeError):
        return None
    if base + pos > len(msg) or len(set(names)) != k:
        return None
    out.update(k=k, names=names, const=np.asarray(const[2:], np.int64))
    return out


def _frames_fast(msgs, topic: str, bag: Path) -> MocapSeries | None:
    """MocapSeries from MocapFrame messages of one fixed layout (else None: use the general route)."""
    if len(msgs) == 0:
        return None
    lengths = msgs.length
    if np.any(lengths != lengths[0]):
        return None
    lay = _mocapframe_layout(msgs.raw(0))
    if lay is None:
        return None
    rows = msgs.rows()                                         # (n, L) uint8
    const = lay["const"]
    if np.any(rows[:, 0] != 0) or np.any(rows[:, 1] != 1) or np.any(rows[:, const] != rows[0, const]):
        return None
    n, k = rows.shape[0], lay["k"]
    rows = np.ascontiguousarray(rows)
    flat = rows.reshape(-1)

    def field(start: int, dtype: str, shape: tuple = (), strides: tuple = ()) -> np.ndarray:
        # the field of every message, read in place: a strided view of the messages' bytes (no copy)
        return np.ndarray((n,) + shape, dtype=dtype, buffer=flat, offset=start, strides=(rows.shape[1],) + strides)

    sec = field(4, "<i4").astype(np.int64)
    nsec = field(8, "<u4").astype(np.int64)
    stamps = sec * 10**9 + nsec
    numbers = field(lay["frame_number"], "<i8").astype(np.int64)
    vals = field(lay["poses"], "<f8", (k, 7), (56, 8))          # (n, k, 7) view
    trk = rows[:, lay["tracked"]:lay["tracked"] + k] != 0
    err = field(lay["err"], "<f4", (k,), (4,)).astype(float) if lay["err"] is not None else np.full((n, k), np.nan)
    if n > 1 and np.any(stamps[1:] < stamps[:-1]):              # out of order: sorted (stable) by stamp
        order = np.argsort(stamps, kind="stable")
        stamps, numbers, vals, trk, err = stamps[order], numbers[order], vals[order], trk[order], err[order]
    trk_t = np.ascontiguousarray(trk.T)                         # (k, n)
    vals_t = vals.transpose(1, 0, 2)                            # (k, n, 7)
    # C-ordered (body, frame, component) like every other reader's arrays (the analyses read them by block);
    # each written once from the messages' bytes, NaN where a body is not tracked
    untracked = ~trk_t
    position = np.empty((k, n, 3))
    np.copyto(position, vals_t[..., :3])
    position[untracked] = np.nan
    quat = np.empty((k, n, 4))
    np.copyto(quat, vals_t[..., 3:])
    quat[untracked] = np.nan
    del vals, vals_t
    return MocapSeries(np.zeros(n), numbers, list(lay["names"]), position, quat, trk_t,
                       np.ascontiguousarray(err.T), name=bag.name,
                       meta={"path": str(bag), "source": f"{MOCAP_FRAME} {topic}",
                             "_stamps": stamps, "_first_ns": int(stamps[0])})


def _poses_fast(mcap, conns: list, prefix: str, bag: Path, merge_tolerance: float) -> MocapSeries | None:
    """MocapSeries from PoseStamped topics read through the fast MCAP reader (None: use the general route)."""
    pattern = re.compile("^" + re.escape(prefix.rstrip("/")) + r"/([^/]+)/pose$")
    body_cids: dict[str, list] = {}
    for topic, msgtype, cids in conns:
        mt = pattern.match(topic)
        if mt and msgtype == POSE_STAMPED:
            body_cids.setdefault(mt.group(1), []).extend(cids)
    if not body_cids:
        return None                                            # the general route raises the error
    bodies = list(body_cids)
    per_body = []
    for name in bodies:
        msgs = mcap.messages(body_cids[name])
        if msgs is None:
            return None
        n = len(msgs)
        stamp, vals = np.zeros(n, np.int64), np.zeros((n, 7))
        try:
            for length in np.unique(msgs.length):
                idx = np.flatnonzero(msgs.length == length)
                stamp[idx], vals[idx] = posestamped_rows(msgs.rows(idx))
        except InputError:
            return None
        per_body.append((stamp, vals[:, :3], vals[:, 3:]))
    return merge_poses(bodies, per_body, prefix, bag, merge_tolerance)


def read_mocap_fast(bag: Path, info: dict, prefix: str, frame_topic: str | None,
                     merge_tolerance: float) -> MocapSeries | None:
    """:func:`~euc_ros.core.io.bags.mocap.read_mocap_bag` through :mod:`euc_ros.core.io.mcap_fast`.

    Returns None when the bag needs rosbags.

    Handles one uncompressed, indexed MCAP file whose MocapFrame messages share one CDR layout (or
    PoseStamped topics). Topics are taken in metadata.yaml order, as rosbags lists its connections.

    Parameters
    ----------
    bag : Path
        The bag directory.
    info : dict
        Its ``rosbag2_bagfile_information`` mapping.
    prefix : str
        Topic prefix of the per-body PoseStamped topics.
    frame_topic : str or None
        The MocapFrame topic, or None to look for one.
    merge_tolerance : float
        Stamps closer than this many frame periods are one frame [frame periods].

    Returns
    -------
    MocapSeries or None
        The recording, or None.
    """
    try:
        files = info.get("relative_file_paths") or []
        topics = info.get("topics_with_message_count") or []
        if len(files) != 1 or (info.get("compression_mode") or "").lower() not in ("", "none") or \
                (info.get("storage_identifier") or "mcap") != "mcap":
            return None
        meta_conns = [(t["topic_metadata"]["name"], t["topic_metadata"]["type"],
                       t["topic_metadata"].get("serialization_format", "cdr")) for t in topics]
    except (AttributeError, KeyError, TypeError):
        return None
    if any(fmt != "cdr" for _, _, fmt in meta_conns):
        return None
    file = bag / str(files[0])
    if not file.is_file():
        return None
    mcap = McapFile(file)
    if mcap.summary is None:
        return None
    channels = mcap.channels.values()
    conns = [(topic, msgtype, [c.id for c in channels if c.topic == topic and c.schema_name == msgtype])
             for topic, msgtype, _ in meta_conns]
    frame_conns = [c for c in conns if c[1] == MOCAP_FRAME]
    if frame_topic is not None:
        frame_conns = [c for c in frame_conns if c[0] == frame_topic][:1]
        if not frame_conns:
            return None                                        # the general route raises the error
    if frame_conns:
        topic, _, cids = frame_conns[0]
        msgs = mcap.messages(cids)
        return None if msgs is None else _frames_fast(msgs, topic, bag)
    if any(c[1] == RIGID_BODIES for c in conns):
        return None                                            # driver messages: the general route
    return _poses_fast(mcap, conns, prefix, bag, merge_tolerance)
