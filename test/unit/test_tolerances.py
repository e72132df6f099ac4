"""The round-off bounds the tests derive their tolerances from (euc_ros.testing), and the replay-timing
arithmetic of the play benchmark."""
from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from euc_ros.testing import EPS, savgol_coefficients, savgol_roundoff


def test_coefficients_are_the_textbook_five_point_quadratic_ones():
    """Savitzky & Golay's 5-point quadratic tables: smoothing, first and second derivative."""
    np.testing.assert_allclose(savgol_coefficients(5, 2, 0, 1.0), np.array([-3, 12, 17, 12, -3]) / 35, atol=1e-15)
    np.testing.assert_allclose(savgol_coefficients(5, 2, 1, 1.0), np.array([-2, -1, 0, 1, 2]) / 10, atol=1e-15)
    np.testing.assert_allclose(savgol_coefficients(5, 2, 2, 1.0), np.array([2, -1, -2, -1, 2]) / 7, atol=1e-15)
    # the sample spacing scales the d-th derivative by dt^-d
    np.testing.assert_allclose(savgol_coefficients(5, 2, 2, 0.1), np.array([2, -1, -2, -1, 2]) / 7 / 0.01,
                               rtol=1e-14)


@pytest.mark.parametrize("window, polyorder, deriv, offset", [(25, 6, 2, 16.0), (145, 6, 2, 25.0), (9, 3, 1, 3.0)])
def test_the_bound_covers_a_sound_filter_far_from_the_origin(window, polyorder, deriv, offset):
    """A quadratic 16-25 m from the origin, filtered with the helper's coefficients in float64, against
    the exact value in rational arithmetic: the error stays within savgol_roundoff."""
    dt = 1 / 120
    k = np.arange(window) - window // 2
    y = offset + 2.0 * k * dt + 0.25 * (k * dt) ** 2
    h = savgol_coefficients(window, polyorder, deriv, dt)
    got = float(h @ y)
    exact = [Fraction(offset), Fraction(2), Fraction(1, 2)][deriv]
    err = abs(Fraction(got) - exact)
    bound = savgol_roundoff(window, polyorder, deriv, dt, float(np.abs(y).max()))
    assert float(err) <= bound
    assert bound < 1e-6 * max(1.0, float(exact))       # and it is a tight tolerance, not a blanket one


def test_the_bound_grows_with_the_scale_and_the_derivative():
    a = savgol_roundoff(25, 6, 2, 1 / 120, 1.0)
    assert savgol_roundoff(25, 6, 2, 1 / 120, 10.0) == pytest.approx(10 * a)
    assert savgol_roundoff(25, 6, 1, 1 / 120, 1.0) < a
    assert a > EPS * np.abs(savgol_coefficients(25, 6, 2, 1 / 120)).sum()


def test_play_timing_errors_remove_the_constant_offset_and_scale_by_the_rate():
    from euc_ros.bench.play import summary_ms, timing_errors

    stamps = np.array([0, 10, 30, 60], dtype=np.int64) * 10**6          # ns
    on_time = 100.0 + np.array([0.0, 0.005, 0.015, 0.030])              # rate 2: half the recorded offsets
    np.testing.assert_allclose(timing_errors(on_time + 0.25, stamps, 2.0), 0.0, atol=1e-12)
    late = on_time + np.array([0.0, 0.0, 0.003, 0.0])
    s = summary_ms(timing_errors(late, stamps, 2.0))
    assert s["max"] == pytest.approx(3.0, abs=1e-9) and s["within_2ms"] == 0.75 and s["n"] == 4
