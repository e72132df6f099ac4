"""Pedals that flex and arms that swing (:mod:`euc_ros.core.ridesim.rider_motion`): the truth checked
against derivations written here by hand.

* pedals: the 4-DoF Lagrange equations (sympy, :func:`~euc_ros.core.ridesim.eom_derivation.derive_pedal`)
  reduce to the rigid model at u = u_dot = 0; without inputs and damping they conserve the energy
  T + V + k u^2 / 2 written here from the point velocities; in a simulated ride the pedal force equals
  the rider's load along the EUC's axis, m (a_G + g e_z) . e_ax, with a_G from the recorded CoG track;
* arms: the segment poses put the weighted CoG on the truth's G; the angular momentum of the rider
  about G computed from the recorded segment CoMs equals the truth's ``(J_pm + dJ) phi_dot + H``.
"""
# covers: euc_ros/core/ridesim/skeleton.py
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError
from euc_ros.core.ridesim import MocapNoise, RideConfig, simulate_ride
from euc_ros.core.ridesim.rider_motion import ArmKinematics, ArmSwing, PedalFlex
from euc_ros.core.ridesim.skeleton import Skeleton
from euc_ros.core.ridesim.truth_model import PedalModel, PlanarModel, PlanarParams

G = 9.81


def test_pedal_model_at_zero_flex_is_the_rigid_model():
    p = PlanarParams()
    pm, rm = PedalModel(p), PlanarModel(p)
    rng = np.random.default_rng(3)
    gam, phi, xd, gd, pd = (rng.normal(size=30) * k for k in (0.2, 0.3, 2.0, 1.0, 1.0))
    M4 = pm.mass_matrix(gam, phi, 0.0, 0.6)
    b4 = pm.bias(gam, phi, 0.0, xd, gd, pd, 0.0, 0.6, 0.1, 0.3, 0.0, -G)
    np.testing.assert_allclose(M4[:, :3, :3], rm.mass_matrix(gam, phi, 0.6), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(b4[:, :3], rm.bias(gam, phi, xd, gd, pd, 0.6, 0.1, 0.3, 0.0, -G), rtol=1e-12,
                               atol=1e-12)
    # u moves the rider only: M_uu = m
    np.testing.assert_allclose(M4[:, 3, 3], p.m, rtol=1e-12)


def _energy(p: PlanarParams, k: float, h: float, y: np.ndarray) -> np.ndarray:
    """T + V from the point velocities, written by hand (y = x, gamma, phi, u and their rates)."""
    x, ga, ph, u, xd, gd, pd, ud = y
    l = p.l0 + u
    vG0 = (xd + p.h0 * np.cos(ga) * gd, -p.h0 * np.sin(ga) * gd)
    vA = (xd - ud * np.sin(ga) - l * np.cos(ga) * gd, -ud * np.cos(ga) + l * np.sin(ga) * gd)
    vG = (vA[0] + h * np.cos(ph) * pd, vA[1] - h * np.sin(ph) * pd)
    T = (0.5 * p.mw * xd ** 2 + 0.5 * p.Jw * (xd / p.R) ** 2 + 0.5 * p.m0 * (vG0[0] ** 2 + vG0[1] ** 2)
         + 0.5 * p.J0 * gd ** 2 + 0.5 * p.m * (vG[0] ** 2 + vG[1] ** 2) + 0.5 * p.J * pd ** 2)
    z_G0 = p.R + p.h0 * np.cos(ga)
    z_G = p.R - l * np.cos(ga) + h * np.cos(ph)
    return T + p.g * (p.mw * p.R + p.m0 * z_G0 + p.m * z_G) + 0.5 * k * u ** 2


def test_pedal_model_conserves_energy_without_inputs_and_damping():
    p, k, h = PlanarParams(), 1.0e5, 0.61
    pm = PedalModel(p)

    def rhs(_t, y):
        a = pm.accel_scalar(y[1], y[2], y[3], *y[4:8], h, 0.0, 0.0, 0.0, -p.g, (0.0, 0.0, 0.0, -k * y[3]))
        return [*y[4:8], *a]

    y0 = [0.0, 0.03, 0.08, 0.004, 1.5, 0.2, -0.1, 0.05]
    sol = solve_ivp(rhs, (0, 0.6), y0, method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    E = _energy(p, k, h, sol.sol(np.linspace(0, 0.6, 200)))
    # the bouncing mode exchanges m g (u amplitude) ~ 3 J with the spring; drift must be at the integrator's tolerance
    scale = p.m * p.g * h
    assert np.ptp(E) < 1e-8 * scale, np.ptp(E)
    assert np.ptp(sol.y[3]) > 1e-3          # the pedals did bounce


def _noiseless_acceleration(**rider_motion):
    """A 3 s acceleration run without mocap noise, the rider moving as ``rider_motion`` says."""
    return simulate_ride(RideConfig(maneuver="acceleration", runs=1, seed=11, duration_s=3.0,
                                    noise=MocapNoise.none(), **rider_motion))


@pytest.fixture(scope="module")
def pedal_ride():
    return _noiseless_acceleration(pedals=PedalFlex(1.0e5, 0.3))


def test_pedal_force_is_the_riders_load_along_the_axis(pedal_ride):
    run = pedal_ride.runs[0]
    m = pedal_ride.params_true.m
    p = pedal_ride.params_true
    dt = float(np.mean(np.diff(run.t)))
    x, ga, ph = run.q.T
    u = run.signals["pedal_u"]
    # the rider's CoG in the plane of the truth model, by hand: G = C + (l0 + u)(-sin ga, -cos ga) + h (sin ph, cos ph)
    Gp = np.stack([x - (p.l0 + u) * np.sin(ga) + run.h * np.sin(ph), p.R - (p.l0 + u) * np.cos(ga) + run.h * np.cos(ph)], 1)  # noqa: E501
    aG = np.gradient(np.gradient(Gp, dt, axis=0), dt, axis=0)
    e_ax = np.stack([np.sin(ga), np.cos(ga)], 1)
    load = m * np.einsum("ni,ni->n", aG + [0.0, G], e_ax)
    inner = slice(4, -4)
    # truncation of the second central difference: dt^2/12 |G''''|, G'''' from the same track
    d4 = np.gradient(np.gradient(aG, dt, axis=0), dt, axis=0)
    tol = m * dt ** 2 / 12 * np.max(np.linalg.norm(d4[inner], axis=1)) * 3 + 1e-6 * m * G
    err = np.abs(run.signals["pedal_force"] - load)[inner]
    assert err.max() < tol, (err.max(), tol)
    # quasi-static deflection m g / k to the load's few per cent
    np.testing.assert_allclose(np.mean(run.signals["pedal_u"]), m * G / 1.0e5, rtol=0.03)


def test_pedals_refuse_forces_at_the_rider_cog():
    with pytest.raises(ConfigError, match="pedals"):
        simulate_ride(RideConfig(maneuver="acceleration", runs=1, duration_s=1.0, pedals=PedalFlex(),
                                 arms=ArmSwing()))


@pytest.fixture(scope="module")
def arm_ride():
    return _noiseless_acceleration(arms=ArmSwing(15.0, 1.2))


def test_swinging_arms_keep_the_reconstructed_cog_on_the_truth(arm_ride):
    run = arm_ride.runs[0]
    sk = Skeleton.for_session(arm_ride.session)
    pos = run.mocap_clean.position[:-1]
    rot = Rotation.from_quat(run.mocap_clean.quat[:-1].reshape(-1, 4)).as_matrix().reshape(pos.shape[0], -1, 3, 3)
    np.testing.assert_allclose(sk.cog(pos, rot), run.G, atol=1e-9)
    # the arms do move: the hands' CoM (lower arms) swings by centimetres relative to the trunk
    i, j = arm_ride.session.segment_arrays()[0].index("LAR"), arm_ride.session.segment_arrays()[0].index("CHR")
    rel = np.einsum("nji,nj->ni", rot[j], pos[i] - pos[j])
    assert np.ptp(rel[:, 0]) > 0.04


def test_swinging_arms_angular_momentum_from_the_recorded_segments(arm_ride):
    """H about G from the recorded segment CoMs (point masses f_i m) against the truth's terms."""
    run = arm_ride.runs[0]
    sess = arm_ride.session
    names, fr, off = sess.segment_arrays()
    m = arm_ride.params_true.m
    pos = run.mocap_clean.position[:-1]
    rot = Rotation.from_quat(run.mocap_clean.quat[:-1].reshape(-1, 4)).as_matrix().reshape(pos.shape[0], -1, 3, 3)
    com = pos + np.einsum("bnij,bj->bni", rot, off)
    # into the EUC's moving frame Rz(psi) Rx(theta): the pitch plane is its x-z plane
    RM = Rotation.from_euler("ZX", np.stack([run.psi, run.theta], 1)).as_matrix()
    r = np.einsum("nji,bnj->bni", RM, com - run.G[None])
    dt = float(np.mean(np.diff(run.t)))
    v = np.gradient(r, dt, axis=1)
    H_meas = m * np.einsum("b,bn->n", fr, r[..., 2] * v[..., 0] - r[..., 0] * v[..., 2])
    kin = ArmKinematics(ArmSwing(15.0, 1.2), Skeleton.for_session(sess), 0.61, m, run_index=0)
    prof = kin.profile(run.t)
    H_truth = (kin.J0 + prof["dJ"]) * run.q_dot[:, 2] + prof["H"]
    inner = slice(3, -3)
    # truncation of the central difference of the CoM track: |v error| <= dt^2/6 |d3r/dt3|, so
    # |H error| <= m sum f_i |r_i| dt^2/6 |d3r_i/dt3| (the third derivative from the same track)
    r3 = np.gradient(np.gradient(v, dt, axis=1), dt, axis=1)
    bound = m * np.einsum("b,bn->n", fr, np.linalg.norm(r, axis=2) * dt ** 2 / 6 * np.linalg.norm(r3, axis=2))
    err = np.abs(H_meas - H_truth)[inner]
    assert np.all(err < 2 * bound[inner] + 1e-6), (err.max(), bound.max())
    assert np.max(np.abs(prof["H"])) > 20 * err.max()        # the relative motion is really seen
    # H_dot is the time derivative of H (the spline's P and K agree)
    np.testing.assert_allclose(np.gradient(prof["H"], dt)[inner], prof["H_dot"][inner],
                               atol=0.01 * np.max(np.abs(prof["H_dot"])))
    exact = kin.profile(run.t[::25], exact=True)
    for key in ("h", "dJ", "H_dot"):
        np.testing.assert_allclose(prof[key][::25], exact[key], atol=1e-7 * max(1.0, np.max(np.abs(exact[key]))))
