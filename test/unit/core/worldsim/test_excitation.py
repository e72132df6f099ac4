"""Band-limited disturbances and speed profiles of the generator."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.worldsim.excitation import PROFILE_KINDS, SKIRT_FACTOR, band_noise, random_band, random_speed_profile


def test_band_noise_rms_band_and_derivative():
    rng = np.random.default_rng(0)
    period = 40.0
    d = band_noise(rng, period, 0.3, 2.0, rms=5.0)
    t = np.arange(0.0, period, 0.005)
    x = d(t)
    # one full period on a grid far finer than the highest frequency: the sample rms is the rms
    assert np.sqrt(np.mean(x**2)) == pytest.approx(5.0, rel=1e-9)
    assert d.freqs.max() <= SKIRT_FACTOR * 2.0 and d.freqs.min() >= 1.0 / period
    # derivative against central differences (truncation (2 pi f_max)^3 h^2 / 6 times the amplitude sum)
    h = 1e-4
    fd = (d(t + h) - d(t - h)) / (2 * h)
    amp = np.sum(np.hypot(d.a, d.b))
    assert np.max(np.abs(fd - d(t, deriv=1))) <= (2 * np.pi * d.freqs.max()) ** 3 * h**2 / 6 * amp + 1e-9 * amp / h


def test_random_band_is_within_limits():
    rng = np.random.default_rng(1)
    for _ in range(200):
        lo, hi = random_band(rng, (0.1, 3.0))
        assert 0.1 <= lo < hi <= 3.0 and hi / lo >= 3.0 - 1e-12


@pytest.mark.parametrize("kind", PROFILE_KINDS)
def test_speed_profile_is_smooth_and_its_acceleration_is_its_derivative(kind):
    prof = random_speed_profile(np.random.default_rng(2), 30.0, kind=kind, v_max=4.0)
    assert prof.t1[-1] >= 30.0 and np.allclose(prof.t0[1:], prof.t1[:-1])
    t = np.linspace(-1.0, 31.0, 64001)
    v, a = prof.speed(t), prof.acceleration(t)
    assert v.min() >= -1e-12 and v.max() <= 4.0 + 1e-12
    h = t[1] - t[0]
    dv, dur = np.abs(prof.v1 - prof.v0), prof.t1 - prof.t0
    # central difference: error <= max|v'''| h^2 / 6 + rounding, with |v'''| <= (2 pi)^2 |dv| / D^3
    third = np.max((2 * np.pi) ** 2 * dv / dur**3)
    assert np.max(np.abs(np.gradient(v, h)[1:-1] - a[1:-1])) <= third * h**2 / 6 + 4 * np.finfo(float).eps * 4 / h
    # continuous acceleration: steps of at most max|jerk| h, |jerk| <= 2 pi |dv| / D^2
    assert np.max(np.abs(np.diff(a))) <= np.max(2 * np.pi * dv / dur**2) * h * (1 + 1e-9)
