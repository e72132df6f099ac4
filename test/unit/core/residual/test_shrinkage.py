"""The discovery's shrunken fold fits and its wheel-phase alignment, against closed forms and known truths."""
from __future__ import annotations

import numpy as np

from euc_ros.core.residual.families import align_wheel_phases, phase_rotations, uniform_knots, wheel_phase_mix
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


def test_phase_mix_is_the_shifted_fourier_series():
    # written out independently: sin(k (theta + d)), cos(k (theta + d)) per recording
    rng = np.random.default_rng(4)
    K, runs = 3, 2
    theta = [rng.uniform(0, 20, 50), rng.uniform(0, 20, 40)]
    d = np.array([0.0, 1.234])
    raw = np.zeros((90, 2 * K * runs))
    want = np.zeros((90, 2 * K))
    k = np.arange(1, K + 1)
    for j, th in enumerate(theta):
        rows = slice(0, 50) if j == 0 else slice(50, 90)
        raw[rows, 2 * K * j:2 * K * (j + 1)] = np.concatenate([np.sin(np.outer(th, k)), np.cos(np.outer(th, k))], 1)
        s = np.outer(th + d[j], k)
        want[rows] = np.concatenate([np.sin(s), np.cos(s)], 1)
    assert np.allclose(raw @ wheel_phase_mix(d, K), want, atol=1e-12)
    assert phase_rotations(d, K).shape == (2, 2 * K, 2 * K)


def test_recordings_tyre_angles_are_found_again():
    # one tyre's periodic force (4 harmonics) seen by 3 recordings that start at unknown wheel angles
    rng = np.random.default_rng(5)
    K = 4
    a = rng.standard_normal(2 * K)
    true = np.array([0.0, 2.1, 4.9])
    raw, r = [], []
    for j, d in enumerate(true):
        th = np.cumsum(rng.uniform(0.02, 0.08, 600))
        k = np.arange(1, K + 1)
        F = np.concatenate([np.sin(np.outer(th, k)), np.cos(np.outer(th, k))], 1)
        block = np.zeros((th.size, 2 * K * 3))
        block[:, 2 * K * j:2 * K * (j + 1)] = F
        raw.append(block)
        s = np.outer(th + d, k)
        r.append(np.concatenate([np.sin(s), np.cos(s)], 1) @ a + 0.3 * rng.standard_normal(th.size))
    est = align_wheel_phases(np.concatenate(raw), np.concatenate(r), K, 3)
    err = np.angle(np.exp(1j * (est - true)))
    # grid step 2 pi / 72 refined tenfold: the offsets to well within a degree here
    assert np.max(np.abs(err)) < np.radians(1.0)


def test_lab_knots_are_evenly_spaced_in_metres():
    kn = uniform_knots(-3.0, 21.0, 2.0)
    assert kn.size == 11 and np.allclose(np.diff(kn), 2.0)
    assert uniform_knots(0.0, 1.5, 4.0).size == 0
    assert uniform_knots(0.0, 0.0, 1.0).size == 0
