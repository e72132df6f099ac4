"""Core frames from one received message, in the Z-up world of REP-103.

A decoded NatNet ``FrameOfData`` (:func:`frame_from_natnet`, stamped with :func:`natnet_capture_stamp`) or a
message of named poses (mocap4r2_msgs/RigidBodies, :func:`frame_from_named_poses`).
"""
from __future__ import annotations

import numpy as np

from euc_ros.core.mocap.frame import QUAT_NORM_TOLERANCE, Frame, empty_frame, valid_pose


def natnet_capture_stamp(receive_ns: int, latency_s: float, max_latency_s: float = 1.0) -> tuple[int, bool]:
    """Capture time of a NatNet frame: receive time minus the system latency the server reports.

    Parameters
    ----------
    receive_ns : int
        Client clock when the datagram arrived [ns].
    latency_s : float
        :func:`euc_ros.core.io.natnet.latency_s` (camera mid-exposure to transmission) [s]; NaN when
        unknown.
    max_latency_s : float
        Latencies outside ``[0, max_latency_s]`` are not trusted [s].

    Returns
    -------
    stamp_ns : int
        ``receive_ns - latency`` [ns], or ``receive_ns`` when the latency is unknown or implausible.
    corrected : bool
        True when the latency was subtracted (capture time), False for the receive time.
    """
    if np.isfinite(latency_s) and 0.0 <= latency_s <= max_latency_s:
        return int(receive_ns) - int(round(latency_s * 1e9)), True
    return int(receive_ns), False


def frame_from_named_poses(stamp_ns: int, frame_number: int, names, position, quat, bodies: list[str],
                           world_up: str = "z") -> tuple[Frame, list[str]]:
    """Core :class:`Frame` from one message of named poses, in the Z-up world of REP-103.

    The message is a mocap4r2_msgs/RigidBodies: one frame, every body by name.

    Parameters
    ----------
    stamp_ns, frame_number : int
    names : sequence of str
        Body names in the message.
    position : array_like (n, 3)
    quat : array_like (n, 4)
        (x, y, z, w), body to world.
    bodies : list of str
        Bodies of the output frame, in order. One absent from the message, or with a non-finite
        position or a quaternion that is not of unit norm, is untracked (NaN pose, never zeros).
    world_up : {"y", "z"}
        Up axis of the poses' world; ``"y"`` (Motive's default axes) maps (X, Y, Z) -> (X, -Z, Y).

    Returns
    -------
    Frame, list of str
        The frame, and the names of the message that are not in ``bodies`` (or repeated).
    """
    from euc_ros.core.rotations import y_up_to_z_up_position, y_up_to_z_up_quat

    out = empty_frame(stamp_ns, frame_number, bodies)
    names = [str(n) for n in names]
    pos = np.asarray(position, float).reshape(len(names), 3)
    q = np.asarray(quat, float).reshape(len(names), 4)
    index = {name: i for i, name in enumerate(bodies)}
    rows = np.array([index.get(n, -1) for n in names], dtype=np.int64)
    first = np.zeros(len(names), bool)
    first[np.unique(rows, return_index=True)[1]] = True      # a name repeated in one message: its first pose
    use = (rows >= 0) & first
    norm = np.linalg.norm(q, axis=1)
    ok = use & np.all(np.isfinite(pos), axis=1) & np.all(np.isfinite(q), axis=1) & (
        np.abs(norm - 1.0) <= QUAT_NORM_TOLERANCE)
    p_ok, q_ok = pos[ok], q[ok] / norm[ok, None]
    if world_up == "y" and ok.any():
        p_ok, q_ok = y_up_to_z_up_position(p_ok), y_up_to_z_up_quat(q_ok)
    out.position[rows[ok]], out.quat[rows[ok]] = p_ok, q_ok
    out.tracked[rows[ok]] = True
    return out, [n for n, u in zip(names, use) if not u]


def frame_from_natnet(frame, names_by_id: dict, bodies: list[str], stamp_ns: int, world_up: str = "y") -> Frame:
    """Core :class:`Frame` from a decoded NatNet ``FrameOfData``, in the Z-up world of REP-103.

    Parameters
    ----------
    frame : euc_ros.core.io.natnet.FrameOfData
    names_by_id : dict of int to str
        Rigid-body streaming id -> name (from MODELDEF).
    bodies : list of str
        Bodies of the output frame, in order; bodies absent from the packet, without a name, or with
        the tracking-valid bit clear are untracked (NaN pose).
    stamp_ns : int
        Frame stamp [ns].
    world_up : {"y", "z"}
        Up axis of Motive's streaming world; ``"y"`` maps (X, Y, Z) -> (X, -Z, Y) (docs/motive_csv.md).

    Returns
    -------
    Frame
        The frame, Z-up.
    """
    from euc_ros.core.rotations import y_up_to_z_up_position, y_up_to_z_up_quat

    out = empty_frame(stamp_ns, int(frame.frame_number), bodies)
    index = {name: i for i, name in enumerate(bodies)}
    for rb in frame.rigid_bodies:
        i = index.get(names_by_id.get(int(rb.id), None))
        if i is None or not rb.tracking_valid or not valid_pose(rb.position, rb.quat):
            continue
        pos = np.asarray(rb.position, float)
        quat = np.asarray(rb.quat, float)
        quat = quat / np.linalg.norm(quat)
        if world_up == "y":
            pos, quat = y_up_to_z_up_position(pos), y_up_to_z_up_quat(quat)
        out.position[i], out.quat[i] = pos, quat
        out.tracked[i] = True
        out.mean_marker_error[i] = float(rb.mean_error)
    return out
