"""One assembled capture frame of a live stream, the frame with nothing tracked, and what a valid pose is.

The frame is a :class:`Frame`; the frame in which nothing is tracked is :func:`empty_frame`; a valid pose is
what :func:`valid_pose` accepts (:data:`QUAT_NORM_TOLERANCE`).

Every live source (pose topics, NatNet, CSV replay, bags) hands its poses on as a :class:`Frame`: Z-up world of
REP-103, SI units, untracked bodies NaN, never zeros.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A quaternion whose norm differs from 1 by more than this is not a valid orientation.
QUAT_NORM_TOLERANCE = 1e-3


@dataclass
class Frame:
    """One assembled capture frame (Z-up world).

    Parameters
    ----------
    stamp_ns : int
        Capture time [ns] (meaning per the source: header stamp, capture time or file time).
    frame_number : int
        Motive frame number; -1 when unknown (per-body pose topics carry none).
    bodies : list of str
    position : ndarray (b, 3)
        Pivot positions [m]; NaN where untracked.
    quat : ndarray (b, 4)
        Body-to-world quaternions (x, y, z, w); NaN where untracked.
    tracked : ndarray (b,) of bool
    mean_marker_error : ndarray (b,)
        [m], NaN when unknown.
    """

    stamp_ns: int
    frame_number: int
    bodies: list[str]
    position: np.ndarray
    quat: np.ndarray
    tracked: np.ndarray
    mean_marker_error: np.ndarray


def empty_frame(stamp_ns: int, frame_number: int, bodies: list[str]) -> Frame:
    """A frame in which no body is tracked (NaN poses, never zeros).

    Parameters
    ----------
    stamp_ns : int
        Capture time [ns].
    frame_number : int
        Frame number; -1 when unknown.
    bodies : list of str
        Body names.

    Returns
    -------
    Frame
        NaN poses, nothing tracked.
    """
    b = len(bodies)
    return Frame(int(stamp_ns), int(frame_number), list(bodies), np.full((b, 3), np.nan), np.full((b, 4), np.nan),
                 np.zeros(b, bool), np.full(b, np.nan))


def valid_pose(position, quat) -> bool:
    """True if the position is finite and the quaternion finite with unit norm (within 1e-3).

    Parameters
    ----------
    position : array_like
        Position (3,) [m].
    quat : array_like
        Quaternion (4,), (x, y, z, w).

    Returns
    -------
    bool
        Whether the pose is usable.
    """
    p = np.asarray(position, float)
    q = np.asarray(quat, float)
    return bool(np.all(np.isfinite(p)) and np.all(np.isfinite(q))
                and abs(float(np.linalg.norm(q)) - 1.0) <= QUAT_NORM_TOLERANCE)
