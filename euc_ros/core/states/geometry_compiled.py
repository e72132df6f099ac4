"""The segments geometry of many frames in one compiled loop (numba).

What :func:`~euc_ros.core.states.geometry.frame_geometry` gives for ``cog_method="segments"``, for the outputs
the states are made of (:data:`~euc_ros.core.states.geometry.GEOMETRY_KEYS`).

The vectorized numpy path makes some thirty temporaries of the block's size per call (rotation matrices,
each body's rotated offset, the moving frame's components); a recording's geometry is evaluated several
times per analysis (the states, the filter choice, every re-noised SIMEX replicate), and those passes over
memory were its cost. Here every frame is computed in registers, with the same formulas in the same order,
so the results equal the numpy path's to round-off (the transcendental functions may differ in the last
bit between numpy's and the C library's implementations; ``test_geometry_compiled.py`` compares them).
Compiled on first use and cached on disk (numba ``cache=True``, next to this file).
"""
from __future__ import annotations

import math

import numba
import numpy as np

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def _rotation(x, y, z, w):
    """Rotation matrix entries of the quaternion (x, y, z, w), normalised (all NaN when not finite or zero).

    :func:`~euc_ros.core.rotations.rotation_matrices`' arithmetic.
    """
    n2 = x * x + y * y + z * z + w * w
    s = 2.0 / n2 if (n2 == n2 and n2 > 0.0 and n2 != math.inf) else math.nan
    xx, yy, zz = s * x * x, s * y * y, s * z * z
    xy, xz, yz = s * x * y, s * x * z, s * y * z
    wx, wy, wz = s * w * x, s * w * y, s * w * z
    return (1.0 - (yy + zz), xy - wz, xz + wy,
            xy + wz, 1.0 - (xx + zz), yz - wx,
            xz - wy, yz + wx, 1.0 - (xx + yy))


@_jit
def _finite(a, b, c):
    return a == a and b == b and c == c and abs(a) != math.inf and abs(b) != math.inf and abs(c) != math.inf


