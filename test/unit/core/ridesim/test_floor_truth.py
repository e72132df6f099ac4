"""Floors in a level lab: the simulator's floor dynamics, and the analysis' floor geometry.

Two derivations meet here. The simulator's :func:`~euc_ros.core.ridesim.eom_derivation.derive_floor`
is Lagrange's equations (sympy) of a wheel centre moving along a curve with tangent angle a(s) and
angles measured from gravity's vertical. The residual analysis'
:class:`~euc_ros.core.model.effects.FloorGeometry` is Newton's law projected on the path by
hand, written with the measured signals (horizontal x_ddot, vertical C_zdd). A third, older derivation
(:func:`~euc_ros.core.ridesim.eom_derivation.derive_planar`: a level floor with gravity tilted) must agree
with the first on a constant slope, once the angles are measured from the floor's normal instead of the
vertical.
"""
# covers: euc_ros/core/ridesim/floors.py
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.model.candidate import ModelContext
from euc_ros.core.model.effects import FloorGeometry
from euc_ros.core.model.terms import EucParams
from euc_ros.core.model.torque import torques
from euc_ros.core.ridesim.floors import FloorProfile
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.ridesim.truth_model import FloorModel, PlanarModel, PlanarParams

G = 9.81


@pytest.fixture(scope="module")
def models():
    p = PlanarParams()
    return FloorModel(p), PlanarModel(p)


def test_a_level_floor_is_the_level_model(models):
    fm, pm = models
    rng = np.random.default_rng(1)
    s = rng.normal(size=(50, 5)) * [0.2, 0.3, 2.0, 1.0, 1.0]
    Q = rng.normal(size=(50, 3)) * 20
    a = fm.accelerations(*s.T, 0.6, 0.0, 0.0, 0.0, -G, 0.0, 0.0, Q)
    b = pm.accelerations(*s.T, 0.6, 0.0, 0.0, 0.0, -G, Q)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("slope_deg", [-4.0, 2.5, 8.0])
def test_a_constant_slope_in_a_level_lab_is_gravity_tilted_in_the_floor_frame(models, slope_deg):
    """Rotating the whole scene by the slope: angles from the floor normal are the vertical ones + a,
    gravity in the floor frame is (-g sin a, -g cos a); accelerations must be equal."""
    fm, pm = models
    a = np.radians(slope_deg)
    rng = np.random.default_rng(2)
    gam, phi, xd, gd, pd = (rng.normal(size=40) * k for k in (0.2, 0.3, 2.0, 1.0, 1.0))
    Q = rng.normal(size=(40, 3)) * 20
    lab = fm.accelerations(gam, phi, xd, gd, pd, 0.6, 0.0, 0.0, 0.0, -G, a, 0.0, Q)
    tilted = pm.accelerations(gam + a, phi + a, xd, gd, pd, 0.6, 0.0, 0.0, -G * np.sin(a), -G * np.cos(a), Q)
    np.testing.assert_allclose(lab, tilted, rtol=1e-10, atol=1e-10)


FLOORS = {
    "ramp": FloorProfile.of(("ramp", {"slope_deg": 3.0})),
    "level_then_ramp": FloorProfile.of(("ramp_from", {"slope_deg": 3.0, "x0_m": 0.0, "width_m": 0.5})),
    "bump": FloorProfile.of(("bump", {"height_m": 0.02, "x0_m": 0.0, "width_m": 0.4})),
}


@pytest.mark.parametrize("kind", list(FLOORS))
def test_the_analysis_floor_geometry_closes_the_simulated_truth(kind):
    """With the true states, the floor geometry model gives M_d1 = M_d2 = the true M_d.

    The true states are the simulator's arc-length ones, converted to what a level lab measures:
    horizontal x_dot = s_dot cos a, x_ddot = s_ddot cos a - s_dot^2 sin a da/ds, and the wheel centre's
    vertical acceleration C_zdd = s_ddot sin a + s_dot^2 cos a da/ds. Tolerance: the ODE's 1e-10.
    """
    ride = simulate_ride(RideConfig(maneuver="deceleration", runs=2, seed=4, floor=FLOORS[kind]))
    p = EucParams.from_session(ride.session, 0.61)
    for run in ride.runs:
        a = run.signals["floor_slope"]
        X = run.C[:, 0]
        _, a1 = FLOORS[kind].slope_along(X, run.psi, run.plan.path.kappa(run.q[:, 0]))
        sd, sdd = run.q_dot[:, 0], run.q_ddot[:, 0]
        xd = sd * np.cos(a)
        xdd = sdd * np.cos(a) - sd ** 2 * np.sin(a) * a1
        czz = sdd * np.sin(a) + sd ** 2 * np.cos(a) * a1
        ctx = ModelContext(t=run.t, x_dot=xd, x_ddot=xdd, gamma=run.q[:, 1], gamma_dot=run.q_dot[:, 1],
                           gamma_ddot=run.q_ddot[:, 1], phi=run.q[:, 2], phi_dot=run.q_dot[:, 2],
                           phi_ddot=run.q_ddot[:, 2], psi=run.psi, psi_dot=run.psi_dot, theta=run.theta, params=p,
                           extras={"floor_a": a, "c_zdd": czz})
        geo = FloorGeometry()
        geo.modify(ctx, np.zeros(0))
        ctx.add_force(geo.force(ctx, np.zeros(0)))
        m1, m2 = torques(ctx.gamma, ctx.phi, ctx.gamma_dot, ctx.phi_dot, ctx.x_ddot, ctx.gamma_ddot, ctx.phi_ddot,
                         ctx.p(), extra_Q=ctx.extra_Q)
        scale = np.max(np.abs(run.M_d))
        np.testing.assert_allclose(m1, run.M_d, atol=1e-6 * scale)
        np.testing.assert_allclose(m2, run.M_d, atol=1e-6 * scale)
        # and the level model does not: the floor is visible in M_d1 - M_d2
        b1, b2 = torques(ctx.gamma, ctx.phi, ctx.gamma_dot, ctx.phi_dot, xdd, ctx.gamma_ddot, ctx.phi_ddot, p)
        assert np.sqrt(np.mean((b1 - b2) ** 2)) > 1e3 * np.sqrt(np.mean((m1 - m2) ** 2))


def test_the_ramp_ride_climbs_its_floor():
    ride = simulate_ride(RideConfig(maneuver="deceleration", runs=2, seed=5, floor=FLOORS["ramp"]))
    for run in ride.runs:
        dz, dx = np.diff(run.C[:, 2]), np.diff(run.C[:, 0])
        np.testing.assert_allclose(np.median(dz / dx), np.tan(np.radians(3.0)), rtol=1e-3)
    assert ride.truth_dict()["floor"]["components"][0]["kind"] == "ramp"
