"""Generated trajectories: the truth equations hold, the magnitudes are the paper's, runs are deterministic."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline, make_interp_spline

from euc_ros.core.errors import ConfigError
from euc_ros.core.ridesim import MANEUVERS, MocapNoise, RideConfig, make_effects, simulate_ride


def _all_runs(*rides):
    return [(ride, run) for ride in rides for run in ride.runs]


def test_paper_equations_hold_along_generated_trajectories(ride_decel, ride_fig8, paper):
    for ride, run in _all_runs(ride_decel, ride_fig8):
        res = paper.run_residual(ride, run)
        scale = max(np.abs(run.M_d).max(), 1.0)
        assert np.abs(res).max() < 1e-9 * scale, run.name


def _interval_integrals(t, f):
    """Integrals of f between consecutive samples, through a quintic spline: its quadrature error
    (~h^6 f^(6)) is below 1e-11 at 120 Hz here, where a cubic spline's (~h^4) reaches 7e-10."""
    F = make_interp_spline(t, f, k=5).antiderivative()
    return np.diff(F(t))


def test_sampled_derivatives_are_consistent_at_integration_tolerance(ride_decel):
    """q_dot integrates to q and q_ddot to q_dot between samples (the ODE was solved, not faked).

    DOP853 keeps each step's error estimate below ``atol + rtol |y|``; between two samples of its dense
    output the q_dot error is measured at up to 10 times that (rides at tolerances 1e-9 to 1e-12), so
    q_ddot's bound is 100 times it. Derivatives by finite differences of the samples miss it by orders
    of magnitude.
    """
    run, cfg = ride_decel.runs[0], ride_decel.config
    t = run.t
    for i in range(3):
        dq = np.diff(run.q[:, i])
        dqd = np.diff(run.q_dot[:, i])
        bound_qd = 100 * (cfg.atol + cfg.rtol * np.abs(run.q_dot[:, i]).max())
        assert np.abs(_interval_integrals(t, run.q_dot[:, i]) - dq).max() < 1e-9
        assert np.abs(_interval_integrals(t, run.q_ddot[:, i]) - dqd).max() < bound_qd
        faked = np.gradient(run.q_dot[:, i], t)
        assert np.abs(_interval_integrals(t, faked) - dqd).max() > 100 * bound_qd
        assert np.abs(dqd).max() > 1e-4  # something happens


def test_speed_is_the_longitudinal_velocity_of_c_in_the_moving_frame(ride_fig8):
    """x_dot is the x component of dC/dt in Rz(psi) Rx(theta) (EUC paper, Section 2), also in turns."""
    run = ride_fig8.runs[0]
    t, C = run.t, run.C
    vC = CubicSpline(t, C).derivative()(t)
    fwd = np.column_stack([np.cos(run.psi), np.sin(run.psi), np.zeros_like(run.psi)])  # Rz Rx e_x
    v_long = np.einsum("ni,ni->n", vC, fwd)
    inner = slice(5, -5)
    np.testing.assert_allclose(v_long[inner], run.q_dot[inner, 0], atol=2e-5)
    assert np.abs(run.psi_dot).max() > 0.5


@pytest.fixture(scope="module")
def rides_all_maneuvers():
    return {m: simulate_ride(RideConfig(maneuver=m, runs=3 if m == "deceleration" else 2, seed=2,
                                        duration_s=10.0 if m == "figure_eight" else None,
                                        noise=MocapNoise.none())) for m in MANEUVERS}


def test_magnitudes_are_those_of_the_papers_figures(rides_all_maneuvers):
    for m, ride in rides_all_maneuvers.items():
        for run in ride.runs:
            phi, gam = np.degrees(run.q[:, 2]), np.degrees(run.q[:, 1])
            assert np.abs(phi).max() < 11.0, (m, run.name)
            assert np.abs(gam).max() < 3.0, (m, run.name)
            assert run.q_dot[:, 0].min() > 0.0 and run.q_dot[:, 0].max() < 4.0, (m, run.name)
            assert np.abs(run.M_d).max() < 60.0, (m, run.name)
    dec = rides_all_maneuvers["deceleration"].runs[0]
    assert dec.q_dot[0, 0] > 3.2 and dec.q_dot[-1, 0] < 1.4
    assert np.degrees(dec.q[:, 2].min()) < -6.0  # leans back to brake (Fig. 6d)
    acc = rides_all_maneuvers["acceleration"].runs[0]
    assert acc.q_dot[0, 0] < 1.4 and acc.q_dot[-1, 0] > 3.2
    assert np.degrees(acc.q[:, 2].max()) > 6.0
    fig = rides_all_maneuvers["figure_eight"].runs[0]
    assert np.degrees(np.abs(fig.theta).max()) > 10.0 and np.ptp(np.unwrap(fig.psi)) > np.pi
    assert np.abs(fig.C[:, :2]).max() < 4.0  # fits a lab


def test_straight_runs_alternate_direction(rides_all_maneuvers):
    psi0 = [r.plan.path.psi0 for r in rides_all_maneuvers["deceleration"].runs]
    assert psi0 == [0.0, np.pi, 0.0]
    run2 = rides_all_maneuvers["deceleration"].runs[1]
    assert np.all(np.diff(run2.C[:, 0]) < 0)  # heading pi: C moves towards -x


def test_same_seed_same_ride_and_run_k_independent_of_run_count():
    a = simulate_ride(RideConfig(maneuver="constant_speed", runs=2, seed=9, duration_s=1.0))
    b = simulate_ride(RideConfig(maneuver="constant_speed", runs=2, seed=9, duration_s=1.0))
    c = simulate_ride(RideConfig(maneuver="constant_speed", runs=1, seed=9, duration_s=1.0))
    d = simulate_ride(RideConfig(maneuver="constant_speed", runs=1, seed=10, duration_s=1.0))
    for ra, rb in zip(a.runs, b.runs):
        np.testing.assert_array_equal(ra.q, rb.q)
        np.testing.assert_array_equal(ra.mocap.position, rb.mocap.position)
        np.testing.assert_array_equal(ra.mocap.quat, rb.mocap.quat)
    np.testing.assert_array_equal(a.runs[0].mocap.position, c.runs[0].mocap.position)
    assert not np.allclose(a.runs[0].q_dot, d.runs[0].q_dot)


def test_bad_configuration_names_the_key():
    with pytest.raises(ConfigError, match="maneuver"):
        simulate_ride(RideConfig(maneuver="wheelie"))
    with pytest.raises(ConfigError, match="runs"):
        simulate_ride(RideConfig(runs=0))
    with pytest.raises(ConfigError, match="'effect'"):
        make_effects(["warp_drive"])
    with pytest.raises(ConfigError, match="alpha_deg"):
        make_effects(["rolling_resistance"], {"alpha_deg": 2.0})
    with pytest.raises(ConfigError, match="c_rr"):
        make_effects(["rolling_resistance"], {"c_rr": -1.0})