@_jit
def segments_geometry(position, quat, tracked, euc_row, pivot_to_wheel, l0, seg_rows, seg_frac, seg_off, total,
                      complete, first, stop):
    """Per frame ``first .. stop - 1`` of ``position`` (b, n, 3), ``quat`` (b, n, 4), ``tracked`` (b, n).

    ``psi, theta, gamma, phi_eq3, phi_hinge`` (stop - first,), ``C, G`` (stop - first, 3),
    ``has_euc, has_rider`` (stop - first,).

    ``euc_row``: the EUC body's row (-1: absent); ``pivot_to_wheel`` (3,), ``l0``: the EUC's geometry;
    ``seg_rows, seg_frac, seg_off`` (k,), (k,), (k, 3): the weighted segments present, ``total`` the sum of
    all weighted fractions, ``complete`` whether every weighted segment is present.
    """
    n = stop - first
    nan = math.nan
    psi_o = np.empty(n)
    theta_o = np.empty(n)
    gamma_o = np.empty(n)
    eq3_o = np.empty(n)
    hinge_o = np.empty(n)
    C_o = np.empty((n, 3))
    G_o = np.empty((n, 3))
    has_euc_o = np.empty(n, np.bool_)
    has_rider_o = np.empty(n, np.bool_)
    px, py, pz = pivot_to_wheel[0], pivot_to_wheel[1], pivot_to_wheel[2]
    for o in range(n):
        j = first + o
        he = False
        if euc_row >= 0:
            he = (tracked[euc_row, j] and _finite(position[euc_row, j, 0], position[euc_row, j, 1],
                                                  position[euc_row, j, 2])
                  and _finite(quat[euc_row, j, 0], quat[euc_row, j, 1], quat[euc_row, j, 2])
                  and quat[euc_row, j, 3] == quat[euc_row, j, 3] and abs(quat[euc_row, j, 3]) != math.inf)
        if he:
            ex, ey, ez = position[euc_row, j, 0], position[euc_row, j, 1], position[euc_row, j, 2]
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = _rotation(quat[euc_row, j, 0], quat[euc_row, j, 1],
                                                                    quat[euc_row, j, 2], quat[euc_row, j, 3])
        else:
            ex = ey = ez = nan
            r00 = r01 = r02 = r10 = r11 = r12 = r20 = r21 = r22 = nan
        theta = math.asin(min(1.0, max(-1.0, r21))) if r21 == r21 else nan
        gamma = math.atan2(-r20, r22)
        psi = math.atan2(-r01, r11)
        cx = ex + (r00 * px + r01 * py + r02 * pz)
        cy = ey + (r10 * px + r11 * py + r12 * pz)
        cz = ez + (r20 * px + r21 * py + r22 * pz)
        ax, ay, az = cx - l0 * r02, cy - l0 * r12, cz - l0 * r22
        hr = complete
        gx = gy = gz = 0.0
        for k in range(seg_rows.shape[0]):
            i = seg_rows[k]
            x, y, z, w = quat[i, j, 0], quat[i, j, 1], quat[i, j, 2], quat[i, j, 3]
            ok = (tracked[i, j] and _finite(position[i, j, 0], position[i, j, 1], position[i, j, 2])
                  and _finite(x, y, z) and w == w and abs(w) != math.inf)
            if not ok:
                hr = False
                continue
            nq = math.sqrt(x * x + y * y + z * z + w * w)
            x, y, z, w = x / nq, y / nq, z / nq, w / nq
            vx, vy, vz = seg_off[k, 0], seg_off[k, 1], seg_off[k, 2]
            tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
            f = seg_frac[k]
            gx += f * (position[i, j, 0] + (vx + w * tx + (y * tz - z * ty)))
            gy += f * (position[i, j, 1] + (vy + w * ty + (z * tx - x * tz)))
            gz += f * (position[i, j, 2] + (vz + w * tz + (x * ty - y * tx)))
        if hr:
            gx, gy, gz = gx / total, gy / total, gz / total
        else:
            gx = gy = gz = nan
        cp, sp, ct, st = math.cos(psi), math.sin(psi), math.cos(theta), math.sin(theta)
        vx, vy, vz = gx - cx, gy - cy, gz - cz
        x1, y1 = cp * vx + sp * vy, -sp * vx + cp * vy
        eq3 = math.atan2(x1, -st * y1 + ct * vz)
        vx, vy, vz = gx - ax, gy - ay, gz - az
        x1, y1 = cp * vx + sp * vy, -sp * vx + cp * vy
        hinge = math.atan2(x1, -st * y1 + ct * vz)
        psi_o[o], theta_o[o], gamma_o[o], eq3_o[o], hinge_o[o] = psi, theta, gamma, eq3, hinge
        C_o[o, 0], C_o[o, 1], C_o[o, 2] = cx, cy, cz
        G_o[o, 0], G_o[o, 1], G_o[o, 2] = gx, gy, gz
        has_euc_o[o], has_rider_o[o] = he, hr
    return psi_o, theta_o, gamma_o, eq3_o, hinge_o, C_o, G_o, has_euc_o, has_rider_o


@_jit
def link_vectors(position, quat, usable, ja, jb, vector):
    """``R_a^T (p_b - p_a) - vector`` (n, 3) of the link from body row ``ja`` to ``jb``, and where both are usable.

    The bodies are rows of ``position`` (b, n, 3) and ``quat`` (b, n, 4); usable as ``usable`` (b, n) says. An
    unusable pose counts as a zero pivot with the identity rotation (masked out by the caller).
    :func:`~euc_ros.core.rotations.quat_rotate`'s arithmetic with the conjugate of ``a``'s quaternion.
    """
    n = position.shape[1]
    d = np.empty((n, 3))
    both = np.empty(n, np.bool_)
    for j in range(n):
        oka, okb = usable[ja, j], usable[jb, j]
        if oka:
            x, y, z, w = -quat[ja, j, 0], -quat[ja, j, 1], -quat[ja, j, 2], quat[ja, j, 3]
            ax, ay, az = position[ja, j, 0], position[ja, j, 1], position[ja, j, 2]
        else:
            x, y, z, w = -0.0, -0.0, -0.0, 1.0
            ax = ay = az = 0.0
        if okb:
            vx, vy, vz = position[jb, j, 0] - ax, position[jb, j, 1] - ay, position[jb, j, 2] - az
        else:
            vx, vy, vz = 0.0 - ax, 0.0 - ay, 0.0 - az
        nq = math.sqrt(x * x + y * y + z * z + w * w)
        x, y, z, w = x / nq, y / nq, z / nq, w / nq
        tx, ty, tz = 2.0 * (y * vz - z * vy), 2.0 * (z * vx - x * vz), 2.0 * (x * vy - y * vx)
        d[j, 0] = vx + w * tx + (y * tz - z * ty) - vector[0]
        d[j, 1] = vy + w * ty + (z * tx - x * tz) - vector[1]
        d[j, 2] = vz + w * tz + (x * ty - y * tx) - vector[2]
        both[j] = oka and okb
    return d, both
