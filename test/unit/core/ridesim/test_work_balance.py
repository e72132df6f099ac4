"""Work-energy balance of simulated rides: the energy change is the work of the non-conservative forces.

Along a ride on a level floor with a rider of constant CoG height, the mechanical energy E = T + V of
wheel, EUC body and rider (written out here by hand from the point kinematics) changes only by the work
of the generalized forces that are not in V: the internal torques ``M_d`` (along ``(1/R, -1, 0)``) and
``M_h`` (along ``(0, 1, -1)``), the effects' ``dQ``, the external forces and, with pedals that flex, the
pedals' spring and damper. The test integrates that power over the ride (Gauss-Legendre on every
integrator step's dense output) and compares it with the energy change.

Not covered here, because their forces are not a balance of these terms: ``ground_slope`` and
``tilt_gravity`` (the in-plane gravity changes with the heading or the tilt, so it has no potential in
the planar state), ``time_varying_h`` and arm swing (rheonomic: the rider's own work moves the CoG) and
floors (another geometry). The measurement-only effect ``mocap_time_offset`` does not change the dynamics.

Tolerance. The computed solution is a chain of exact solutions joined by the local errors ``delta_k`` of
its steps. Along each exact piece the balance holds exactly; the jump ``delta_k`` changes E by
``grad E . delta_k`` and leaves the work unchanged. DOP853 keeps ``|delta_k,i| <= sqrt(n) sc_k,i`` with
``sc = atol + rtol |y|`` (RMS norm over n states), and its dense output is as accurate within a step,
which moves the work of step k by at most ``h_k sum_i |dP/dy_i| sqrt(n) sc_k,i``. So
``|dE - W| <= sqrt(n) sum_k sum_i sc_k,i (|dE/dy_i| + h_k max |dP/dy_i|)``, evaluated along the ride.
"""
# covers: euc_ros/core/ridesim/maneuvers.py
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.ridesim import MocapNoise, RideConfig, make_effects
from euc_ros.core.ridesim.external import ExternalForce
from euc_ros.core.ridesim.maneuvers import plan_run
from euc_ros.core.ridesim.rider_motion import PedalFlex
from euc_ros.core.ridesim.simulate import integrate_run, run_dynamics, true_params
from euc_ros.core.ridesim.skeleton import Skeleton
from euc_ros.core.ridesim.truth_model import PlanarParams

#: Gauss-Legendre nodes per integrator step for the work integral (exact for degree 15 polynomials).
NODES = 8


def _config(**kw) -> RideConfig:
    base = {"maneuver": "deceleration", "runs": 1, "seed": 6, "duration_s": 2.0, "settle_s": 0.5,
            "noise": MocapNoise.none()}
    return RideConfig(**{**base, **kw})


CASES = {
    "inputs-only": _config(),
    "inputs-only-reference": _config(method="reference"),
    "figure-eight": _config(maneuver="figure_eight"),
    **{name: _config(effects=make_effects([name]))
       for name in ("rolling_resistance", "viscous_friction", "wheel_body_friction", "aero_drag")},
    "parameter-errors": _config(effects=make_effects(["rider_mass_error", "rider_inertia_error",
                                                      "wheel_radius_error"])),
    "rope": _config(external=(ExternalForce("rope", {"k_n_per_m": 40.0, "anchor_x_m": 2.0, "hand_m": 1.0}),)),
    "headwind": _config(external=(ExternalForce("headwind", {"wind_m_per_s": 4.0, "cda_m2": 0.6}),)),
    "torque_ripple": _config(external=(ExternalForce("torque_ripple", {"amp_nm": 3.0, "per_turn": 16.0}),)),
    "pedals": _config(maneuver="acceleration", pedals=PedalFlex(1.0e5, 0.3)),
}


