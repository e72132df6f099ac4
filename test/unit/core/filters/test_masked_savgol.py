"""Least-squares polynomial fits through the recorded samples of every window (masked Savitzky-Golay).

Checked against Savitzky-Golay itself where no sample is missing (its ends included), against the analytic
derivatives of a polynomial of the fit's order where samples are missing (the fit is exact for it, whatever the
pattern), and for the variance inflation its normal equations predict: 1 with the full window, the measured
scatter of the second derivative on white noise next to a gap, an independent construction's one-sided
weights at the ends. The fits of chosen rows are those of every row, number for number.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.filters.derivatives import savgol_derivatives
from euc_ros.core.filters.masked_savgol import masked_savgol

DT = 1.0 / 120.0


def test_without_missing_samples_the_fits_are_savitzky_golay():
    rng = np.random.default_rng(1)
    t = np.arange(2400) * DT
    y = np.column_stack([np.sin(2 * np.pi * 0.7 * t) + 0.3 * np.sin(2 * np.pi * 2.1 * t), np.cos(1.3 * t)]) + 4.0
    y += rng.normal(0.0, 1e-3, y.shape)
    ref = savgol_derivatives(DT, y, window=145, polyorder=8)
    out = masked_savgol(y, 145, 8, DT)
    inner = slice(72, t.size - 72)
    for a, b in zip(ref, (out.y, out.y_dot, out.y_ddot)):
        np.testing.assert_allclose(b[inner], a[inner], rtol=0, atol=1e-10 * np.max(np.abs(a[inner])))
    np.testing.assert_allclose(out.inflation[inner], 1.0, rtol=1e-9)
    assert out.usable[inner].all() and out.recorded.all()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_polynomial_of_the_fits_order_is_exact_through_any_gaps(seed):
    rng = np.random.default_rng(seed)
    n, p = 1200, 6
    t = np.arange(n) * DT
    c = rng.normal(0.0, 1.0, p + 1)
    poly = np.polynomial.Polynomial(c, domain=[0, t[-1]], window=[-1, 1])
    y = poly(t)
    keep = rng.uniform(size=n) > 0.05                        # 5 % dropped frames
    for start in rng.integers(100, n - 120, 4):               # and four occlusions of 4-20 frames
        keep[start:start + rng.integers(4, 21)] = False
    out = masked_savgol(np.where(keep, y, np.nan), 121, p, DT)
    u = out.usable
    assert u.mean() > 0.9
    for est, exact in ((out.y, y), (out.y_dot, poly.deriv(1)(t)), (out.y_ddot, poly.deriv(2)(t))):
        scale = np.max(np.abs(exact))
        np.testing.assert_allclose(est[u], exact[u], rtol=0, atol=1e-8 * scale)


def test_the_inflation_is_the_scatter_of_the_second_derivative_next_to_a_gap():
    """On white noise the second derivative's variance next to a gap over its variance far from it is the
    predicted inflation (500 noise draws: the ratio's relative standard error is about 9 %)."""
    rng = np.random.default_rng(3)
    n, w, p = 600, 61, 4
    keep = np.ones(n, bool)
    keep[300:320] = False
    near, far = 325, 150
    draws = rng.normal(0.0, 1.0, (n, 500))
    out = masked_savgol(np.where(keep[:, None], draws, np.nan), w, p, DT)
    ratio = np.var(out.y_ddot[near]) / np.var(out.y_ddot[far])
    assert out.inflation[far] == pytest.approx(1.0)
    assert out.inflation[near] > 1.5
    assert ratio == pytest.approx(out.inflation[near], rel=4 * 0.09)


def test_a_gap_longer_than_the_window_is_not_bridged():
    y = np.arange(600, dtype=float)
    y[200:330] = np.nan                                      # 130 samples > the 61-sample window
    out = masked_savgol(y, 61, 4, DT)
    assert not out.usable[230:300].any() and np.isnan(out.y_ddot[265])
    assert out.usable[100] and out.usable[400]


def test_bad_arguments_name_the_key():
    with pytest.raises(ConfigError, match="window"):
        masked_savgol(np.zeros(50), 10, 4, DT)
    with pytest.raises(ConfigError, match="dt"):
        masked_savgol(np.zeros(50), 11, 4, 0.0)
    with pytest.raises(InputError, match="y"):
        masked_savgol(np.zeros((5, 5, 5)), 11, 4, DT)
    with pytest.raises(ConfigError, match="ends"):
        masked_savgol(np.zeros(50), 11, 4, DT, ends="reflect")
    with pytest.raises(InputError, match="rows"):
        masked_savgol(np.zeros(50), 11, 4, DT, rows=[0, 50])


def test_at_the_ends_the_first_and_last_windows_are_evaluated_off_centre():
    """With every sample recorded, the rows within half a window of either end are Savitzky-Golay's ends (the
    fit of the first or last whole window, ``mode="interp"``), and their inflation is the one-sided fit's
    variance over the centred one's: the sums of squares of the second-derivative weights of an independent
    construction (``euc_ros.testing.savgol_coefficients``, a pseudo-inverse of the monomial Vandermonde)."""
    from euc_ros.testing import savgol_coefficients

    rng = np.random.default_rng(7)
    w, p, h = 145, 6, 72
    t = np.arange(900) * DT
    y = np.column_stack([np.sin(2.3 * t), np.cos(0.9 * t)]) + rng.normal(0.0, 1e-3, (t.size, 2)) + 2.0
    ref = savgol_derivatives(DT, y, window=w, polyorder=p)
    out = masked_savgol(y, w, p, DT)
    for a, b in zip(ref, (out.y, out.y_dot, out.y_ddot)):
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-10 * np.max(np.abs(a)))
    centre = np.sum(savgol_coefficients(w, p, 2, DT) ** 2)
    one_sided = np.array([np.sum(savgol_coefficients(w, p, 2, DT, pos) ** 2) for pos in range(h)]) / centre
    np.testing.assert_allclose(out.inflation[:h], one_sided, rtol=1e-8)
    np.testing.assert_allclose(out.inflation[::-1][:h], one_sided, rtol=1e-8)
    assert np.array_equal(out.usable[:h], one_sided <= 4.0)
    assert 0 < out.usable[:h].sum() < h                           # part of each end, not all of it


