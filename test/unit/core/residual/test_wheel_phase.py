"""The wheel phases of the aligned wheel-rotation family (:mod:`euc_ros.core.residual.wheel_phase`), against the
shifted Fourier series written out term by term and against offsets a simulated tyre was given."""
from __future__ import annotations

import numpy as np

from euc_ros.core.residual.wheel_phase import align_wheel_phases, phase_rotations, wheel_phase_mix


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
