"""A lab field's knotted levels: fitted over the span two passes meet, nothing said beyond it.

:func:`~euc_ros.core.residual.splines.revisited_span` is checked against a count on a fine grid of the passes a
random back-and-forth path makes (the path built from its own turning points, so the passes are known); the
local B-splines against their defining properties (a partition of unity inside the span, zero beyond its
support) and the complete cubic spline's error bound.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.residual.families import LAB_LEVELS, REVERSAL_M
from euc_ros.core.residual.splines import local_bspline_basis, revisited_span


def path(turns: np.ndarray, per_metre: int = 40) -> np.ndarray:
    """A coordinate sweeping linearly from each turning point to the next."""
    parts = [np.linspace(a, b, max(int(abs(b - a) * per_metre), 2))[:-1] for a, b in zip(turns[:-1], turns[1:])]
    return np.concatenate(parts + [turns[-1:]])


def covered_twice(turn_lists, grid: np.ndarray) -> np.ndarray:
    """On a grid, whether two or more sweeps (of any recording) cover each point: counted, not intersected."""
    count = np.zeros(grid.size, int)
    for turns in turn_lists:
        for a, b in zip(turns[:-1], turns[1:]):
            count += (grid >= min(a, b)) & (grid <= max(a, b))
    return count >= 2


@pytest.mark.parametrize("seed", range(12))
def test_the_revisited_span_is_the_hull_of_what_two_passes_cover(seed):
    rng = np.random.default_rng(seed)
    turn_lists = []
    for _ in range(int(rng.integers(1, 4))):
        # turning points alternate in direction and move by more than the reversal (a pass ends at each)
        k = int(rng.integers(1, 4))
        steps = rng.uniform(1.0, 12.0, k) * np.where(np.arange(k) % 2 == 0, 1.0, -1.0) * rng.choice([-1.0, 1.0])
        turn_lists.append(np.concatenate([[rng.uniform(-5.0, 5.0)], rng.uniform(-5.0, 5.0) + np.cumsum(steps)]))
    span = revisited_span([path(t) for t in turn_lists], REVERSAL_M)
    grid = np.linspace(-60.0, 60.0, 24001)
    twice = covered_twice(turn_lists, grid)
    if not twice.any():
        assert span is None
        return
    lo, hi = grid[twice][0], grid[twice][-1]
    assert span is not None
    # a pass's ends are samples of the path (1/40 m apart) and the grid's points 5 mm apart
    assert abs(span[0] - lo) <= 0.03 and abs(span[1] - hi) <= 0.03, (span, (lo, hi), turn_lists)


def test_jitter_below_the_reversal_does_not_start_a_pass():
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 10.0, 1000) + 0.02 * rng.standard_normal(1000)     # 100 times the capture's noise
    assert revisited_span([x], REVERSAL_M) is None
    assert revisited_span([x, x[::-1][:400]], REVERSAL_M) == pytest.approx((float(x[::-1][:400].min()), x.max()),
                                                                           abs=0.2)


@pytest.mark.parametrize("level", [lv for lv, (_, spacing) in enumerate(LAB_LEVELS) if spacing is not None])
def test_local_splines_fit_a_field_inside_the_span_and_vanish_beyond_it(level):
    degree, spacing = LAB_LEVELS[level]
    lo, hi = 2.0, 13.0
    x = np.linspace(-10.0, 25.0, 7001)
    B = local_bspline_basis(x, lo, hi, degree, spacing)
    pieces = int(np.ceil((hi - lo) / spacing))
    step = (hi - lo) / pieces
    assert B.shape == (x.size, pieces + degree)
    inside = (x >= lo) & (x <= hi)
    assert np.allclose(B[inside].sum(axis=1), 1.0)
    assert np.all(B[(x < lo - degree * step) | (x > hi + degree * step)] == 0.0)
    assert np.all(B[~inside].sum(axis=1) < 1.0 - 1e-12)     # the field decays beyond the span
    # a field of wavelength 3 m inside the span, to the complete cubic spline's bound 5/384 H^4 max|f''''|
    w = 2.0 * np.pi / 3.0
    f = np.sin(w * x[inside] + 0.4)
    c, *_ = np.linalg.lstsq(B[inside], f, rcond=None)
    err = np.max(np.abs(B[inside] @ c - f))
    bound = 5.0 / 384.0 * step ** 4 * w ** 4
    # least squares minimises the mean square, not the maximum: up to the basis' Lebesgue constant (< 2 for
    # cubic B-splines on uniform knots: de Boor's bound on the max-norm of the L2 projection is about 3)
    assert err <= 3.0 * bound or err < 1e-3, (err, bound)
