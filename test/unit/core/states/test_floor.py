"""The floor measured from the wheel's contact path, on hand-built geometry.

Not the ride simulator: wheel centres are placed by hand over a known floor surface. A wheel of
rolling radius R' standing upright on a surface with unit normal n (in the wheel's plane) has its
centre at P + R' n; tilted by theta about the direction of travel on a level floor, at height
R' cos(theta). Tolerances: the plane's slope over L metres of n points with noise sigma has a standard
error of about sigma sqrt(12 / n) / L; the checks allow 5 of those.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from euc_ros.core.states.floor import fit_floor, rolling_radius_from_floor

R = 0.203
SIGMA = 0.0003             # wheel-centre noise after smoothing [m]
N = 1200                   # 10 s at 120 Hz


def path(length=6.0, direction=1.0, seed=0):
    """A ride along x (0 -> length, or back) weaving 0.3 m sideways; the tilt theta swings +-3 deg."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, length, N)
    x = s if direction > 0 else length - s
    y = 0.3 * np.sin(2 * np.pi * s / 3.0)
    theta = np.radians(3.0) * np.sin(2 * np.pi * s / 2.0)
    return x, y, theta, rng


def centres(x, y, theta, rng, surface, radius=R):
    """Wheel centres over ``surface(x) -> (height, slope angle along x)`` (slope along travel only)."""
    height, alpha = surface(x)
    normal_x, normal_z = -np.sin(alpha), np.cos(alpha)          # the floor's normal in the x-z plane
    C = np.column_stack([x + radius * normal_x, y, height + radius * normal_z * np.cos(theta)])
    return C + rng.normal(0.0, SIGMA, C.shape)


def level(x):
    return np.zeros_like(x), np.zeros_like(x)


def test_level_floor_and_nominal_radius_is_flat_and_no_radius_error():
    x, y, theta, rng = path()
    fit = fit_floor(centres(x, y, theta, rng, level), theta, np.ones(N, bool), R)
    assert fit.flat and abs(fit.offset_m) < 5 * SIGMA / math.sqrt(N) + 1e-5
    r, significant, _ = rolling_radius_from_floor(fit, R, 0.005)
    assert not significant and r == pytest.approx(R, abs=1e-4)


def test_a_radius_error_on_a_level_floor_is_measured():
    x, y, theta, rng = path(seed=1)
    fit = fit_floor(centres(x, y, theta, rng, level, radius=R + 0.008), theta, np.ones(N, bool), R)
    r, significant, reason = rolling_radius_from_floor(fit, R, 0.005)
    assert fit.flat and significant, reason
    assert r == pytest.approx(R + 0.008, abs=5 * SIGMA / math.sqrt(N) + 1e-5)


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_a_ramp_in_a_level_calibrated_lab_is_a_slope_not_a_radius(direction):
    alpha = math.radians(2.0)
    x, y, theta, rng = path(direction=direction, seed=2)

    def ramp(x):
        return np.tan(alpha) * x, np.full_like(x, alpha)

    fit = fit_floor(centres(x, y, 0 * theta, rng, ramp, radius=R + 0.008), 0 * theta, np.ones(N, bool), R)
    tol = 5 * SIGMA * math.sqrt(12 / N) / 6.0
    assert not fit.flat
    # along a weaving path the slope felt is tan(alpha) times the cosine of the heading's angle to x
    hx, hy = np.gradient(x), np.gradient(y)
    felt = math.atan(float(np.mean(np.tan(alpha) * hx / np.hypot(hx, hy))))
    assert fit.slope_along_travel_rad == pytest.approx(felt, abs=tol)                # uphill +, downhill -
    assert np.sign(fit.slope_along_travel_rad) == direction
    assert fit.slope_rad == pytest.approx(alpha, abs=tol)
    r, significant, reason = rolling_radius_from_floor(fit, R, 0.005)
    assert math.isnan(r) and not significant and "not flat" in reason              # never a radius


def test_a_level_floor_then_a_ramp_and_a_bump_are_not_flat():
    x, y, theta, rng = path(seed=3)

    def level_then_ramp(x):
        a = math.radians(3.0)
        return np.where(x > 3.0, np.tan(a) * (x - 3.0), 0.0), np.where(x > 3.0, a, 0.0)

    def bump(x):
        h = 0.01 * np.exp(-0.5 * ((x - 3.0) / 0.15) ** 2)
        return h, np.arctan(np.gradient(h, x))

    for surface in (level_then_ramp, bump):
        fit = fit_floor(centres(x, y, theta, rng, surface), theta, np.ones(N, bool), R)
        assert not fit.flat, surface.__name__
        assert math.isnan(rolling_radius_from_floor(fit, R, 0.005)[0])
    assert fit.deviation_m == pytest.approx(0.01, abs=0.004)        # the bump's height, seen as a deviation


def test_too_short_a_path_gives_no_fit():
    x, y, theta, rng = path(length=0.5)
    assert fit_floor(centres(x, y, theta, rng, level), theta, np.ones(N, bool), R) is None
    assert rolling_radius_from_floor(None, R, 0.005)[2] == "path too short for a floor fit"
