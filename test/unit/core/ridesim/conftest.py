"""Shared fixtures of the ride-simulator tests: small simulated rides and the paper's equations.

The EUC paper's eqs (5)-(8) are written out here by hand (not imported from the simulator or the
estimator) so that the tests check the simulator's sympy-derived truth against an independent
transcription.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.ridesim import MocapNoise, RideConfig, make_effects, simulate_ride

G = 9.81


def paper_residual(p, q, qd, qdd, h, M_d, M_h, g_x=0.0, g_z=-G):
    """Residual ``M q_ddot + h_vec - Q`` of the EUC paper's eqs (5)-(8), (n, 3).

    ``p`` has attributes m, m0, mw, Jw, J0, J, R, l0, h0. The gravity terms of eq. (8) are written for a
    general in-plane gravity vector (g_x, g_z); with (0, -g) they are the paper's
    ``(m0 h0 - m l0) g sin(gamma)`` and ``m g h sin(phi)`` (and 0 in the first row).
    """
    m, m0, mw, Jw, J0, J, R, l0, h0 = (p.m, p.m0, p.mw, p.Jw, p.J0, p.J, p.R, p.l0, p.h0)
    x, ga, ph = q.T
    xd, gd, pd = qd.T
    xdd, gdd, pdd = qdd.T
    # eq. (6)
    m11 = m + m0 + mw + Jw / R**2
    m12 = -(m * l0 - m0 * h0) * np.cos(ga)
    m13 = m * h * np.cos(ph)
    m22 = J0 + m0 * h0**2 + m * l0**2
    m23 = -m * h * l0 * np.cos(ph - ga)
    m33 = J + m * h**2
    # eq. (7)
    h1 = -m * h * pd**2 * np.sin(ph) + (m * l0 - m0 * h0) * gd**2 * np.sin(ga)
    h2 = m * h * l0 * pd**2 * np.sin(ph - ga)
    h3 = -m * h * l0 * gd**2 * np.sin(ph - ga)
    # eq. (8), gravity as sum_k m_k g_vec . dr_k/dq
    gq1 = (m + m0 + mw) * g_x
    gq2 = (m0 * h0 - m * l0) * (g_x * np.cos(ga) - g_z * np.sin(ga))
    gq3 = m * h * (g_x * np.cos(ph) - g_z * np.sin(ph))
    Q1 = M_d / R + gq1
    Q2 = M_h - M_d + gq2
    Q3 = gq3 - M_h
    r1 = m11 * xdd + m12 * gdd + m13 * pdd + h1 - Q1
    r2 = m12 * xdd + m22 * gdd + m23 * pdd + h2 - Q2
    r3 = m13 * xdd + m23 * gdd + m33 * pdd + h3 - Q3
    return np.stack([r1, r2, r3], -1)


def run_residual(ride, run, params=None, **kw):
    """Paper residual along a run with the given parameters (default: the true ones)."""
    p = ride.params_true if params is None else params
    return paper_residual(p, run.q, run.q_dot, run.q_ddot, run.h, run.M_d, run.M_h, **kw)


@pytest.fixture(scope="session")
def ride_decel():
    """Two noise-free deceleration runs without effects."""
    return simulate_ride(RideConfig(maneuver="deceleration", runs=2, seed=11, noise=MocapNoise.none()))


@pytest.fixture(scope="session")
def ride_fig8():
    """A noise-free 8 s figure-eight run without effects."""
    return simulate_ride(RideConfig(maneuver="figure_eight", runs=1, seed=5, duration_s=8.0, noise=MocapNoise.none()))


@pytest.fixture(scope="session")
def ride_noisy():
    """A deceleration run with the default noise, 3 occlusion gaps and 3 % dropped frames."""
    return simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=3,
                                    noise=MocapNoise(gaps=3, drop_rate=0.03)))


@pytest.fixture(scope="session")
def effect_ride():
    """Factory: ``effect_ride(name, **params)`` -> noise-free ride with that effect (cached).

    Each ride has one 3.5 s deceleration run (figure-eight for tilt_gravity) with seed 21, so that the
    runs with and without an effect share their plan.
    """
    cache = {}

    def make(name=None, maneuver=None, runs=1, **params):
        man = maneuver or ("figure_eight" if name == "tilt_gravity" else "deceleration")
        key = (name, man, runs, tuple(sorted(params.items())))
        if key not in cache:
            eff = make_effects([name] if name else [], params)
            cache[key] = simulate_ride(RideConfig(maneuver=man, runs=runs, seed=21, duration_s=3.5, effects=eff,
                                                  noise=MocapNoise.none()))
        return cache[key]

    return make


@pytest.fixture(scope="session")
def paper():
    """The hand-written paper equations: ``paper.residual`` and ``paper.run_residual``."""

    class _Paper:
        residual = staticmethod(paper_residual)
        run_residual = staticmethod(run_residual)
        g = G

    return _Paper()
