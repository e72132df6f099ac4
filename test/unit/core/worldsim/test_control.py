"""The independent generator's controllers (euc_ros.core.worldsim.control), checked against what their design
promises: the EUC loop's pitch mode where it was placed, the linearization against the nonlinear plant, a
stable closed loop, the steady lean solving its own equations, and the tilt-back's limits."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.worldsim import control as K
from euc_ros.core.worldsim.dynamics import solve
from euc_ros.core.worldsim.simulate import draw_spec

SEEDS = (3, 11, 42)


@pytest.fixture(scope="module", params=SEEDS)
def spec(request):
    return draw_spec(request.param)


def test_the_jacobians_predict_the_plant_to_second_order(spec):
    """A small pitch and torque step changes the accelerations as the Jacobians say, with an error that falls
    four times when the step halves (second order)."""
    p = spec.plant
    jac = K.plant_jacobians(p)
    z = np.zeros(3)
    errors = []
    for eps in (1e-3, 5e-4):
        dq = np.array([0.0, 0.7, -0.4]) * eps
        dm = np.array([3.0, -2.0]) * eps
        got = solve(dq, z, dm[0], dm[1], p)[:3] - solve(z, z, 0.0, 0.0, p)[:3]
        want = jac["angles"] @ dq[1:] + jac["torques"] @ dm
        errors.append(np.max(np.abs(got - want)))
    assert errors[1] < 0.3 * errors[0] or errors[0] < 1e-12
    assert jac["torques"][1, 0] < 0            # the motor's reaction tips the body back


def test_the_euc_loop_places_its_pitch_mode_where_it_was_asked(spec):
    """With the rider frozen, gamma_ddot = a gamma + b M_d; the PD gains put the mode's natural frequency and
    damping at the requested values (eigenvalues of the 2x2 loop, not the design formula)."""
    p = spec.plant
    jac = K.plant_jacobians(p)
    a, b = jac["angles"][1, 0], jac["torques"][1, 0]
    for hz, zeta in ((8.0, 0.5), (12.0, 0.9)):
        loop = K.design_euc_loop(p, hz, zeta, 0.002)
        lam = np.linalg.eigvals(np.array([[0.0, 1.0], [a + b * loop.k_p, b * loop.k_d]]))
        assert np.abs(lam) == pytest.approx([2 * np.pi * hz] * 2, rel=1e-9)
        assert -lam.real / np.abs(lam) == pytest.approx([zeta] * 2, rel=1e-9)


def test_both_loops_closed_are_stable_and_the_pitch_mode_is_near_the_euc_design(spec):
    lam = np.linalg.eigvals(K.closed_loop_matrix(spec.plant, spec.euc, spec.rider_loop))
    assert np.all(lam.real < 0), lam
    f = K.pitch_mode_hz(spec.plant, spec.euc, spec.rider_loop)
    assert 0.5 * spec.euc.natural_hz < f < 2.0 * spec.euc.natural_hz


def test_the_steady_lean_solves_the_steady_equations(spec):
    """At constant acceleration with constant angles the accelerations are (a, 0, 0) and M_d = k_p gamma."""
    p, euc = spec.plant, spec.euc
    s = K.steady_acceleration(p, euc)
    jac = K.plant_jacobians(p)
    acc = jac["angles"] @ s[:2] + jac["torques"] @ np.array([s[5], s[6]])
    np.testing.assert_allclose(acc, [1.0, 0.0, 0.0], atol=1e-9)
    assert s[5] == pytest.approx(euc.k_p * s[0])
    # the rider's law at its own reference state commands exactly the steady ankle torque
    z = 0.8 * s + 2.0 * np.eye(7)[2]
    assert float(spec.rider_loop.command(z, 2.0, 0.8)) == pytest.approx(0.8 * spec.rider_loop.steady[6], abs=1e-9)


def test_the_tilt_back_is_zero_below_the_limit_and_has_its_slope_above():
    loop = K.EucLoop(k_p=100.0, k_d=5.0, tau=0.002, v_limit=5.0, tilt_back=0.05)
    v = np.array([0.0, 3.0, 4.0, 7.0, 9.0])
    ref = loop.pitch_reference(v)
    assert abs(ref[0]) < 1e-12 and abs(ref[1]) < 1e-9
    assert (ref[4] - ref[3]) / 2.0 == pytest.approx(-0.05, rel=1e-6)
    assert [loop.pitch_reference_one(float(x)) for x in v] == pytest.approx(ref.tolist(), rel=1e-12, abs=1e-15)
    assert np.all(K.EucLoop(k_p=1.0, k_d=1.0, tau=0.01).pitch_reference(v) == 0.0)
