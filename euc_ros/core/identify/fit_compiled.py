"""Compiled loops of the h fit (numba).

The residual's per-sample coefficients in one pass over a recording, and the grid search's sum of squares
(:func:`~euc_ros.core.identify.fit.sse_grid`) without the (grid x chunk) temporaries. The coefficients are the model's
terms sorted by powers of h (the model functions extract them from three evaluations: equal to round-off); the sums
accumulate sample by sample (numpy's chunked sums add in another order: equal to round-off). Compiled on first use and
cached on disk (numba ``cache=True``, next to this file).
"""
from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, error_model="numpy")
def sse_curve(coef, h):
    """``sum_i ((c a2 h + c a1) h + c a0)^2 / (d1 h + d0)^2`` for every ``h``.

    ``coef`` (6, n): the rows ``c, a0, a1, a2, d0, d1`` of :func:`~euc_ros.core.identify.fit.residual_coefficients`.
    """
    n = coef.shape[1]
    sse = np.zeros(h.shape[0])
    for i in range(n):
        c = coef[0, i]
        x0, x1, x2 = c * coef[1, i], c * coef[2, i], c * coef[3, i]
        e0, e1 = coef[4, i], coef[5, i]
        for g in range(h.shape[0]):
            H = h[g]
            r = ((H * x2 + x1) * H + x0) / (H * e1 + e0)
            sse[g] += r * r
    return sse


@numba.njit(cache=True, nogil=True, error_model="numpy")
def consistency_coefficients(gamma, phi, gamma_dot, phi_dot, x_ddot, gamma_ddot, phi_ddot, valid, p, extra):
    """Rows ``c, a0, a1, a2, d0, d1`` of :func:`~euc_ros.core.identify.fit.residual_coefficients` where ``valid``.

    Computed in one pass over the recording.

    ``p``: ``(m, J, m0, J0, mw, Jw, R, h0, l0, g)``; ``extra``: (n, 3) extra generalized force, or (0, 3).
    The model's terms (:mod:`euc_ros.core.model.terms`, eqs (6)-(8)) sorted by powers of h: with
    ``K = m l0 - m0 h0``, ``w = [R, 1, 1]`` and ``r = M q_ddot + h_vec - Q_g - Q_extra``,

    * ``w . r = a0 + a1 h + a2 h^2`` with ``a2 = m phi_ddot`` and
      ``a1 = m (R (cos phi phi_ddot - sin phi phi_dot^2) - l0 cos(phi - gamma) (phi_ddot + gamma_ddot)
      + l0 sin(phi - gamma) (phi_dot^2 - gamma_dot^2) + cos phi x_ddot - g sin phi)``;
    * ``w . M[:, 0] = d0 + d1 h`` with ``d0 = R m11 - K cos gamma``, ``d1 = m cos phi``; ``c = R m11``.
    """
    m, J, m0, J0, mw, Jw, R, h0, l0, g = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9]
    m11 = m + m0 + mw + Jw / R**2
    K = m * l0 - m0 * h0
    I22 = J0 + m0 * h0**2 + m * l0**2
    has_extra = extra.shape[0] > 0
    out = np.empty((6, np.count_nonzero(valid)))
    j = 0
    for i in range(valid.shape[0]):
        if not valid[i]:
            continue
        ga, ph = gamma[i], phi[i]
        gd, pd = gamma_dot[i], phi_dot[i]
        xdd, gdd, pdd = x_ddot[i], gamma_ddot[i], phi_ddot[i]
        cg, sg = math.cos(ga), math.sin(ga)
        cp, sp = math.cos(ph), math.sin(ph)
        cpg, spg = math.cos(ph - ga), math.sin(ph - ga)
        a0 = (R * (m11 * xdd - K * cg * gdd + K * gd * gd * sg) + (-K * cg * xdd + I22 * gdd + K * g * sg)
              + J * pdd)
        if has_extra:
            a0 -= R * extra[i, 0] + extra[i, 1] + extra[i, 2]
        a1 = m * (R * (cp * pdd - sp * pd * pd) - l0 * cpg * (pdd + gdd) + l0 * spg * (pd * pd - gd * gd)
                  + cp * xdd - g * sp)
        out[0, j] = R * m11
        out[1, j] = a0
        out[2, j] = a1
        out[3, j] = m * pdd
        out[4, j] = R * m11 - K * cg
        out[5, j] = m * cp
        j += 1
    return out
