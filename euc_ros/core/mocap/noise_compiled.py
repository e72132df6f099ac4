"""Re-noised poses of many frames in one compiled loop (numba).

What :func:`~euc_ros.core.mocap.noise.pose_noise_series` makes of a block of frames (positions plus scaled
draws, quaternions turned by the scaled rotation-vector draws), without the float64 copy of the draws and the
block-sized temporaries of each step. The same formulas in the same order; equal to the numpy arithmetic to
round-off (the sine and cosine may differ in the last bit between implementations). Compiled on first use and
cached on disk (numba ``cache=True``, next to this file).
"""
from __future__ import annotations

import math

import numba
import numpy as np

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def perturb_poses(position, quat, z, pos_scale, rot_scale, rotate, first):
    """``(position + pos_scale z[..., :3], quat turned by rot_scale z[..., 3:])`` for frames ``first .. first + m - 1``.

    ``position`` is (b, n, 3) and ``quat`` (b, n, 4); ``m`` is the draws' number of frames.

    ``z`` (b, m, 6) the draws (any float type); ``pos_scale``, ``rot_scale`` (b,) per body (the sign of
    antithetic noise included); ``rotate`` (b,) bool: bodies whose quaternions are turned. A quaternion is
    normalised first; one that is not finite, or of a body not turned, is copied as given.
    """
    b, m = position.shape[0], z.shape[1]
    pos_o = np.empty((b, m, 3))
    quat_o = np.empty((b, m, 4))
    for i in range(b):
        ps, rs, turn = pos_scale[i], rot_scale[i], rotate[i]
        for j in range(m):
            f = first + j
            for c in range(3):
                pos_o[i, j, c] = position[i, f, c] + ps * np.float64(z[i, j, c])
            x, y, zq, w = quat[i, f, 0], quat[i, f, 1], quat[i, f, 2], quat[i, f, 3]
            finite = (x - x == 0.0) and (y - y == 0.0) and (zq - zq == 0.0) and (w - w == 0.0)
            if not (finite and turn):
                quat_o[i, j, 0], quat_o[i, j, 1], quat_o[i, j, 2], quat_o[i, j, 3] = x, y, zq, w
                continue
            rx, ry, rz = rs * np.float64(z[i, j, 3]), rs * np.float64(z[i, j, 4]), rs * np.float64(z[i, j, 5])
            angle = math.sqrt(rx * rx + ry * ry + rz * rz)
            half = 0.5 * angle
            k = 0.5 - angle * angle / 48.0 if angle <= 1e-6 else math.sin(half) / angle
            bx, by, bz, bw = k * rx, k * ry, k * rz, math.cos(half)
            norm = math.sqrt(x * x + y * y + zq * zq + w * w)
            x, y, zq, w = x / norm, y / norm, zq / norm, w / norm
            quat_o[i, j, 0] = w * bx + bw * x + (y * bz - zq * by)
            quat_o[i, j, 1] = w * by + bw * y + (zq * bx - x * bz)
            quat_o[i, j, 2] = w * bz + bw * zq + (x * by - y * bx)
            quat_o[i, j, 3] = w * bw - (x * bx + y * by + zq * bz)
    return pos_o, quat_o
