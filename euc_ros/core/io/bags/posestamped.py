"""The vectorized ``geometry_msgs/msg/PoseStamped`` codec and the alignment of per-body poses.

The codec converts little-endian CDR to and from numpy arrays; the alignment merges per-body PoseStamped
arrays into one :class:`~euc_ros.core.mocap.series.MocapSeries` (both routes of
:func:`~euc_ros.core.io.bags.mocap.read_mocap_bag` use it).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from euc_ros.core.errors import InputError
from euc_ros.core.io.bags.common import POSE_STAMPED
from euc_ros.core.io.cdr import ENCAPSULATION_LE, HEAD, pad, split_stamp
from euc_ros.core.mocap.series import MocapSeries


def posestamped_cdr(stamp_ns, position, quat, frame_id: str = "world") -> list[bytes]:
    """Serialize PoseStamped messages to little-endian CDR, vectorized.

    Layout (XCDR1, alignment relative to the byte after the 4-byte encapsulation header):
    ``00 01 00 00``; ``int32 sec``; ``uint32 nanosec``; ``uint32 len(frame_id)+1``; frame_id, NUL;
    padding to 8; 7 ``float64`` (position x y z, orientation x y z w).

    Parameters
    ----------
    stamp_ns : array (n,) of int
        Header stamps [ns].
    position : array (n, 3)
        [m].
    quat : array (n, 4)
        (x, y, z, w).
    frame_id : str

    Returns
    -------
    list of bytes
        One CDR message per sample.
    """
    stamp_ns = np.atleast_1d(np.asarray(stamp_ns, dtype=np.int64))
    n = stamp_ns.shape[0]
    fid = frame_id.encode("utf-8") + b"\0"
    body_start = 12 + len(fid)                     # relative to the encapsulation end
    pose_rel = pad(body_start, 8)
    length = HEAD + pose_rel + 56
    buf = np.zeros((n, length), dtype=np.uint8)
    buf[:, :HEAD] = np.frombuffer(ENCAPSULATION_LE, np.uint8)
    sec, nsec = split_stamp(stamp_ns)
    buf[:, 4:8] = sec.astype("<i4")[:, None].view(np.uint8)
    buf[:, 8:12] = nsec.astype("<u4")[:, None].view(np.uint8)
    buf[:, 12:16] = np.frombuffer(np.uint32(len(fid)).astype("<u4").tobytes(), np.uint8)
    buf[:, 16:16 + len(fid)] = np.frombuffer(fid, np.uint8)
    values = np.concatenate([np.asarray(position, float).reshape(n, 3), np.asarray(quat, float).reshape(n, 4)],
                            axis=1).astype("<f8")
    buf[:, HEAD + pose_rel:] = values.view(np.uint8).reshape(n, 56)
    return [row.tobytes() for row in buf]


def posestamped_arrays(raws: list[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Parse little-endian CDR PoseStamped messages, vectorized per message length.

    Parameters
    ----------
    raws : list of bytes

    Returns
    -------
    stamp_ns : ndarray (n,) of int64
    position : ndarray (n, 3)
    quat : ndarray (n, 4)

    Raises
    ------
    InputError
        Big-endian or malformed data (use :func:`~euc_ros.core.io.bags.reader.read_bag` for those).
    """
    n = len(raws)
    stamp = np.zeros(n, np.int64)
    vals = np.zeros((n, 7))
    lengths = np.fromiter((len(r) for r in raws), dtype=np.int64, count=n)
    for length in np.unique(lengths):
        idx = np.flatnonzero(lengths == length)
        arr = np.frombuffer(b"".join(raws[i] for i in idx), dtype=np.uint8).reshape(len(idx), int(length))
        stamp[idx], vals[idx] = posestamped_rows(arr)
    return stamp, vals[:, :3], vals[:, 3:]


def posestamped_rows(arr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stamps [ns] and (position, quaternion) values (m, 7) of PoseStamped CDR rows of one length (m, L).

    Parameters
    ----------
    arr : numpy.ndarray
        CDR rows (m, L) of uint8.

    Returns
    -------
    stamps : numpy.ndarray
        Header stamps (m,) [ns], int64.
    values : numpy.ndarray
        Position [m] and quaternion (x, y, z, w) (m, 7).

    Raises
    ------
    InputError
        When the rows are not little-endian XCDR1 PoseStamped messages.
    """
    m, length = arr.shape
    if length < 16 or np.any(arr[:, 1] != 1) or np.any(arr[:, 0] != 0):
        raise InputError("PoseStamped CDR is not little-endian XCDR1 or is too short", key=POSE_STAMPED)
    slen = arr[:, 12:16].copy().view("<u4")[:, 0].astype(np.int64)
    pose_rel = (12 + slen + 7) // 8 * 8
    if np.any(4 + pose_rel + 56 > length):
        raise InputError("PoseStamped CDR shorter than its frame_id length implies", key=POSE_STAMPED)
    sec = arr[:, 4:8].copy().view("<i4")[:, 0].astype(np.int64)
    nsec = arr[:, 8:12].copy().view("<u4")[:, 0].astype(np.int64)
    vals = np.zeros((m, 7))
    for start in np.unique(pose_rel):
        rows = np.flatnonzero(pose_rel == start)
        block = arr[rows, 4 + int(start):4 + int(start) + 56].copy()
        vals[rows] = block.view("<f8").reshape(len(rows), 7)
    return sec * 10**9 + nsec, vals


def merge_poses(bodies: list, per_body: list, prefix: str, bag: Path, merge_tolerance: float) -> MocapSeries:
    """Align per-body PoseStamped ``(stamp_ns, position, quat)`` arrays on their header stamps.

    Parameters
    ----------
    bodies : list of str
        Body names.
    per_body : list of tuple
        ``(stamp_ns (k,), position (k, 3), quat (k, 4))`` of each body.
    prefix : str
        Topic prefix, for the metadata.
    bag : Path
        The bag, for the metadata.
    merge_tolerance : float
        Stamps closer than this many frame periods are one frame [frame periods].

    Returns
    -------
    MocapSeries
        One frame per merged stamp, frame numbers -1.
    """
    all_stamps = np.unique(np.concatenate([s for s, _, _ in per_body]))
    # Merge stamps of one frame that differ by jitter: new frame where the gap exceeds the tolerance.
    periods = [np.median(np.diff(np.unique(s))) for s, _, _ in per_body if np.unique(s).size > 1]
    if all_stamps.size > 1 and periods:
        period = float(np.median(periods))         # per body: one body's stamps are one per frame
        gaps = np.diff(all_stamps) > merge_tolerance * period
        group = np.concatenate([[0], np.cumsum(gaps)])
    else:
        group = np.zeros(all_stamps.size, np.int64)
    starts = np.flatnonzero(np.concatenate([[True], np.diff(group) > 0]))
    frame_stamps = all_stamps[starts]
    n, b = frame_stamps.size, len(bodies)
    position, quat = np.full((b, n, 3), np.nan), np.full((b, n, 4), np.nan)
    tracked = np.zeros((b, n), bool)
    for j, (stamp, pos, q) in enumerate(per_body):
        cols = group[np.searchsorted(all_stamps, stamp)]
        position[j, cols], quat[j, cols], tracked[j, cols] = pos, q, True
    return MocapSeries(np.zeros(n), np.full(n, -1, np.int64), bodies, position, quat, tracked,
                       np.full((b, n), np.nan), name=bag.name,
                       meta={"path": str(bag), "source": f"{POSE_STAMPED} {prefix}/<Body>/pose",
                             "_stamps": frame_stamps, "_first_ns": int(frame_stamps[0])})
