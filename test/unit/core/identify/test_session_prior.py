"""The data's h combined with the segments' geometric h (euc_ros.core.identify.session_prior).

The combination is checked against independent computations: the product of two normals in closed form, a
one-sided likelihood's posterior median by quadrature, and the coverage of the interval by Monte Carlo with the
errors the two measurements have (a rectangular session error; a normal spread or a worst-case bound in the
data's interval).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, optimize, stats

from euc_ros.core.identify.session_prior import GRID_STEP_M, Z95, Z975, combine, split_levels

#: The grid's resolution of a quantile (the interpolation between two grid points is linear) [m].
GRID_TOL = GRID_STEP_M


@pytest.mark.parametrize(("h_d", "s_d", "h_g", "u_g"), [(0.60, 0.010, 0.61, 0.005), (0.80, 0.002, 0.79, 0.008),
                                                       (0.45, 0.050, 0.47, 0.006)])
def test_normal_data_give_the_product_of_normals(h_d, s_d, h_g, u_g):
    c = combine(h_d, (h_d - Z95 * s_d, h_d + Z95 * s_d), h_g, u_g)
    w = (1 / s_d ** 2) / (1 / s_d ** 2 + 1 / u_g ** 2)
    assert c.h_m == pytest.approx(w * h_d + (1 - w) * h_g, abs=GRID_TOL)
    assert c.weight_data == pytest.approx(w, rel=1e-9)
    # the interval: both intersected at levels whose misses sum to 5 % (Bonferroni), the narrower one's at least
    # 97.5 % (the larger share of the 5 %); equal widths: 97.5 % each
    z_d, z_g = split_levels(s_d, u_g)
    assert 2 * (stats.norm.sf(z_d) + stats.norm.sf(z_g)) == pytest.approx(0.05, rel=1e-9)
    assert (z_d if s_d < u_g else z_g) <= Z975 + 1e-9
    assert split_levels(u_g, u_g) == pytest.approx((Z975, Z975), abs=1e-6)
    lo = max(h_d - z_d * s_d, h_g - z_g * u_g)
    hi = min(h_d + z_d * s_d, h_g + z_g * u_g)
    assert c.consistent and c.ci95_m == pytest.approx((lo, hi), abs=1e-12)
    assert c.z == pytest.approx((h_d - h_g) / math.hypot(s_d, u_g))


def test_one_sided_data_give_the_quadrature_median():
    """Data bounded below only (flat above): the posterior median against scipy's quadrature of the density."""
    h_d, lo_d, h_g, u_g = 0.62, 0.58, 0.63, 0.01
    s_lo = (h_d - lo_d) / Z95

    def density(h):
        data = -0.5 * ((h - h_d) / s_lo) ** 2 if h < h_d else 0.0
        return math.exp(data - 0.5 * ((h - h_g) / u_g) ** 2)

    total = integrate.quad(density, 0.1, 1.2, points=[h_d, h_g], limit=200)[0]
    median = optimize.brentq(lambda x: integrate.quad(density, 0.1, x, points=[h_d], limit=200)[0] / total - 0.5,
                             0.5, 0.8)
    c = combine(h_d, (lo_d, None), h_g, u_g)
    assert c.h_m == pytest.approx(median, abs=GRID_TOL)
    assert math.isnan(c.h_data_ci95_m[1])
    z_d, z_g = split_levels(s_lo, u_g)          # the data's one bounded side sets its precision
    assert c.ci95_m == pytest.approx((max(h_d - z_d * s_lo, h_g - z_g * u_g), h_g + z_g * u_g), abs=1e-12)


def test_an_end_at_the_search_range_bounds_nothing():
    c = combine(0.30, (0.10, 0.35), 0.33, 0.006, bounds=(0.1, 1.2))
    assert math.isnan(c.h_data_ci95_m[0]) and c.h_data_ci95_m[1] == 0.35


@pytest.mark.parametrize("data_kind", ["normal", "bound"])
@pytest.mark.parametrize("ratio", [0.2, 1.0, 5.0])
def test_the_interval_holds_the_truth_at_least_95_percent(data_kind, ratio):
    """Monte Carlo: a rectangular session error (its u the stated one) and the data's error either normal (the
    interval +-1.96 sd) or a worst-case bound (any bias within it, uniform: the interval is the bound). The
    coverage is at least 95 % within three binomial standard errors, and the interval is never wider than the
    narrower of the two at 97.5 %."""
    rng = np.random.default_rng([77, int(10 * ratio), data_kind == "bound"])
    n, truth, u_g = 1500, 0.6, 0.0065
    half_g = u_g * math.sqrt(3.0)
    hits, too_wide = 0, 0
    for _ in range(n):
        h_g = truth + rng.uniform(-half_g, half_g)
        if data_kind == "normal":
            s = ratio * u_g
            h_d = truth + rng.normal(0.0, s)
            ci = (h_d - Z95 * s, h_d + Z95 * s)
        else:
            bound = ratio * half_g
            h_d = truth + rng.uniform(-bound, bound)
            ci = (h_d - bound, h_d + bound)
        c = combine(h_d, ci, h_g, u_g)
        hits += c.ci95_m[0] <= truth <= c.ci95_m[1]
        width_d = (ci[1] - ci[0]) * Z975 / Z95
        too_wide += c.consistent and (c.ci95_m[1] - c.ci95_m[0]) > min(width_d, 2 * Z975 * u_g) + 1e-12
    se = math.sqrt(0.95 * 0.05 / n)
    assert hits / n >= 0.95 - 3 * se, (hits / n, data_kind, ratio)
    assert too_wide == 0


def test_disagreement_gives_the_hull_of_both_and_says_what_to_check():
    c = combine(0.60, (0.59, 0.61), 0.66, 0.005)
    assert not c.consistent
    assert c.ci95_m == pytest.approx((0.59, 0.66 + Z95 * 0.005))
    assert "session" in c.warning() and "euc-ros residual" in c.warning()
    assert c.warning() in c.console_line()
    assert combine(0.60, (0.59, 0.61), 0.605, 0.005).warning() == ""


def test_the_json_names_both_measurements():
    d = combine(0.60, (0.58, None), 0.61, 0.005).to_json()
    assert d["h_from_data_ci95_m"] == [0.58, None]
    assert d["h_geometric_m"] == 0.61 and d["u_geometric_m"] == 0.005 and d["consistent"] is True
    assert 0.0 <= d["weight_data"] <= 1.0


@pytest.mark.parametrize(("args", "message"), [((float("nan"), None, 0.6, 0.01), "finite"),
                                               ((0.6, None, 0.6, 0.0), "positive")])
def test_bad_input_is_refused(args, message):
    with pytest.raises(ValueError, match=message):
        combine(*args)