def energy(p: PlanarParams, h: float, Y: np.ndarray) -> np.ndarray:
    """T + V [J] of wheel, EUC body and rider for states Y (n_states, ...) (u = 0 without pedals).

    ``C = (x, R)``, ``A = C + (l0 + u)(-sin gamma, -cos gamma)``, ``G0 = C + h0 (sin gamma, cos gamma)``,
    ``G = A + h (sin phi, cos phi)``; wheel spin ``x_dot / R``; gravity ``(0, -g)``.
    """
    _, ga, ph, xd, gd, pd = Y[:6]
    u, ud = (Y[10], Y[11]) if Y.shape[0] > 10 else (0.0 * xd, 0.0 * xd)
    lu = p.l0 + u
    vA = (xd - lu * np.cos(ga) * gd - ud * np.sin(ga), lu * np.sin(ga) * gd - ud * np.cos(ga))
    vG0 = (xd + p.h0 * np.cos(ga) * gd, -p.h0 * np.sin(ga) * gd)
    vG = (vA[0] + h * np.cos(ph) * pd, vA[1] - h * np.sin(ph) * pd)
    T = (0.5 * p.mw * xd**2 + 0.5 * p.Jw * (xd / p.R) ** 2 + 0.5 * p.m0 * (vG0[0] ** 2 + vG0[1] ** 2)
         + 0.5 * p.J0 * gd**2 + 0.5 * p.m * (vG[0] ** 2 + vG[1] ** 2) + 0.5 * p.J * pd**2)
    V = p.g * (p.mw * p.R + p.m0 * (p.R + p.h0 * np.cos(ga)) + p.m * (p.R - lu * np.cos(ga) + h * np.cos(ph)))
    return T + V


def power(dyn, t: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Power [W] of the generalized forces outside V: inputs, effects, external forces, pedal spring and damper."""
    s = dyn.sample(t, Y)
    R = dyn.p.R
    Q = np.stack([s["M_d"] / R + s["dQ"][:, 0], s["M_h"] - s["M_d"] + s["dQ"][:, 1], -s["M_h"] + s["dQ"][:, 2]])
    P = np.einsum("in,in->n", Q, Y[3:6])
    if dyn.pedal_k is not None:
        u, ud = Y[10], Y[11]
        P = P + (-dyn.pedal_k * u - dyn.pedal_c * ud) * ud
    return P


def _gradient(f, Y: np.ndarray) -> np.ndarray:
    """|df/dy_i| (n_states, m) by central differences (step 1e-6 (1 + |y_i|))."""
    out = np.empty_like(Y)
    for i in range(Y.shape[0]):
        d = 1e-6 * (1.0 + np.abs(Y[i]))
        Yp, Ym = Y.copy(), Y.copy()
        Yp[i] += d
        Ym[i] -= d
        out[i] = np.abs(f(Yp) - f(Ym)) / (2 * d)
    return out


@pytest.mark.parametrize("case", sorted(CASES))
def test_energy_change_is_the_work_of_the_non_conservative_forces(case):
    config = CASES[case]
    session = config.nominal_session()
    params = true_params(PlanarParams.from_session(session), config.effects)
    plan = plan_run(config.maneuver, 0, np.random.default_rng(config.seed), config.duration_s)
    dyn = run_dynamics(plan, config, params, Skeleton.for_session(session))
    sol = integrate_run(dyn, config, -config.settle_s, config.duration_s)
    assert sol.success
    ts, ys = sol.t, sol.y
    h = np.diff(ts)
    xi, wi = np.polynomial.legendre.leggauss(NODES)
    tq = (ts[:-1, None] + 0.5 * h[:, None] * (1 + xi)).ravel()
    Yq = sol.sol(tq)
    Pq = power(dyn, tq, Yq).reshape(h.size, NODES)
    W = np.sum(0.5 * h * (Pq @ wi))
    dE = energy(params, config.h, ys[:, -1]) - energy(params, config.h, ys[:, 0])

    n = ys.shape[0]
    sc = config.atol + config.rtol * np.maximum(np.abs(ys[:, :-1]), np.abs(ys[:, 1:]))
    gE = _gradient(lambda Y: energy(params, config.h, Y), ys[:, :-1])
    gP = _gradient(lambda Y: power(dyn, tq, Y), Yq).reshape(n, h.size, NODES).max(axis=2)
    bound = np.sqrt(n) * np.sum(sc * (gE + h * gP))

    assert abs(dE - W) <= bound, (case, dE, W, bound)
    # the balance is not trivial: the forces move far more energy than the bound
    flow = np.sum(0.5 * h * (np.abs(Pq) @ wi))
    assert flow > 1e4 * bound, (case, flow, bound)
