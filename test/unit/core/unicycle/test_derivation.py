"""Closed-form eqs (6) and (36) against independent derivations (Kane, Lagrange) and the power balance."""
# covers: euc_ros/core/unicycle/dynamics.py
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.unicycle import dynamics as dyn
from euc_ros.core.unicycle.derivation import derive_lagrange

N_STATES = 300
WHEEL_ROWS = [0, 1, 2, 3, 6, 7, 8, 9]   # unicycle state indices that make up the wheel state (7)


def _rel_err(a, b):
    return np.max(np.abs(a - b) / (1.0 + np.abs(b)))


def test_unicycle_closed_form_equals_kane(params, kane, random_states):
    x = random_states(N_STATES, seed=1)
    u = np.random.default_rng(2).uniform(-200, 200, N_STATES)
    assert _rel_err(dyn.unicycle_rhs(x, u, params), kane.rhs(x, u, params)) < 1e-11


@pytest.mark.parametrize("m, m0, R, g", [(10.0, 5.0, 0.3, 9.81), (2.0, 30.0, 0.5, 3.7), (80.0, 0.5, 0.2, 9.81)])
def test_control_affine_split_equals_kane(kane, m, m0, R, g, random_states):
    p = dyn.UnicycleParams(m=m, m0=m0, R=R, g=g)
    x = random_states(N_STATES, seed=3)
    assert _rel_err(dyn.drift(x, p), kane.f(x, p)) < 1e-11
    assert _rel_err(dyn.input_field(x, p), kane.g(x, p)) < 1e-11
    u = 7.5
    assert np.allclose(dyn.drift(x, p) + dyn.input_field(x, p) * u, dyn.unicycle_rhs(x, u, p), rtol=1e-13, atol=1e-12)


def test_wheel_closed_form_equals_kane(params, kane_wheel, random_states):
    xw = random_states(N_STATES, seed=4)[WHEEL_ROWS]
    assert _rel_err(dyn.wheel_rhs(xw, params), kane_wheel.rhs(xw, 0.0, params)) < 1e-11


def test_unicycle_without_point_mass_is_the_wheel(params, random_states):
    """Paper, below eq (37): with m0 = 0 and u = 0 the essential dynamics of (36) become those of (6)."""
    x = random_states(N_STATES, seed=5)
    x[4] = 0.0
    p0 = dyn.UnicycleParams(m=params.m, m0=np.float64(0.0), R=params.R, g=params.g)  # numpy: m/m0 -> inf, not an error
    with np.errstate(divide="ignore", invalid="ignore"):
        uni = dyn.unicycle_rhs(x, 0.0, p0)
    wheel = dyn.wheel_rhs(x[WHEEL_ROWS], p0)
    rows = [0, 1, 2, 3, 6, 7, 8, 9]
    assert _rel_err(uni[rows], wheel) < 1e-12


def test_kane_equals_lagrange_unicycle(params, kane, random_states):
    """Second, independent route: Lagrange's equations with multipliers in the full coordinates."""
    lag = derive_lagrange(True)
    x = random_states(120, seed=6)
    u = np.random.default_rng(7).uniform(-200, 200, 120)
    assert _rel_err(lag.rhs(x, u, params), kane.rhs(x, u, params)) < 1e-9


def test_kane_equals_lagrange_wheel(params, kane_wheel, random_states):
    lag = derive_lagrange(False)
    xw = random_states(120, seed=8)[WHEEL_ROWS]
    assert _rel_err(lag.rhs(xw, 0.0, params), kane_wheel.rhs(xw, 0.0, params)) < 1e-9


def _energy_rate(energy_fn, rhs, x, h=1e-30):
    """dE/dt = grad E . x_dot by complex-step differentiation along x_dot (exact to rounding)."""
    return np.imag(energy_fn(x + 1j * h * rhs)) / h


def test_power_balance_of_closed_form(params, random_states):
    """Third check, no derivation at all: the internal force pair does power u sigma, nothing else works."""
    x = random_states(N_STATES, seed=9)
    u = np.random.default_rng(10).uniform(-200, 200, N_STATES)
    rhs = dyn.unicycle_rhs(x, u, params)
    dE = _energy_rate(lambda z: dyn.energy(z, params), rhs, x)
    scale = 1.0 + np.abs(u * x[4])
    assert np.max(np.abs(dE - u * x[4]) / scale) < 1e-10
    # and it is not trivially satisfied: a wrong coefficient breaks it
    bad = rhs.copy()
    bad[4] *= 1.001
    assert np.max(np.abs(_energy_rate(lambda z: dyn.energy(z, params), bad, x) - u * x[4]) / scale) > 1e-4


def test_wheel_conserves_energy(params, random_states):
    xw = random_states(N_STATES, seed=11)[WHEEL_ROWS]
    dE = _energy_rate(lambda z: dyn.wheel_energy(z, params), dyn.wheel_rhs(xw, params), xw)
    assert np.max(np.abs(dE)) / np.max(dyn.wheel_energy(xw, params)) < 1e-12


def test_printed_sigma_line_is_wrong_and_errata_fixes_it(params, kane, random_states):
    """ERRATA: eq (36)'s sigma_dot as printed (prefactor m0, omega2^2, -8 omega1 sigma R^2 r) disagrees."""
    m, m0, R, g = params.m, params.m0, params.R, params.g
    x = random_states(50, seed=12)
    w1, w2, w3, th, sg, r = x[:6]
    u = 3.0
    t = np.tan(th)
    printed = m0 / (5 * m * R**2 + 4 * m0 * r**2) * (
        w1**2 * (5 * m * R**2 + 4 * m0 * (R**2 + r**2)) * r
        + w2**2 * (5 * m * R**2 * r - 4 * m0 * R * r**2 * t + 4 * m0 * r**3 - m * R**3 * t)
        - 8 * w1 * sg * R**2 * r + w2 * w3 * R * (m * R**2 + 4 * m0 * (R * r * t - r**2))
        - (m * R**2 + 4 * m0 * r**2) * g * np.sin(th) - 4 * m0 * g * R * r * np.cos(th)
        + (5 * m / m0 * R**2 + 4 * R**2 + 4 * r**2) * u)
    derived = kane.rhs(x, u, params)[4]
    assert np.median(np.abs(printed - derived) / (1 + np.abs(derived))) > 0.1
    assert _rel_err(dyn.unicycle_rhs(x, u, params)[4], derived) < 1e-11


def test_updfcn_contract(params, random_states):
    x = random_states(1, seed=13)[:, 0]
    out = dyn.updfcn(0.0, x, np.array([4.0]), params)
    assert out.shape == (10,)
    assert np.array_equal(out, dyn.unicycle_rhs(x, 4.0, params))
    with pytest.raises(ValueError):
        dyn.updfcn(0.0, x, np.array([1.0, 2.0]), params)


@pytest.mark.parametrize("key, kwargs", [("m", {"m": 0.0}), ("R", {"R": -1.0}), ("g", {"g": float("nan")}),
                                         ("m0", {"m0": -1.0})])
def test_params_are_validated(key, kwargs):
    from euc_ros.core.errors import ConfigError

    with pytest.raises(ConfigError, match=f"key '{key}'"):
        dyn.UnicycleParams(**kwargs)
