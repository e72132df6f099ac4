"""The grid search's sum of squares in one compiled loop (numba): :func:`~euc_ros.core.identify.fit.sse_grid`
without the (grid x chunk) temporaries. The same per-sample arithmetic; the sums accumulate sample by sample
(numpy's chunked sums add in another order: equal to round-off). Compiled on first use and cached on disk
(numba ``cache=True``, next to this file).
"""
from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, nogil=True, error_model="numpy")
def sse_curve(coef, h):
    """``sum_i ((c a2 h + c a1) h + c a0)^2 / (d1 h + d0)^2`` for every ``h``; ``coef`` (6, n) the rows
    ``c, a0, a1, a2, d0, d1`` of :func:`~euc_ros.core.identify.fit.residual_coefficients`."""
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