def test_truncated_ends_fit_the_centred_window_through_the_samples_it_has():
    """``ends="truncate"``: the first row's fit is the one-sided polynomial through the ``h + 1`` samples from
    it on, evaluated at the first (the independent construction's weights at position 0 of that window). The
    masked fit solves normal equations in the Legendre basis, whose round-off is the least-squares bound
    (``savgol_roundoff``) times that basis's condition number on the window (the normal matrix's is its
    square)."""
    from numpy.polynomial import legendre

    from euc_ros.testing import savgol_coefficients, savgol_roundoff

    rng = np.random.default_rng(8)
    w, p, h = 61, 4, 30
    t = np.arange(300) * DT
    y = np.sin(3.0 * t) + rng.normal(0.0, 1e-3, t.size)
    out = masked_savgol(y, w, p, DT, ends="truncate")
    kappa = np.linalg.cond(legendre.legvander(np.arange(h + 1) / h, p))
    scale = np.max(np.abs(y[:h + 1]))
    for est, d in ((out.y, 0), (out.y_dot, 1), (out.y_ddot, 2)):
        exact = savgol_coefficients(h + 1, p, d, DT, 0) @ y[:h + 1]
        assert abs(est[0] - exact) <= kappa * savgol_roundoff(h + 1, p, d, DT, scale, pos=0), d
    assert not out.usable[0]                                     # one-sided over half a window: too uncertain


