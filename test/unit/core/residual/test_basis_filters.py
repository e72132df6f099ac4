"""The filters that make the discovery's columns (:mod:`euc_ros.core.residual.basis_filters`), against independent
derivations.

* the first-order low-pass against scipy's zero-order-hold simulation of ``1 / (tau s + 1)`` (a matrix
  exponential), the input held over each step as the filter assumes;
* the resonators against their continuous transfer functions at the bilinear transform's frequency, and the
  payload band's slopes at both ends;
* the Savitzky-Golay smoothing weights against the least-squares fit of a polynomial written out (a QR solve
  of the window's Vandermonde matrix in a normalised time), and on polynomials the fit reproduces.

Tolerances are round-off bounds derived in each test (or the transient left after the skipped samples).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from euc_ros.core.residual.basis_filters import low_pass, payload_band, resonate, savgol_kernel

EPS = float(np.finfo(float).eps)
#: Seeds drawn once from 0-999.
SEEDS = tuple(int(s) for s in np.random.default_rng(8117).choice(1000, 8, replace=False))


@pytest.mark.parametrize("seed", SEEDS)
def test_low_pass_is_the_first_order_lag_of_a_held_input(seed):
    """``1 / (tau s + 1)`` driven by an input held at ``u[n]`` over ``(t[n-1], t[n]]`` and started at rest at
    ``u[0]``: scipy's ``lsim`` with a zero-order hold (its own discretisation, a matrix exponential), the input
    shifted one sample since lsim holds ``u[n]`` over ``[t[n], t[n+1])``. Tolerance: each step of either
    recursion rounds a few times (coefficients, two products, a sum: at most 8 eps of the largest |u|), and a
    stable first-order recursion sums its per-step errors with weights ``a^k``: at most ``1 / (1 - a)`` of one."""
    rng = np.random.default_rng(seed)
    tau = float(np.exp(rng.uniform(np.log(0.05), np.log(5.0))))
    dt = float(np.exp(rng.uniform(np.log(1e-3), np.log(2e-2))))
    n = int(rng.integers(500, 3000))
    u = rng.normal(rng.uniform(-2, 2), 1.0, n)
    y = low_pass(u, tau, dt)
    t = np.arange(n) * dt
    _, want, _ = signal.lsim(([1.0], [tau, 1.0]), np.append(u[1:], u[-1]), t, X0=[u[0] * tau], interp=False)
    a = np.exp(-dt / tau)
    tol = 8 * EPS * float(np.max(np.abs(u))) / (1 - a)
    assert np.max(np.abs(y - want)) <= tol, (tau, dt, np.max(np.abs(y - want)), tol)
    assert y[0] == pytest.approx(u[0], abs=4 * EPS * abs(u[0]))


@pytest.mark.parametrize("seed", SEEDS)
def test_savgol_kernel_is_the_least_squares_fit_at_the_centre(seed):
    """The weights ``w`` give the value at the window's centre of the least-squares polynomial of degree
    ``polyorder``: ``w = V (V^T V)^-1 e_0 = Q R^-T e_0`` (V the window's Vandermonde matrix in the normalised time
    ``j / half``, V = QR), and ``w . p(j) = p(0)`` for a random polynomial p of that degree. Tolerance: the kernel
    is scipy's minimum-norm solve of ``A w = e_0`` with A the Vandermonde matrix in the raw sample index j
    (condition number ``kappa``, up to ~1e10 here), backward stable: ``|dw|_2 <= (polyorder + 1) kappa eps |w|_2``,
    so ``|dw|_1 <= sqrt(window)`` times that in 1-norms; the QR solve is far better conditioned; the dot product
    and the polynomial's samples add ``(window + 4) eps |w|_1`` of the largest |p|."""
    rng = np.random.default_rng(seed)
    polyorder = int(rng.integers(2, 7))
    window = 2 * int(rng.integers(polyorder // 2 + 2, 40)) + 1
    w = savgol_kernel(window, polyorder)
    half = (window - 1) // 2
    j = np.arange(window) - half
    Q, R = np.linalg.qr(np.vander(j / half, polyorder + 1, increasing=True))
    want = Q @ np.linalg.solve(R.T, np.eye(polyorder + 1)[0])
    kappa = float(np.linalg.cond(np.vander(j.astype(float), polyorder + 1, increasing=True)))
    bound = ((polyorder + 1) * np.sqrt(window) * kappa + window + 4) * EPS * float(np.abs(w).sum())
    assert np.abs(w - want).sum() <= bound, (window, polyorder, np.abs(w - want).sum(), bound)
    c = rng.standard_normal(polyorder + 1)
    p = np.polynomial.polynomial.polyval(j / half, c)
    assert abs(w @ p - c[0]) <= bound * float(np.max(np.abs(p)))


@pytest.mark.parametrize("seed", SEEDS)
def test_resonator_follows_its_transfer_function(seed):
    """A sinusoid through :func:`resonate`: after the transient, amplitude and phase of both columns are the
    continuous transfer functions' ``w^2 / (s^2 + 2 zeta w s + w^2)`` and ``w s / (...)`` at the bilinear
    transform's frequency ``tan(pi f dt) / (pi dt)`` (an identity of the transform). Tolerance: the transient
    left after the skipped samples, ``exp(-zeta w t_skip)``, below 1e-9, and round-off."""
    rng = np.random.default_rng(seed)
    dt = 1 / 120
    f_res = float(np.exp(rng.uniform(np.log(0.5), np.log(4.0))))
    f_in = float(np.exp(rng.uniform(np.log(0.3), np.log(8.0))))
    t = np.arange(0.0, 60.0, dt)
    w = 2 * np.pi * f_res
    skip = int(np.ceil(np.log(1e9) / (0.1 * w) / dt))
    Y = resonate(np.sin(2 * np.pi * f_in * t), f_res, dt)[skip:]
    wa = 2 * np.tan(np.pi * f_in * dt) / dt            # the analogue frequency of f_in under the transform
    s_ = 1j * wa
    H = np.array([w * w, w * s_]) / (s_ * s_ + 2 * 0.1 * w * s_ + w * w)
    # steady state: Im(H exp(i 2 pi f_in t)), from the discrete phase of the samples
    ph = 2 * np.pi * f_in * t[skip:]
    expect = (H[None, :] * np.exp(1j * ph)[:, None]).imag
    assert np.max(np.abs(Y - expect)) <= 1e-8 * max(1.0, float(np.max(np.abs(H))))


def test_payload_band_has_neither_a_mass_nor_an_acceleration():
    """Its two columns' gains against a velocity fall as f^2 or faster below the resonance and do not rise above it
    (so neither is an acceleration, gain proportional to f, at either end): sinusoids at 0.1 and 0.2 times, and
    at 5 and 10 times, the resonance, amplitudes read after the transient."""
    dt = 1 / 1000
    f0 = 1.0
    t = np.arange(0.0, 60.0, dt)

    def gain(f):
        y = payload_band(np.sin(2 * np.pi * f * t), f0, dt)[t > 40.0]
        return np.max(np.abs(y), axis=0)

    low1, low2 = gain(0.1), gain(0.2)
    assert np.all(low2 / low1 >= 0.9 * 4)             # ~ f^2 or steeper
    high1, high2 = gain(5.0), gain(10.0)
    assert np.all(high2 / high1 <= 1.05)
