"""The rider's segments and the EUC body as rigid bodies: posture, segment table, poses.

The rider of the planar model is one rigid body hinged at the ankle A. Its thirteen segments
(docs/session.md, rigid bodies) are fixed in a rider frame with origin A (x forward, y left, z up;
the rider's centre of gravity G on the frame's z axis at height h), each with its own pitch from the
standing pose. So every segment turns with the rider pitch ``phi`` and the mass-weighted segment
centres of mass are G of the model exactly.

Anthropometry: segment lengths as fractions of stature and mass fractions after Drillis-Contini and
de Leva (rounded); the posture (knee bend, trunk lean, arms) is drawn per rider.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Rider rigid bodies, in the order of the recording-format spec.
SEGMENT_BODIES = ("H", "CHR", "CHL", "UAR", "UAL", "LAR", "LAL", "HR", "HL", "TR", "TL", "LR", "LL")
#: The EUC's rigid body.
EUC_BODY = "E"

#: Mass fractions of the rider mass; they sum to 1 exactly (head; chest halves: thorax, abdomen and
#: half the pelvis's upper part; upper arms; forearm + hand; pelvis halves; thighs; shank + foot).
MASS_FRACTIONS = {"H": 0.081, "CHR": 0.1575, "CHL": 0.1575, "UAR": 0.028, "UAL": 0.028, "LAR": 0.022,
                  "LAL": 0.022, "HR": 0.091, "HL": 0.091, "TR": 0.100, "TL": 0.100, "LR": 0.061, "LL": 0.061}
#: Sagittal radius of gyration of each segment about its own centre of mass, as a fraction of its length.
GYRATION = {"H": 0.30, "CH": 0.35, "UA": 0.30, "LA": 0.30, "HP": 0.35, "T": 0.33, "L": 0.30}


def ry(a) -> np.ndarray:
    """Rotation matrices about +y by ``a`` [rad], shape ``a.shape + (3, 3)``.

    Parameters
    ----------
    a : array_like
        Angles [rad] (any shape).

    Returns
    -------
    numpy.ndarray
        ``a.shape + (3, 3)``: ``[[cos a, 0, sin a], [0, 1, 0], [-sin a, 0, cos a]]``.
    """
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def quat_mul(a, b) -> np.ndarray:
    """Hamilton product of quaternions (x, y, z, w), broadcast over leading axes.

    Parameters
    ----------
    a, b : array_like (..., 4)
        Quaternions (x, y, z, w).

    Returns
    -------
    numpy.ndarray (..., 4)
        ``a b``: as rotations, ``b`` first, then ``a``.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], -1)


def quat_axis(axis: int, a) -> np.ndarray:
    """Quaternions (x, y, z, w) of rotations by ``a`` [rad] about coordinate axis ``axis`` (0, 1, 2).

    Parameters
    ----------
    axis : int
        0, 1 or 2 (x, y or z).
    a : array_like
        Angles [rad] (any shape).

    Returns
    -------
    numpy.ndarray
        ``a.shape + (4,)``.
    """
    a = np.asarray(a, dtype=float)
    q = np.zeros(a.shape + (4,))
    q[..., axis] = np.sin(a / 2)
    q[..., 3] = np.cos(a / 2)
    return q


