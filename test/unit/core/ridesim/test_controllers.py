"""The ride simulator's controllers, checked on hand-computed values and their documented fixed points
(euc_ros.core.ridesim.controllers)."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.ridesim.controllers import EucBalanceController, RiderLeanController


def test_balance_torque_hand_computed_and_vectorized():
    c = EucBalanceController(k_p=1000.0, k_d=50.0, k_v=5.0)
    assert c.torque(0.01, -0.2, 3.0) == pytest.approx(10.0 - 10.0 + 15.0)
    out = c.torque(np.array([0.0, 0.02]), np.array([0.1, 0.0]), np.array([0.0, -1.0]))
    np.testing.assert_allclose(out, [5.0, 20.0 - 5.0])


def test_balance_tilt_back_settles_at_minus_kv_xdot_over_kp():
    c = EucBalanceController()
    x_dot = 4.0
    gamma = -c.k_v * x_dot / c.k_p  # documented steady pitch at constant speed: no torque there
    assert c.torque(gamma, 0.0, x_dot) == pytest.approx(0.0, abs=1e-12)


def test_rider_gains_for_a_rider():
    m, h, g, R, m_eq = 70.0, 0.6, 9.81, 0.2, 25.0
    c = RiderLeanController.for_rider(m, h, g, R, m_eq)
    assert c.mgh == pytest.approx(70 * 9.81 * 0.6)
    assert c.c_ff == pytest.approx((42.0 + 5.0) / 412.02)
    assert (c.k_p, c.k_d, c.k_speed, c.k_int) == (800.0, 150.0, 0.12, 0.05)


def test_desired_lean_is_the_feed_forward_at_the_reference_speed():
    c = RiderLeanController(k_p=800.0, k_d=150.0, k_speed=0.1, k_int=0.05, c_ff=0.1, mgh=400.0)
    a = 1.5
    # on the speed profile, no integrated error, no sway: tan(phi_des) = c_ff a
    assert np.tan(c.desired_lean(3.0, a, 3.0, 0.0, 0.0)) == pytest.approx(0.1 * a)
    # a speed deficit of 1 m/s, 2 m of integrated error and 0.01 rad sway lean further forward
    assert c.desired_lean(3.0, 0.0, 2.0, 2.0, 0.01) == pytest.approx(0.1 + 0.1 + 0.01)


def test_rider_torque_is_gravity_compensation_at_the_desired_lean():
    c = RiderLeanController(k_p=800.0, k_d=150.0, k_speed=0.1, k_int=0.05, c_ff=0.1, mgh=400.0)
    phi = np.array([0.0, 0.1, -0.2])
    np.testing.assert_allclose(c.torque(phi, 0.0, phi), 400.0 * np.sin(phi))
    assert c.torque(0.0, 0.5, 0.1) == pytest.approx(-80.0 + 75.0)
