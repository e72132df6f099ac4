"""Numerical (complex-step) Jacobians against the analytic matrices (18)/(19), (25), (50), (55), (60)."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.unicycle import dynamics as dyn
from euc_ros.core.unicycle import linearize as lz
from euc_ros.core.unicycle import steady as st

SPEEDS = [0.3, 1.0, 1.2130539971493437, 5.0, 12.0]


@pytest.mark.parametrize("speed", SPEEDS)
def test_straight_rolling_jacobian_equals_eqs_50_55(params, speed):
    A, B = lz.linearize_straight_rolling(params, speed)
    A_paper, B_paper = lz.straight_rolling_matrices(params, speed)
    assert np.allclose(A, A_paper, rtol=1e-12, atol=1e-12)
    assert np.allclose(B, B_paper, rtol=1e-12, atol=1e-14)


def test_errata_entries_of_50_and_55_matter(params):
    """The garbled entries are not cosmetic: the printed values differ from the model's Jacobian."""
    A, B = lz.linearize_straight_rolling(params, 1.0)
    assert A[4, 3] == pytest.approx(-params.g / 5) and abs(A[4, 3] - (-params.R / 5)) > 1.0
    assert B[4] == pytest.approx((5 * params.m + 4 * params.m0) / (5 * params.m * params.m0))
    assert abs(B[4] - (5 * params.m + 4 * params.m0) / (5 * params.m0)) > 1.0


@pytest.mark.parametrize("speed", SPEEDS)
def test_wheel_straight_rolling_jacobian_equals_eq_25(params, speed):
    x = lz.wheel_straight_rolling_state(params, speed)
    assert np.allclose(lz.wheel_jacobian(params, x), lz.wheel_straight_rolling_matrix(params, speed),
                       rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("speed", SPEEDS)
def test_reduction_equals_eq_60_and_is_invariant(params, speed):
    A, B = lz.linearize_straight_rolling(params, speed)
    pitch = speed / params.R
    Ar, Br = lz.reduce_linear_system(A, B, pitch)
    Ar_paper, Br_paper = lz.reduced_matrices(params, speed)
    assert np.allclose(Ar, Ar_paper, rtol=1e-12, atol=1e-12)
    assert np.allclose(Br, Br_paper, rtol=1e-12, atol=1e-14)
    # the reduced state space is invariant under A (so the reduction is exact): A S = S A_r
    S = np.zeros((10, 6))
    for j, name in enumerate(lz.REDUCED_STATES):
        S[dyn.STATE_NAMES.index(name), j] = 1.0
    S[2, 1] = -2 * pitch
    assert np.allclose(A @ S, S @ Ar, atol=1e-12)
    # B lies in it too
    assert np.allclose(B, S @ Br)


def test_complex_step_matches_finite_differences_of_kane(params, kane, random_states):
    """The Jacobian of the closed form against central differences of the independent Kane model."""
    x = random_states(20, seed=21, max_tilt_deg=60)
    u = 5.0
    A, Bv = lz.linearize(params, x, u)
    h = 1e-6
    for j in range(10):
        e = np.zeros((10, 1))
        e[j] = h
        fd = (kane.rhs(x + e, u, params) - kane.rhs(x - e, u, params)) / (2 * h)
        assert np.allclose(A[:, :, j].T, fd, rtol=1e-6, atol=1e-6)
    fdB = (kane.rhs(x, u + 1e-3, params) - kane.rhs(x, u - 1e-3, params)) / 2e-3
    assert np.allclose(Bv.T, fdB, rtol=1e-8, atol=1e-10)


def test_wheel_turning_jacobian_equals_eq_19(params):
    rng = np.random.default_rng(22)
    th = np.radians(rng.uniform(-60, 60, 200))
    pd = rng.uniform(0.2, 8, 200) * rng.choice([-1, 1], 200)
    fd = st.wheel_turning_pitch_rate(th, pd, params)
    J = lz.wheel_jacobian(params, st.wheel_steady_state(th, pd, fd))
    g, R = params.g, params.R
    expected = {
        (0, 1): 6 / 5 * pd * np.cos(th),
        (0, 2): 4 / 5 * pd * np.sin(th) + 6 / 5 * fd,
        (0, 3): -1 / 5 * pd**2 + 4 * g / (5 * R) * np.cos(th),
        (1, 0): -2 / 3 * pd * np.cos(th),
        (2, 0): -pd * np.sin(th) - 2 * fd,
        (4, 2): 1 / np.cos(th),
        (4, 3): pd * np.tan(th),
        (5, 2): -np.tan(th),
        (5, 3): -pd / np.cos(th),
    }
    for (i, j), val in expected.items():
        assert np.allclose(J[:, i, j], val, rtol=1e-10, atol=1e-10), (i, j)
    # every other essential entry is zero (structure of (18))
    mask = np.zeros((8, 8), bool)
    mask[:4, :4] = True
    for (i, j) in expected:
        mask[i, j] = False
    mask[3, 0] = False  # theta_dot = omega1
    assert np.max(np.abs(J[:, mask])) < 1e-12


def test_unicycle_needs_point_mass():
    from euc_ros.core.errors import ConfigError

    with pytest.raises(ConfigError, match="key 'm0'"):
        lz.linearize_straight_rolling(dyn.UnicycleParams(m0=0.0), 1.0)