def quat_rotate(q, v) -> np.ndarray:
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q`` (..., 4): ``v + 2 w (u x v) + 2 u x (u x v)``.

    Parameters
    ----------
    q : array_like (..., 4)
        Unit quaternions (x, y, z, w) = (u, w).
    v : array_like (..., 3)
        Vectors (broadcast against ``q``).

    Returns
    -------
    numpy.ndarray (..., 3)
        The rotated vectors.
    """
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_from_rotvec(r) -> np.ndarray:
    """Quaternions (x, y, z, w) of rotation vectors ``r`` (..., 3) [rad]: ``(sin(|r|/2) r/|r|, cos(|r|/2))``.

    Parameters
    ----------
    r : array_like (..., 3)
        Rotation vectors: axis times angle [rad].

    Returns
    -------
    numpy.ndarray (..., 4)
        Unit quaternions; ``(0, 0, 0, 1)`` for ``r = 0``.
    """
    r = np.asarray(r, dtype=float)
    ang = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * ang
    # sin(x)/x with its series near 0
    k = np.where(ang > 1e-8, np.sin(half) / np.where(ang > 0, ang, 1.0), 0.5 - ang**2 / 48.0)
    return np.concatenate([r * k, np.cos(half)], axis=-1)


@dataclass(frozen=True)
class Posture:
    """A riding posture, angles from the upright standing pose [rad] and stature [m].

    Parameters
    ----------
    stature : float
        Standing height [m].
    shank, thigh, trunk : float
        Pitch of shank, thigh and trunk (positive: top of the segment forward). A bent knee has
        ``shank > 0 > thigh``.
    upper_arm, forearm : float
        Forward swing of the upper arm (elbow ahead of the shoulder) and of the forearm (wrist
        ahead of the elbow).
    head : float
        Pitch of the head.
    """

    stature: float = 1.75
    shank: float = 0.25
    thigh: float = -0.15
    trunk: float = 0.15
    upper_arm: float = 0.2
    forearm: float = 0.6
    head: float = 0.1

    @staticmethod
    def draw(rng: np.random.Generator) -> "Posture":
        """A random riding posture: stature 1.55-1.95 m, knees bent 10-45 deg, trunk lean 0-25 deg.

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of the draws (uniform; the knee bend is shared 40-60 % by the shank).

        Returns
        -------
        Posture
            Also upper arm 0-30 deg, forearm 20-80 deg, head -0.1-0.3 rad.
        """
        knee = rng.uniform(np.radians(10), np.radians(45))
        share = rng.uniform(0.4, 0.6)
        return Posture(stature=rng.uniform(1.55, 1.95), shank=share * knee, thigh=-(1 - share) * knee,
                       trunk=rng.uniform(0.0, np.radians(25)), upper_arm=rng.uniform(0.0, np.radians(30)),
                       forearm=rng.uniform(np.radians(20), np.radians(80)), head=rng.uniform(-0.1, 0.3))


@dataclass(frozen=True)
class RiderBody:
    """The rider as a rigid body: segment pivots, pitches and centres of mass in the rider frame.

    Parameters
    ----------
    bodies : tuple of str
        :data:`SEGMENT_BODIES`.
    pivot : ndarray (13, 3)
        Pivot of each segment in the rider frame (origin at the hinge A) [m].
    pitch : ndarray (13,)
        Pitch of each segment's body frame relative to the rider frame [rad].
    com_offset : ndarray (13, 3)
        Segment centre of mass from its pivot, in the segment's body frame [m] (the session's
        ``com_offset``).
    mass_fraction : ndarray (13,)
        Share of the rider mass of each segment (:data:`MASS_FRACTIONS`; sums to 1).
    mass : float
        Rider mass [kg].
    h : float
        Distance from A to the rider's centre of gravity G [m].
    J : float
        Pitch inertia about G [kg m^2].
    """

    bodies: tuple
    pivot: np.ndarray
    pitch: np.ndarray
    com_offset: np.ndarray
    mass_fraction: np.ndarray
    mass: float
    h: float
    J: float

    def com_rider_frame(self) -> np.ndarray:
        """Segment centres of mass in the rider frame (13, 3): ``pivot + R_y(pitch) com_offset``.

        Returns
        -------
        numpy.ndarray (13, 3)
            In the order of :attr:`bodies` [m].
        """
        return self.pivot + np.einsum("kij,kj->ki", ry(self.pitch), self.com_offset)

    def cog_rider_frame(self) -> np.ndarray:
        """Mass-weighted centre of the segments in the rider frame (3,): ``(0, 0, h)`` by construction.

        Returns
        -------
        numpy.ndarray (3,)
            The rider's centre of gravity G [m] (for a rider of :func:`build_rider`).
        """
        return self.mass_fraction @ self.com_rider_frame()


def _raw_segments(post: Posture) -> tuple[dict, dict, dict, dict]:
    """Pivots, pitches, CoM offsets and lengths of the segments before the rider frame is levelled.

    Joint positions are built from the ankle up in a frame with origin at the ankle hinge; lateral
    positions are mirrored exactly between left (y > 0) and right.
    """
    H = post.stature
    L_shank, L_thigh, L_trunk, L_head = 0.246 * H, 0.245 * H, 0.288 * H, 0.182 * H
    L_ua, L_fa, L_hand = 0.186 * H, 0.146 * H, 0.108 * H
    w_leg, w_sh, w_arm = 0.055 * H, 0.129 * H, 0.150 * H

    def up(a, length):                      # vector of a segment of pitch a pointing up
        return length * np.array([np.sin(a), 0.0, np.cos(a)])

    ankle = np.zeros(3)
    knee = ankle + up(post.shank, L_shank)
    hip = knee + up(post.thigh, L_thigh)
    shoulder = hip + up(post.trunk, L_trunk)
    top = shoulder + up(post.head, L_head)
    elbow = shoulder + up(-post.upper_arm, -L_ua)    # hanging: up(-a, -L) = L (sin a, 0, -cos a)
    wrist = elbow + up(-post.forearm, -L_fa)

    def side(p, w):
        return p + np.array([0.0, w, 0.0])

    pivot, pitch, off, length = {}, {}, {}, {}
    pivot["H"], pitch["H"], off["H"], length["H"] = top, post.head, np.array([0.0, 0.0, -0.07 * H]), L_head
    for s, sg in (("R", -1.0), ("L", 1.0)):
        # chest half: from the shoulder, down the trunk and towards the midline
        pivot["CH" + s], pitch["CH" + s] = side(shoulder, sg * w_sh), post.trunk
        off["CH" + s], length["CH" + s] = np.array([0.02 * H, -sg * 0.085 * H, -0.13 * H]), L_trunk
        # upper arm: from the elbow up to its centre (0.436 of the arm from the shoulder)
        pivot["UA" + s], pitch["UA" + s] = side(elbow, sg * w_arm), -post.upper_arm
        off["UA" + s], length["UA" + s] = np.array([0.0, 0.0, 0.564 * L_ua]), L_ua
        # forearm and hand: the forearm's centre 0.57 of it above the wrist, the hand's half a hand below
        z_la = (0.016 * 0.57 * L_fa - 0.006 * 0.5 * L_hand) / 0.022
        pivot["LA" + s], pitch["LA" + s] = side(wrist, sg * w_arm), -post.forearm
        off["LA" + s], length["LA" + s] = np.array([0.0, 0.0, z_la]), L_fa + L_hand
        # pelvis half: from the hip joint, a little up, back and towards the midline
        pivot["H" + s], pitch["H" + s] = side(hip, sg * w_leg), 0.5 * post.trunk
        off["H" + s], length["H" + s] = np.array([-0.01 * H, -sg * 0.03 * H, 0.03 * H]), 0.1 * H
        # thigh: from the knee up to its centre (0.433 of it below the hip)
        pivot["T" + s], pitch["T" + s] = side(knee, sg * w_leg), post.thigh
        off["T" + s], length["T" + s] = np.array([0.0, 0.0, 0.567 * L_thigh]), L_thigh
        # shank and foot: from the ankle; the shank's centre 0.567 of it above, the foot's ahead and below
        z_l = (0.0465 * 0.567 * L_shank - 0.0145 * 0.02 * H) / 0.061
        x_l = 0.0145 * 0.06 * H / 0.061
        pivot["L" + s], pitch["L" + s] = side(ankle, sg * w_leg), post.shank
        off["L" + s], length["L" + s] = np.array([x_l, 0.0, z_l]), L_shank
    return pivot, pitch, off, length


def _gyration_key(name: str) -> str:
    if name == "H":
        return "H"
    if name in ("HR", "HL"):
        return "HP"
    return name[:-1]


def build_rider(posture: Posture, mass: float) -> RiderBody:
    """Build the rigid rider of a posture and mass, levelled so that G lies above A.

    Parameters
    ----------
    posture : Posture
    mass : float
        Rider mass [kg].

    Returns
    -------
    RiderBody

    Notes
    -----
    With the raw segment table (pivots ``p_i``, pitches ``b_i``, offsets ``c_i``) the weighted centre
    is ``g = sum f_i (p_i + R_y(b_i) c_i)``. Turning the whole posture about A by
    ``d = -atan2(g_x, g_z)`` (``p_i <- R_y(d) p_i``, ``b_i <- b_i + d``; the offsets live in the
    body frames and do not change) brings G onto the rider frame's z axis, at ``h = |g|`` (the
    lateral component is zero by the mirror symmetry). The pitch inertia about G is
    ``J = sum m_i (|r_i - G|_xz^2 + (k_i L_i)^2)`` with segment radii of gyration ``k_i L_i``.
    """
    pivot, pitch, off, length = _raw_segments(posture)
    names = SEGMENT_BODIES
    P = np.array([pivot[n] for n in names])
    B = np.array([pitch[n] for n in names])
    C = np.array([off[n] for n in names])
    f = np.array([MASS_FRACTIONS[n] for n in names])
    g = f @ (P + np.einsum("kij,kj->ki", ry(B), C))
    d = -np.arctan2(g[0], g[2])
    P = P @ ry(d).T
    B = B + d
    rider = RiderBody(names, P, B, C, f, float(mass), float(np.hypot(g[0], g[2])), 0.0)
    com = rider.com_rider_frame()
    G = np.array([0.0, 0.0, rider.h])
    r2 = (com[:, 0] - G[0]) ** 2 + (com[:, 2] - G[2]) ** 2
    k2 = np.array([(GYRATION[_gyration_key(n)] * length[n]) ** 2 for n in names])
    J = float(mass * f @ (r2 + k2))
    return RiderBody(names, P, B, C, f, float(mass), rider.h, J)


@dataclass(frozen=True)
class Placement:
    """Where the ride happens in the lab: origin of the path, heading, and the EUC's pivot.

    Parameters
    ----------
    origin : ndarray (2,)
        Ground point (x, y) where the wheel starts, Z-up world [m].
    heading : float
        Yaw of the direction of travel [rad].
    euc_top : ndarray (3,)
        EUC pivot E relative to the wheel centre C in the EUC body frame [m]; the session's
        ``pivot_to_wheel_center`` is its negative.
    """

    origin: np.ndarray
    heading: float
    euc_top: np.ndarray


def poses(x, gamma, phi, rider: RiderBody, R: float, l_0: float, place: Placement) -> dict:
    """World (Z-up) pivots and orientations of the rider segments and the EUC body.

    Parameters
    ----------
    x, gamma, phi : ndarray (n,)
        Wheel travel [m], EUC pitch and rider pitch [rad].
    rider : RiderBody
    R, l_0 : float
        Wheel radius and hinge depth below the axle [m].
    place : Placement

    Returns
    -------
    dict
        ``bodies`` (14 names: the segments then ``E``), ``position`` (14, n, 3) [m] and ``quat``
        (14, n, 4) (x, y, z, w), and ``G`` (n, 3), the rider's centre of gravity [m].

    Notes
    -----
    In the travel frame (origin at the start point on the ground, x along the heading, z up):
    ``C = (x, 0, R)``, ``A = C - l_0 R_y(gamma) e_z``, a segment's pivot ``A + R_y(phi) p_i`` and
    orientation ``R_y(phi + b_i)``; the EUC's pivot ``C + R_y(gamma) e_top``, orientation
    ``R_y(gamma)``. The world adds the heading ``R_z(psi)`` and the origin.
    """
    x, gamma, phi = (np.asarray(a, dtype=float) for a in (x, gamma, phi))
    n = x.size
    C = np.stack([x, np.zeros(n), np.full(n, R)], -1)
    Rg, Rp = ry(gamma), ry(phi)
    A = C - l_0 * Rg[..., :, 2]
    seg_pos = A[None] + np.einsum("nij,kj->kni", Rp, rider.pivot)                       # (13, n, 3)
    G = A + np.einsum("nij,j->ni", Rp, np.array([0.0, 0.0, rider.h]))
    E = C + np.einsum("nij,j->ni", Rg, place.euc_top)
    pos = np.concatenate([seg_pos, E[None]], axis=0)
    ang = np.concatenate([phi[None] + rider.pitch[:, None], gamma[None]], axis=0)     # (14, n)
    q_yaw = quat_axis(2, place.heading)
    quat = quat_mul(q_yaw, quat_axis(1, ang))
    quat = quat * np.where(quat[..., 3:] < 0, -1.0, 1.0)
    cz, sz = np.cos(place.heading), np.sin(place.heading)
    Rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    shift = np.array([place.origin[0], place.origin[1], 0.0])
    pos = pos @ Rz.T + shift
    G = G @ Rz.T + shift
    return {"bodies": SEGMENT_BODIES + (EUC_BODY,), "position": pos, "quat": quat, "G": G}
