"""The median of long arrays, exactly numpy's, with most of the selection skipped.

The robust scales of a recording (the pose noise, the links' sliding) take medians over every frame: hundreds
of thousands of values, where :func:`numpy.median`'s selection (``partition``) costs about 10 ns a value.
:func:`median` selects only among the values near the median: a deterministic sample of about
:data:`SAMPLE` values brackets it, the values below the bracket are counted, and the order statistics the
median needs are selected among those inside. That is the same element(s) numpy selects, averaged the same
way, so the result is numpy's bit for bit; when the bracket misses (a sample unlike the whole), numpy's own
selection runs instead. NaN anywhere gives NaN, as numpy does.

>>> import numpy as np
>>> x = np.random.default_rng(0).standard_normal(100_001)
>>> bool(median(x) == np.median(x))
True
"""
from __future__ import annotations

import numpy as np

#: Below this many values numpy's selection is used directly.
MIN_SIZE = 4096
#: Values in the bracketing sample (every ``n // SAMPLE``-th value).
SAMPLE = 1024
#: The bracket's half-width in sample ranks, in standard deviations of the sample median's rank
#: (``sqrt(SAMPLE) / 2``): wide enough that a representative sample almost never misses.
BRACKET_SIGMAS = 4.0


def _median_1d(x: np.ndarray) -> float:
    n = x.size
    if n < MIN_SIZE:
        return float(np.median(x))
    if np.isnan(x).any():
        return float("nan")
    k_lo, k_hi = (n - 1) // 2, n // 2                 # the order statistics numpy averages (equal for odd n)
    sample = np.sort(x[::max(1, n // SAMPLE)])
    m = sample.size
    half = int(np.ceil(BRACKET_SIGMAS * 0.5 * np.sqrt(m)))
    lo, hi = sample[max(0, m // 2 - half)], sample[min(m - 1, m // 2 + half)]
    below = int(np.count_nonzero(x < lo))
    inside = x[(x >= lo) & (x <= hi)]
    if not (below <= k_lo and k_hi < below + inside.size):
        return float(np.median(x))                    # the bracket missed: numpy's selection over everything
    a, b = k_lo - below, k_hi - below
    part = np.partition(inside, [a, b] if a != b else a)
    # numpy's median is the mean of the selected elements: (x_a + x_b) / 2, or x_a alone
    return float(part[a]) if a == b else float(np.mean(part[[a, b]]))


def median(a, axis: int | None = None, keepdims: bool = False):
    """:func:`numpy.median` of ``a`` (float64), over everything (``axis`` None) or along ``axis``.

    Equal to numpy's bit for bit (module docstring).

    Parameters
    ----------
    a : array_like
        Values, converted to float64.
    axis : int, optional
        Axis to take the median along; None for all values.
    keepdims : bool
        Keep the reduced axis (or all axes when ``axis`` is None) with length one.

    Returns
    -------
    float or numpy.ndarray
        The median: a float when ``axis`` is None and not ``keepdims``, else an array.
    """
    a = np.asarray(a, dtype=float)
    if axis is None:
        out = _median_1d(a.ravel())
        return np.full((1,) * a.ndim, out) if keepdims else out
    moved = np.moveaxis(a, axis, -1)
    rows = moved.reshape(-1, moved.shape[-1])
    vals = np.array([_median_1d(np.ascontiguousarray(r)) for r in rows]).reshape(moved.shape[:-1])
    return np.expand_dims(vals, axis) if keepdims else vals
