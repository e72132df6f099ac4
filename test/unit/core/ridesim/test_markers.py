"""Marker-level mocap (:mod:`euc_ros.core.ridesim.markers`): exact fits without noise, the fit's
noise against the small-angle prediction.

Tolerances:

* noise-free fits: poses of a few metres and layouts of <= 0.5 m go through one SVD of a 3x3
  matrix and a few products (round-off ~1e-15 relative); atol 1e-12 leaves ~100x margin;
* noise statistics: ``N`` frames of the same pose. The orientation errors ``delta`` are whitened
  with the predicted covariance ``Sigma = L L^T`` (``z = L^-1 delta``, covariance I if the
  prediction is right). Each entry ``S_jk`` of the sample covariance of ``N`` Gaussian samples of
  covariance I has standard deviation ``sqrt((1 + [j == k]) / N)``, each sample mean ``1/sqrt(N)``:
  the tests allow 5 of those (a false failure about once in 10^6 per entry; the seed is fixed
  anyway). The small-angle approximation's own error is of relative order ``(sigma / r)^2 ~ 1e-4``
  at the noise used, far below ``5 sqrt(2 / N) = 0.035`` at ``N = 40000``.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.ridesim.markers import (
    fit_poses,
    marker_positions,
    random_layout,
    rms_angle_deg,
    rotation_covariance,
    sigma_for_angle,
    synthesize,
)
from euc_ros.core.ridesim.mocap_synth import rotations_to_quats
from euc_ros.core.rotations import rotation_matrices


def _poses(rng, n):
    pos = rng.uniform(-3.0, 3.0, (n, 3)) + np.array([0.0, 0.0, 1.0])
    quat = Rotation.random(n, random_state=rng).as_quat()
    return pos, quat


@pytest.mark.parametrize("n_markers, centroid", [(3, (0.0, 0.0, 0.0)), (4, (0.0, 0.0, 0.0)),
                                                 (6, (0.0, 0.0, 0.0)), (5, (0.0, 0.0, -0.3)),
                                                 (4, (0.2, -0.1, 0.15))])
def test_noise_free_markers_give_the_poses_back(n_markers, centroid):
    rng = np.random.default_rng(n_markers)
    lay = random_layout(rng, n_markers, 0.15, centroid=centroid)
    np.testing.assert_allclose(lay.mean(axis=0), centroid, atol=1e-15)
    pos, quat = _poses(rng, 2000)
    P, R = fit_poses(marker_positions(pos, quat, lay), lay)
    assert np.abs(P - pos).max() < 1e-12
    assert np.abs(R - rotation_matrices(quat)).max() < 1e-12
    # 3 markers are coplanar: the plain SVD solution is a reflection in about half the frames
    assert np.abs(np.linalg.det(R) - 1.0).max() < 1e-12


def test_reflections_are_excluded_and_rotations_are_proper():
    rng = np.random.default_rng(1)
    lay = random_layout(rng, 3, 0.1)
    pos, quat = _poses(rng, 3000)
    w = marker_positions(pos, quat, lay) + rng.normal(0.0, 1e-3, (3000, 3, 3))
    _, R = fit_poses(w, lay)
    assert np.abs(np.linalg.det(R) - 1.0).max() < 1e-12
    assert np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max() < 1e-12
    # markers mirrored through a plane: still a rotation
    mirrored = marker_positions(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), lay) * np.array([1.0, 1.0, -1.0])
    _, Rm = fit_poses(mirrored, lay)
    assert abs(np.linalg.det(Rm) - 1.0) < 1e-12


def test_non_finite_markers_give_nan_frames_only():
    rng = np.random.default_rng(2)
    lay = random_layout(rng, 4, 0.1)
    pos, quat = _poses(rng, 10)
    w = marker_positions(pos, quat, lay)
    w[3, 1, 0] = np.nan
    P, R = fit_poses(w, lay)
    assert np.all(np.isnan(P[3])) and np.all(np.isnan(R[3]))
    keep = np.arange(10) != 3
    assert np.abs(P[keep] - pos[keep]).max() < 1e-12


def test_layouts_are_asymmetric_and_of_the_asked_spread():
    rng = np.random.default_rng(3)
    for k in (3, 4, 5, 6):
        lay = random_layout(rng, k, 0.2)
        d = np.linalg.norm(lay[:, None] - lay[None], axis=-1)[np.triu_indices(k, 1)]
        assert abs(d.max() - 0.2) < 1e-15
        assert np.diff(np.sort(d)).min() >= 0.01 * 0.2
    with pytest.raises(ConfigError):
        random_layout(rng, 2, 0.1)


@pytest.mark.parametrize("n_markers, centroid", [(4, (0.0, 0.0, 0.0)), (3, (0.0, 0.0, -0.3)),
                                                 (6, (0.1, 0.05, 0.2))])
def test_noise_matches_the_small_angle_prediction(n_markers, centroid):
    N, sigma = 40000, 0.3e-3
    rng = np.random.default_rng(10 + n_markers)
    lay = random_layout(rng, n_markers, 0.12, centroid=centroid)
    pos = np.array([0.5, -1.0, 0.8])
    quat = Rotation.from_rotvec([0.3, -0.7, 1.1]).as_quat()
    R0 = rotation_matrices(quat)
    clean = marker_positions(pos, quat, lay)
    w = clean[None] + rng.normal(0.0, sigma, (N, n_markers, 3))
    P, R = fit_poses(w, lay)
    delta = Rotation.from_matrix(R0.T @ R).as_rotvec()           # R = R0 exp([delta]_x), body frame
    cov = rotation_covariance(lay, sigma)
    L = np.linalg.cholesky(cov)
    z = np.linalg.solve(L, delta.T).T
    S = np.cov(z.T)
    tol = 5.0 * np.sqrt((1.0 + np.eye(3)) / N)
    assert np.all(np.abs(S - np.eye(3)) < tol), (S, tol)
    assert np.all(np.abs(z.mean(axis=0)) < 5.0 / np.sqrt(N))
    # the centroid: sigma^2 / k per axis, uncorrelated with the orientation
    c_err = (P + R @ lay.mean(axis=0)) - (pos + R0 @ lay.mean(axis=0))
    zc = c_err / (sigma / np.sqrt(n_markers))
    Sc = np.cov(np.hstack([zc, z]).T)
    assert np.all(np.abs(Sc[:3, :3] - np.eye(3)) < tol)
    assert np.all(np.abs(Sc[:3, 3:]) < 5.0 / np.sqrt(N))
    # the pivot: the centroid's error plus the rotation about the centroid over the lever -d
    d = lay.mean(axis=0)
    lin = c_err - (R0 @ np.cross(delta, d)[..., None])[..., 0]
    if np.linalg.norm(d) > 1e-9:
        first = np.sqrt(np.mean(np.sum((R0 @ np.cross(delta, d)[..., None])[..., 0] ** 2, axis=-1)))
        assert np.sqrt(np.mean(np.sum((P - pos - lin) ** 2, axis=-1))) < 1e-2 * first
    else:
        assert np.abs(P - pos - c_err).max() < 1e-12
    # the scalar summaries
    assert rms_angle_deg(lay, sigma) == pytest.approx(np.degrees(np.sqrt(np.trace(cov))))
    assert rms_angle_deg(lay, sigma_for_angle(lay, 0.5)) == pytest.approx(0.5)


def test_synthesize_series():
    rng = np.random.default_rng(4)
    n = 300
    pos, quat = _poses(rng, 2 * n)
    pos, quat = pos.reshape(2, n, 3), rotations_to_quats(rotation_matrices(quat)).reshape(2, n, 4)
    tracked = np.ones((2, n), bool)
    tracked[1, 100:110] = False
    pos[1, 100:110] = np.nan
    quat[1, 100:110] = np.nan
    clean = MocapSeries(t=np.arange(n) / 120.0, frame=np.arange(n), bodies=["a", "E"], position=pos, quat=quat,
                        tracked=tracked, mean_marker_error=np.zeros((2, n)), meta={"rate_hz": 120.0})
    layouts = {"a": random_layout(rng, 4, 0.1), "E": random_layout(rng, 5, 0.2, centroid=(0.0, 0.0, -0.3))}
    exact = synthesize(clean, layouts, 0.0, rng)
    ok = tracked
    assert np.abs(exact.position[ok] - pos[ok]).max() < 1e-12
    assert np.abs(rotation_matrices(exact.quat[ok]) - rotation_matrices(quat[ok])).max() < 1e-12
    assert np.array_equal(exact.tracked, tracked)
    assert np.all(np.isnan(exact.position[1, 100:110]))
    assert np.nanmax(exact.mean_marker_error) < 1e-12
    noisy = synthesize(clean, layouts, 0.2e-3, np.random.default_rng(5))
    again = synthesize(clean, layouts, 0.2e-3, np.random.default_rng(5))
    assert np.array_equal(noisy.position, again.position, equal_nan=True)
    # mean marker error: about sigma sqrt(3 (k - 6) / k)-ish; just its order of magnitude
    assert 0.05e-3 < np.nanmean(noisy.mean_marker_error) < 0.4e-3
    with pytest.raises(ConfigError):
        synthesize(clean, {"a": layouts["a"]}, 0.1e-3, rng)
