"""Compiled loop of :func:`~euc_ros.core.model.torque.torque_difference` (numba).

The residual analysis evaluates ``M_d1 - M_d2`` some hundreds of times per run, and numpy's version makes some
forty temporary arrays each time. The same expression, term by term in numpy's order, on each sample: equal to
numpy's bit for bit (``test_torque.py``). Compiled on first use and cached on disk (numba ``cache=True``).
"""
from __future__ import annotations

import math

import numba


@numba.njit(cache=True, nogil=True, error_model="numpy")
def torque_difference_loop(g, ph, gd, pd, xdd, gdd, pdd, S, extra, out):
    """``M_d1 - M_d2`` per sample into ``out``.

    ``S`` (12, 1) or (12, n): the constants ``(R, R m11, -k, mh, m22, -mh l0, m33, -mh, mh l0, k g, mh g, k)``
    as :func:`~euc_ros.core.model.torque.torque_difference` forms them, one column for every sample or one per
    sample (parameters given per sample); ``extra``: (n, 3) extra generalized force, or (0, 3).
    """
    has_extra = extra.shape[0] > 0
    per_sample = S.shape[1] > 1
    for i in range(out.shape[0]):
        j = i if per_sample else 0
        R, Rm11, nk, mh, m22, c23, m33, nmh, mhl0, kg, mhg, k = (S[0, j], S[1, j], S[2, j], S[3, j], S[4, j],
                                                                S[5, j], S[6, j], S[7, j], S[8, j], S[9, j],
                                                                S[10, j], S[11, j])
        gi, pi = g[i], ph[i]
        cg, sg = math.cos(gi), math.sin(gi)
        cp, sp = math.cos(pi), math.sin(pi)
        cpg, spg = math.cos(pi - gi), math.sin(pi - gi)
        m12 = nk * cg
        m13 = mh * cp
        m23 = c23 * cpg
        D = Rm11 + m12 + m13
        pd2, gd2 = pd[i] * pd[i], gd[i] * gd[i]
        w = (gdd[i] * (R * m12 + m22 + m23) + pdd[i] * (R * m13 + m23 + m33)
             + R * (nmh * pd2 * sp + k * gd2 * sg) + mhl0 * (pd2 - gd2) * spg + kg * sg - mhg * sp)
        if has_extra:
            w = w - (R * extra[i, 0] + extra[i, 1] + extra[i, 2])
        out[i] = Rm11 * (xdd[i] * D + w) / D
    return out
