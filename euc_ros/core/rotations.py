"""Rotations: quaternions, the EUC paper's yaw-tilt-pitch sequence, and Motive Y-up -> REP-103 Z-up.

Conventions
-----------
* Quaternions are ``(x, y, z, w)`` (ROS and scipy order), body-to-world, last axis of the array.
* Yaw-tilt-pitch (EUC paper, Fig. 2 and eqs (1)-(2)): ``R = Rz(psi) @ Rx(theta) @ Ry(pitch)``, i.e.
  yaw psi about world Z (up), then tilt theta about the yawed forward axis x, then pitch about the
  tilted lateral axis y. Positive pitch tips the body's z axis towards its x axis (forward).
* Motive's default world is Y-up; with REP-103 axes (x, y, z) the Motive axes are (X, Y, Z) = (x, z, -y)
  (docs/motive_csv.md).

Examples
--------
>>> import numpy as np
>>> q = quat_from_yaw_tilt_pitch(0.3, -0.1, 0.05)
>>> np.round(yaw_tilt_pitch_from_quat(q), 12)
array([ 0.3 , -0.1 ,  0.05])
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

#: scipy's name of the intrinsic yaw (Z) - tilt (X) - pitch (Y) sequence.
YAW_TILT_PITCH_SEQ = "ZXY"


def quat_from_yaw_tilt_pitch(psi, theta, pitch) -> np.ndarray:
    """Body-to-world quaternions (..., 4) for yaw psi, tilt theta, pitch [rad].

    Parameters
    ----------
    psi, theta, pitch : array_like
        Yaw, tilt and pitch [rad] (broadcast together).

    Returns
    -------
    numpy.ndarray
        Body-to-world quaternions (..., 4), (x, y, z, w).
    """
    angles = np.stack(np.broadcast_arrays(np.asarray(psi, float), np.asarray(theta, float),
                                          np.asarray(pitch, float)), axis=-1)
    flat = angles.reshape(-1, 3)
    q = Rotation.from_euler(YAW_TILT_PITCH_SEQ, flat).as_quat()
    return q.reshape(angles.shape[:-1] + (4,))


def yaw_tilt_pitch_from_quat(q) -> np.ndarray:
    """``[psi, theta, pitch]`` (..., 3) [rad] from quaternions (..., 4) (x, y, z, w).

    NaN quaternions give NaN angles (untracked samples stay gaps). With ``R = Rz(psi) Rx(theta)
    Ry(pitch)`` (intrinsic Z-X-Y, :data:`YAW_TILT_PITCH_SEQ`) the last row of R is
    ``(-cos(theta) sin(pitch), sin(theta), cos(theta) cos(pitch))`` and ``R[0, 1] = -sin(psi) cos(theta)``,
    ``R[1, 1] = cos(psi) cos(theta)``: closed forms in numpy (equal to scipy's ``as_euler("ZXY")`` to
    round-off away from theta = +-90 deg, tested), ~10x cheaper than scipy on one frame.

    Parameters
    ----------
    q : array_like
        Quaternions (..., 4), (x, y, z, w), body to world; need not be normalised.

    Returns
    -------
    numpy.ndarray
        ``[psi, theta, pitch]`` (..., 3) [rad].
    """
    R = rotation_matrices(q)
    theta = np.arcsin(np.clip(R[..., 2, 1], -1.0, 1.0))
    pitch = np.arctan2(-R[..., 2, 0], R[..., 2, 2])
    psi = np.arctan2(-R[..., 0, 1], R[..., 1, 1])
    return np.stack([psi, theta, pitch], axis=-1)


def rotation_matrices(q) -> np.ndarray:
    """Rotation matrices (..., 3, 3) for quaternions (..., 4) (x, y, z, w; normalised here).

    NaN where q is not finite or zero.

    Parameters
    ----------
    q : array_like
        Quaternions (..., 4), (x, y, z, w).

    Returns
    -------
    numpy.ndarray
        Rotation matrices (..., 3, 3), body to world.
    """
    q = np.asarray(q, dtype=float)
    n2 = np.einsum("...i,...i->...", q, q)
    ok = np.isfinite(n2) & (n2 > 0)
    s = np.where(ok, 2.0 / np.where(ok, n2, 1.0), np.nan)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    xx, yy, zz = s * x * x, s * y * y, s * z * z
    xy, xz, yz = s * x * y, s * x * z, s * y * z
    wx, wy, wz = s * w * x, s * w * y, s * w * z
    R = np.stack([1.0 - (yy + zz), xy - wz, xz + wy,
                  xy + wz, 1.0 - (xx + zz), yz - wx,
                  xz - wy, yz + wx, 1.0 - (xx + yy)], axis=-1)
    return R.reshape(q.shape[:-1] + (3, 3))


def rotate(q, v) -> np.ndarray:
    """Rotate body-frame vectors v (..., 3) to the world by quaternions q (..., 4) (broadcasting).

    Parameters
    ----------
    q : array_like
        Body-to-world quaternions (..., 4), (x, y, z, w).
    v : array_like
        Body-frame vectors (..., 3).

    Returns
    -------
    numpy.ndarray
        World-frame vectors (..., 3).
    """
    return np.einsum("...ij,...j->...i", rotation_matrices(q), np.asarray(v, dtype=float))


def y_up_to_z_up_position(p) -> np.ndarray:
    """Motive Y-up position (X, Y, Z) -> REP-103 Z-up (X, -Z, Y).

    Parameters
    ----------
    p : array_like
        Positions (..., 3) in Motive's Y-up axes [m].

    Returns
    -------
    numpy.ndarray
        Positions (..., 3) in REP-103 Z-up axes [m].
    """
    p = np.asarray(p, dtype=float)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def z_up_to_y_up_position(p) -> np.ndarray:
    """REP-103 Z-up position (x, y, z) -> Motive Y-up (x, z, -y); inverse of :func:`y_up_to_z_up_position`.

    Parameters
    ----------
    p : array_like
        Positions (..., 3) in REP-103 Z-up axes [m].

    Returns
    -------
    numpy.ndarray
        Positions (..., 3) in Motive's Y-up axes [m].
    """
    p = np.asarray(p, dtype=float)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def y_up_to_z_up_quat(q) -> np.ndarray:
    """Motive Y-up quaternion (qx, qy, qz, qw) -> REP-103 Z-up (qx, -qz, qy, qw).

    Parameters
    ----------
    q : array_like
        Quaternions (..., 4), (x, y, z, w), in Motive's Y-up axes.

    Returns
    -------
    numpy.ndarray
        Quaternions (..., 4) in REP-103 Z-up axes.
    """
    q = np.asarray(q, dtype=float)
    return np.stack([q[..., 0], -q[..., 2], q[..., 1], q[..., 3]], axis=-1)


def z_up_to_y_up_quat(q) -> np.ndarray:
    """REP-103 Z-up quaternion -> Motive Y-up; inverse of :func:`y_up_to_z_up_quat`.

    Parameters
    ----------
    q : array_like
        Quaternions (..., 4), (x, y, z, w), in REP-103 Z-up axes.

    Returns
    -------
    numpy.ndarray
        Quaternions (..., 4) in Motive's Y-up axes.
    """
    q = np.asarray(q, dtype=float)
    return np.stack([q[..., 0], q[..., 2], -q[..., 1], q[..., 3]], axis=-1)


def canonical_quat(q) -> np.ndarray:
    """Quaternions with w >= 0 (the sign of a quaternion is arbitrary).

    Parameters
    ----------
    q : array_like
        Quaternions (..., 4), (x, y, z, w).

    Returns
    -------
    numpy.ndarray
        The same rotations (..., 4) with w >= 0.
    """
    q = np.asarray(q, dtype=float)
    return np.where(q[..., 3:4] < 0, -q, q)


def quat_multiply(a, b) -> np.ndarray:
    """Hamilton product ``a b`` of quaternions (..., 4) in (x, y, z, w) order (broadcasting).

    The rotation ``b`` followed by ``a`` in the fixed frame, i.e. ``R(a b) = R(a) R(b)``.

    Parameters
    ----------
    a, b : array_like
        Quaternions (..., 4), (x, y, z, w) (broadcast together).

    Returns
    -------
    numpy.ndarray
        The products ``a b`` (..., 4).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    av, aw = a[..., :3], a[..., 3:]
    bv, bw = b[..., :3], b[..., 3:]
    v = aw * bv + bw * av + np.cross(av, bv)
    w = aw * bw - np.sum(av * bv, axis=-1, keepdims=True)
    return np.concatenate([v, w], axis=-1)


