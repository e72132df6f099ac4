"""The range of h that the rider's own recorded body allows, before any dynamics.

h is the distance of the rider's CoG ``G = sum f_i CoM_i`` from the ankle hinge ``A``. Each segment's centre
of mass lies on the segment, between the two joints that end it, whatever the session's CoM offsets say, and
the recording gives those joints: the rigid bodies' pivots (helmet top, shoulder, elbow, wrist, hip, knee,
ankle). So, for every frame and any CoM offsets,

* ``|G - A| >= (G - A) . up = sum f_i (CoM_i - A) . up >= sum f_i min over the segment's ends of (P - A) . up``;
* ``|G - A| <= sum f_i |CoM_i - A| <= sum f_i max over the segment's ends of |P - A|``.

The segment ends (:data:`SEGMENT_ENDS`) follow the recording contract's bodies and the anthropometric table's
segments (:mod:`euc_ros.core.anthropometry`): the head from the shoulders to the helmet top, each half trunk
from its hip to the helmet top (the neck's base lies between the shoulders and the head), the upper arm from
the elbow to the shoulder, a hip body (where a session gives it mass: the pelvis) from the hip to the shoulder,
the forearm with the hand from :data:`HAND_COM_M` below the wrist to the elbow, the
thigh from the knee to the hip, the shank with the foot from :data:`FOOT_COM_M` below the ankle to the knee. The
mass fractions are the session's, moved by their tolerance between the legs and the upper body (the range
holds both ends). Over the recording, the range runs from a low percentile of the per-frame lower bounds to a
high percentile of the upper ones (:data:`PERCENTILES`), so that a glitch of one frame does not set it.

The range is what the body allows; it says nothing about the dynamics. An interval of h that reaches past it
is cut at it, and an h outside it is not the rider's.

Examples
--------
>>> SEGMENT_ENDS["TR"]
('TR', 'HR')
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from euc_ros.core.mocap.blocks import pose_block
from euc_ros.core.rotations import rotation_matrices

#: Body -> the bodies whose pivots end its segment (the body's own pivot is one of them).
SEGMENT_ENDS = {
    "H": ("H", "CHR", "CHL"),
    "CHR": ("HR", "H"), "CHL": ("HL", "H"),
    "HR": ("HR", "CHR"), "HL": ("HL", "CHL"),
    "UAR": ("UAR", "CHR"), "UAL": ("UAL", "CHL"),
    "LAR": ("LAR", "UAR"), "LAL": ("LAL", "UAL"),
    "TR": ("TR", "HR"), "TL": ("TL", "HL"),
    "LR": ("LR", "TR"), "LL": ("LL", "TL"),
}
#: Bodies whose segment reaches below their pivot: the hand below the wrist, the foot below the ankle.
HAND_COM_M = 0.10
FOOT_COM_M = 0.06
_BELOW = {"LAR": HAND_COM_M, "LAL": HAND_COM_M, "LR": FOOT_COM_M, "LL": FOOT_COM_M}
#: Lower and upper percentiles of the per-frame bounds over the recording.
PERCENTILES = (1.0, 99.0)
#: Frames used per recording (evenly spaced; the range moves with the posture, not with the frame rate).
MAX_FRAMES = 2000
_LEGS = ("TR", "TL", "LR", "LL")


@dataclass(frozen=True)
class AdmissibleRange:
    """The h the rider's recorded body allows.

    Parameters
    ----------
    low_m, high_m : float
        The range [m].
    frames : int
        Frames it was taken from.
    """

    low_m: float
    high_m: float
    frames: int

    def to_json(self) -> list[float]:
        """The range as JSON.

        Returns
        -------
        list of float
            ``[low, high]`` [m].
        """
        return [float(self.low_m), float(self.high_m)]


def admissible_h(series_list: Sequence, session, *, fraction_tolerance: float = 0.02) -> AdmissibleRange | None:
    """The range of h the recorded joints allow for the session's mass fractions (None when it cannot be had).

    Parameters
    ----------
    series_list : sequence of MocapSeries
        The recordings (Z-up).
    session : Session
        Mass fractions, the EUC body and its geometry (``l0``, ``pivot_to_wheel_center``).
    fraction_tolerance : float
        Share of the body mass that may move between the legs and the upper body.

    Returns
    -------
    AdmissibleRange or None
        None when a body with mass, an end of its segment, or the EUC is not recorded, or no frame has them all.
    """
    segs = session.rider.segments
    massive = [b for b, s in segs.items() if s.mass_fraction > 0]
    if any(b not in SEGMENT_ENDS for b in massive):
        return None
    lows, highs = [], []
    for series in series_list:
        bounds = _frame_bounds(series, session, massive, fraction_tolerance)
        if bounds is not None:
            lows.append(bounds[0])
            highs.append(bounds[1])
    if not lows:
        return None
    lo, hi = np.concatenate(lows), np.concatenate(highs)
    return AdmissibleRange(float(np.percentile(lo, PERCENTILES[0])), float(np.percentile(hi, PERCENTILES[1])),
                           int(lo.size))


def _frame_bounds(series, session, massive: list, fraction_tolerance: float):
    """Per-frame ``(lower, upper)`` over evenly spaced frames with every needed body (None when there are none)."""
    bodies = list(series.bodies)
    needed = sorted({e for b in massive for e in SEGMENT_ENDS[b]} | {session.euc.body})
    if any(b not in bodies for b in needed):
        return None
    n = int(series.n_frames)
    step = max(1, n // MAX_FRAMES)
    pos, quat, trk = pose_block(series, 0, n)
    pos, quat, trk = pos[:, ::step], quat[:, ::step], trk[:, ::step]
    idx = {b: bodies.index(b) for b in needed}
    ok = np.ones(pos.shape[1], bool)
    for i in idx.values():
        ok &= trk[i] & np.isfinite(pos[i]).all(-1) & np.isfinite(quat[i]).all(-1)
    if not ok.any():
        return None
    e = idx[session.euc.body]
    R_E = rotation_matrices(quat[e, ok])
    C = pos[e, ok] + R_E @ np.asarray(session.euc.pivot_to_wheel_center, float)
    A = C - session.euc.l0 * R_E[:, :, 2]
    up = np.array([0.0, 0.0, 1.0])
    fr = {b: session.rider.segments[b].mass_fraction for b in massive}
    low_seg, high_seg = {}, {}
    for b in massive:
        ends = np.stack([pos[idx[o], ok] - A for o in SEGMENT_ENDS[b]])            # (k, m, 3)
        heights = ends @ up
        low_seg[b] = heights.min(axis=0) - _BELOW.get(b, 0.0)
        high_seg[b] = np.linalg.norm(ends, axis=-1).max(axis=0)
    legs = sum(fr[b] for b in massive if b in _LEGS)
    upper = sum(fr[b] for b in massive if b not in _LEGS)
    lows, highs = [], []
    for moved in (-fraction_tolerance, 0.0, fraction_tolerance):
        if (legs <= 0 or upper <= 0) and moved != 0.0:
            continue
        w = {b: fr[b] * (1.0 - moved / legs if b in _LEGS else 1.0 + moved / upper) for b in massive}
        lows.append(sum(w[b] * low_seg[b] for b in massive))
        highs.append(sum(w[b] * high_seg[b] for b in massive))
    return np.min(lows, axis=0), np.max(highs, axis=0)
