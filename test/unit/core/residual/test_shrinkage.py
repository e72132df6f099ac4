"""The discovery's shrunken fold fits and the lab field's knots, against closed forms and known truths."""
from __future__ import annotations

import numpy as np

from euc_ros.core.residual.families import uniform_knots
from euc_ros.core.residual.shrinkage import evidence_ridge, fit_with_free


def test_well_determined_columns_are_least_squares():
    # 2000 independent samples, 3 columns, noise 0.1: the prior's pull is of order (sigma / |c|)^2 / n
    rng = np.random.default_rng(0)
    B = rng.standard_normal((2000, 3))
    c_true = np.array([1.0, -2.0, 0.5])
    r = B @ c_true + 0.1 * rng.standard_normal(2000)
    c, ratio = evidence_ridge(B, r)
    ls = np.linalg.lstsq(B, r, rcond=None)[0]
    # on unit-norm, nearly orthogonal columns (singular values ~1) the posterior mean is least squares scaled by
    # 1 / (1 + ratio): a relative change of the order of the ridge ratio
    assert ratio < 1e-3
    assert np.max(np.abs(c - ls)) <= 10 * ratio * np.max(np.abs(ls)) + 1e-12
    assert np.allclose(c, c_true, atol=5 * 0.1 / np.sqrt(2000))


def test_a_column_the_data_hardly_see_is_shrunk():
    # column 2 is non-zero on 3 samples only: least squares fits those samples' noise with any size
    rng = np.random.default_rng(1)
    n = 500
    B = np.column_stack([rng.standard_normal(n), np.zeros(n)])
    B[:3, 1] = 1e-3
    r = 2.0 * B[:, 0] + 0.5 * rng.standard_normal(n)
    ls = np.linalg.lstsq(B, r, rcond=None)[0]
    # the prior is set on the columns' common scale (a group's columns alike), as the discovery does
    scale = np.full(2, np.linalg.norm(B[:, 0]))
    c, _ = evidence_ridge(B, r, norms=scale)
    assert abs(ls[1]) > 20.0
    assert abs(c[1]) < 0.05 * abs(ls[1])
    assert abs(c[0] - ls[0]) < 0.05


def test_tempering_shrinks_more_when_samples_are_correlated():
    rng = np.random.default_rng(2)
    B = rng.standard_normal((400, 6))
    r = B @ np.array([0.2, 0, 0, 0, 0, 0.1]) + rng.standard_normal(400)
    _, ratio_all = evidence_ridge(B, r)
    _, ratio_few = evidence_ridge(B, r, n_eff=40)
    assert ratio_few > ratio_all


def test_the_free_column_is_fitted_without_a_prior():
    rng = np.random.default_rng(3)
    n = 300
    f = rng.standard_normal(n)
    B = rng.standard_normal((n, 2))
    r = 3.0 * f + B @ np.array([0.5, -0.5]) + 0.01 * rng.standard_normal(n)
    a = fit_with_free(f, B, r)
    assert abs(a[0] - 3.0) < 0.01
    assert np.allclose(a[1:], [0.5, -0.5], atol=0.02)


def test_lab_knots_are_evenly_spaced_in_metres():
    kn = uniform_knots(-3.0, 21.0, 2.0)
    assert kn.size == 11 and np.allclose(np.diff(kn), 2.0)
    assert uniform_knots(0.0, 1.5, 4.0).size == 0
    assert uniform_knots(0.0, 0.0, 1.0).size == 0