def quat_conjugate(q) -> np.ndarray:
    """Inverse of unit quaternions (..., 4) (x, y, z, w).

    Parameters
    ----------
    q : array_like
        Unit quaternions (..., 4), (x, y, z, w).

    Returns
    -------
    numpy.ndarray
        Conjugates (..., 4): the inverse rotations.
    """
    q = np.asarray(q, dtype=float)
    return np.concatenate([-q[..., :3], q[..., 3:]], axis=-1)


def quat_from_rotvec(v) -> np.ndarray:
    """Unit quaternions (..., 4) of rotation vectors (..., 3) [rad] (axis times angle).

    Parameters
    ----------
    v : array_like
        Rotation vectors (..., 3) [rad].

    Returns
    -------
    numpy.ndarray
        Unit quaternions (..., 4), (x, y, z, w).
    """
    v = np.asarray(v, dtype=float)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(a/2)/a, with its series near 0
    k = np.where(angle > 1e-6, np.sin(half) / np.where(angle > 1e-6, angle, 1.0), 0.5 - angle ** 2 / 48.0)
    return np.concatenate([k * v, np.cos(half)], axis=-1)


def rotvec_from_quat(q) -> np.ndarray:
    """Rotation vectors (..., 3) [rad] of quaternions (..., 4), the angle in [0, pi] (sign of q ignored).

    Parameters
    ----------
    q : array_like
        Quaternions (..., 4), (x, y, z, w); normalised here.

    Returns
    -------
    numpy.ndarray
        Rotation vectors (..., 3) [rad].
    """
    q = canonical_quat(np.asarray(q, dtype=float) / np.linalg.norm(q, axis=-1, keepdims=True))
    s = np.linalg.norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(s, q[..., 3:])
    k = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0 / np.maximum(q[..., 3:], 1e-300))
    return k * q[..., :3]


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate the body vectors ``v`` (..., 3) by quaternions ``q`` (..., 4) (x, y, z, w), normalised here.

    ``v' = v + 2 w (u x v) + 2 u x (u x v)`` with ``u = (x, y, z)``; NaN quaternions give NaN. The
    cross products are written out (``np.cross`` costs more than the arithmetic on one frame), so this
    is cheaper than :func:`rotate` on a single frame; the two agree to rounding.

    Parameters
    ----------
    q : numpy.ndarray
        Body-to-world quaternions (..., 4), (x, y, z, w).
    v : numpy.ndarray
        Body-frame vectors (..., 3).

    Returns
    -------
    numpy.ndarray
        World-frame vectors (..., 3).
    """
    q = q / np.sqrt(np.einsum("...i,...i->...", q, q))[..., None]
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    vx, vy, vz = v[..., 0], v[..., 1], v[..., 2]
    tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
    return np.stack([vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz),
                     vz + w * tz + (x * ty - y * tx)], axis=-1)