@pytest.mark.parametrize("ends", ["shift", "truncate"])
def test_the_fits_of_chosen_rows_are_those_of_every_row(ends):
    """Solving only the wanted rows' windows changes no number beyond round-off, whatever the rows and the gaps:
    with rows that leave no gap between their windows, the same numbers; else the correlations' round-off
    (the FFT's, ``eps`` times the window's sum of weights, about ``window``, relative to the samples' scale)
    amplified by the normal matrix's condition number (under 1e5 for every fit of order 6 whose inflation is
    under 4: 8e4 the largest of 3000 random masks of 121-433 samples)."""
    from numpy.polynomial import legendre

    rng = np.random.default_rng(11)
    n, w, p = 2000, 121, 6
    t = np.arange(n) * DT
    y = np.column_stack([np.sin(1.7 * t), t ** 2, np.cos(0.4 * t)]) + rng.normal(0.0, 1e-3, (n, 3))
    keep = rng.uniform(size=n) > 0.01
    for start in rng.integers(0, n - 30, 6):
        keep[start:start + rng.integers(2, 21)] = False
    y[~keep] = np.nan
    full = masked_savgol(y, w, p, DT, ends=ends)
    fields = ("y", "y_dot", "y_ddot", "inflation", "usable", "recorded")
    dense = rng.permutation(n)[:n - 50]                          # unsorted; no run of 50 rows left out
    part = masked_savgol(y, w, p, DT, rows=dense, ends=ends)
    for f in fields:
        assert np.array_equal(getattr(part, f), getattr(full, f)[dense], equal_nan=True), f
    sparse = np.r_[0, n - 1, rng.choice(np.arange(1, n - 1), 60, replace=False)]
    part = masked_savgol(y, w, p, DT, rows=sparse, ends=ends)
    assert np.array_equal(part.recorded, full.recorded[sparse])
    assert np.array_equal(part.usable, full.usable[sparse])
    use = part.usable
    scale = np.nanmax(np.abs(y - np.nanmedian(y, axis=0)))
    eye = np.eye(p + 1)
    for d, f in enumerate(("y", "y_dot", "y_ddot")):
        g = np.abs([legendre.legval(1.0, legendre.legder(eye[k], d)) for k in range(p + 1)]).sum()
        tol = 1e5 * w * np.finfo(float).eps * scale * g / ((w // 2) * DT) ** d
        np.testing.assert_allclose(getattr(part, f)[use], getattr(full, f)[sparse][use], rtol=0, atol=tol)
    np.testing.assert_allclose(part.inflation[use], full.inflation[sparse][use], rtol=1e5 * w * np.finfo(float).eps)
    one = masked_savgol(y, w, p, DT, rows=[n - 3], ends=ends)          # its window runs past the last row
    np.testing.assert_allclose(one.inflation, full.inflation[[n - 3]], rtol=1e5 * w * np.finfo(float).eps)


def test_the_kept_plan_of_a_mask_gives_the_fits_made_without_it():
    # the mask's part of the fits (normal matrices, basis, variance factors) is kept per mask and rows; fits of
    # other values on the same samples, made with the kept part, must be those made from nothing, number for
    # number, and another mask with the same rows must not take it
    from euc_ros.core.filters import masked_savgol as ms

    rng = np.random.default_rng(5)
    n, w, p = 3000, 61, 4
    t = np.arange(n) * DT
    keep = rng.uniform(size=n) > 0.02
    keep[700:730] = False
    rows = np.flatnonzero(keep)[::7]
    fields = ("y", "y_dot", "y_ddot", "inflation", "usable", "recorded")

    def fresh(y):
        ms._PLANS.clear()
        return ms.masked_savgol(y, w, p, DT, rows=rows)

    first = np.where(keep[:, None], np.column_stack([np.sin(t), t ** 2]), np.nan)
    second = np.where(keep[:, None], np.column_stack([np.cos(2 * t), np.exp(-t)]) + rng.normal(0, 1e-3, (n, 2)),
                      np.nan)
    made = fresh(second)
    ms.masked_savgol(first, w, p, DT, rows=rows)             # keeps the plan of this mask and these rows
    assert len(ms._PLANS) == 1
    kept = ms.masked_savgol(second, w, p, DT, rows=rows)
    for f in fields:
        assert np.array_equal(getattr(kept, f), getattr(made, f), equal_nan=True), f
    kept.y[:] = 0.0                                           # the results are the caller's, not the plan's
    again = ms.masked_savgol(second, w, p, DT, rows=rows)
    assert np.array_equal(again.y, made.y, equal_nan=True)
    other = keep.copy()
    other[1500:1540] = False                                  # another gap, the same rows
    third = np.where(other[:, None], second, np.nan)
    shared = ms.masked_savgol(third, w, p, DT, rows=rows)
    alone = fresh(third)
    assert len(ms._PLANS) == 1
    for f in fields:
        assert np.array_equal(getattr(shared, f), getattr(alone, f), equal_nan=True), f
    assert not np.array_equal(shared.inflation, made.inflation, equal_nan=True)   # the gap changed the fits
