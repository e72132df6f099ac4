"""The h of the 3-DoF model extended with fixed effects (euc_ros.core.identify.extended).

Known answers: a quadratic sum of squares has its minimum, curvature and sharpness in closed form; an
effect of zero strength adds nothing, so the extended fit is the paper's 3-DoF fit (fit_h) on the same
samples; a sandwich interval shrinks when a second, independent recording is added.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.identify.extended import extended_fits, extended_inputs, extended_interval, fit_from_sse
from euc_ros.core.identify.fit import fit_h
from euc_ros.core.model.terms import EucParams
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.kinematics import reconstruct_states

H_TRUE = 0.61  # RideConfig's default truth
GRID = np.linspace(0.1, 1.2, 45)
ZERO_ROLLING = {"rolling_resistance": {"c_rr": 0.0}}


@pytest.fixture(scope="module")
def ride():
    """Two 6 s simulated decelerations (h = 0.61 m) and their reconstructed states."""
    sim = simulate_ride(RideConfig(runs=2, seed=3, duration_s=6))
    states = [reconstruct_states(r.mocap, sim.session) for r in sim.runs]
    return states, EucParams.from_session(sim.session, H_TRUE)


# --- fit_from_sse on a sum of squares with a known answer ------------------------------------------------

def test_fit_from_sse_of_a_parabola_gives_its_vertex_curvature_std_and_sharpness():
    a, h0, c, n = 50.0, 0.4321, 2.0, 101  # sse(h) = a (h - h0)^2 + c, vertex between grid points
    fit = fit_from_sse(lambda h: a * (h - h0) ** 2 + c, np.linspace(0.1, 1.0, 10), n, "m")
    assert fit.model == "m" and fit.n_samples == n
    assert fit.h_m == pytest.approx(h0, abs=1e-6)
    assert fit.rmse_nm == pytest.approx(np.sqrt(c / n), rel=1e-9)
    # sigma^2 = 2 s^2 / SSE'' with s^2 = c / (n - 1) and SSE'' = 2 a
    assert fit.h_std_m == pytest.approx(np.sqrt(2 * c / (n - 1) / (2 * a)), rel=1e-4)
    # RMSE at h0 +- 0.1 is sqrt((a 0.01 + c) / n) on both sides
    assert fit.sharpness == pytest.approx(np.sqrt((a * 0.01 + c) / c) - 1, rel=1e-6)
    assert not fit.at_bound
    assert fit.rmse_curve_nm.shape == (10,)


def test_fit_from_sse_flags_a_minimum_at_the_grid_end():
    fit = fit_from_sse(lambda h: (h - 2.0) ** 2 + 1.0, np.linspace(0.1, 1.0, 10), 10, "m")
    assert fit.at_bound
    assert fit.h_m == pytest.approx(1.0)


def test_fit_from_sse_without_samples_is_nan():
    fit = fit_from_sse(lambda h: 0.0, np.linspace(0.1, 1.0, 5), 0, "m")
    assert np.isnan(fit.h_m) and np.isnan(fit.rmse_nm) and fit.n_samples == 0
    assert np.all(np.isnan(fit.rmse_curve_nm))


# --- extended_fits / extended_inputs on a simulated ride -------------------------------------------------

def test_a_zero_strength_effect_gives_the_papers_3dof_fit(ride):
    states, params = ride
    paper = fit_h(states, params, GRID, models=("3dof",))
    label, per, pooled = extended_fits(states, params, ZERO_ROLLING, GRID)
    assert label == "3dof+rolling_resistance"
    ref = paper.pooled["3dof"]
    assert pooled.n_samples == ref.n_samples
    assert pooled.h_m == pytest.approx(ref.h_m, abs=1e-6)
    assert pooled.rmse_nm == pytest.approx(ref.rmse_nm, rel=1e-6)
    np.testing.assert_allclose(pooled.rmse_curve_nm, ref.rmse_curve_nm, rtol=1e-6)
    assert len(per) == len(states)
    for fit, rec in zip(per, paper.per_recording):
        assert fit.n_samples == rec.fits["3dof"].n_samples
        assert fit.h_m == pytest.approx(rec.fits["3dof"].h_m, abs=1e-6)
    assert pooled.h_m == pytest.approx(H_TRUE, abs=0.02)  # and that fit finds the simulator's truth


def test_extended_inputs_are_the_valid_samples_with_time_from_the_recordings_start(ride):
    states, params = ride
    inputs = extended_inputs(states, params, ZERO_ROLLING)
    assert len(inputs) == len(states)
    for (arrays, extras), st in zip(inputs, states):
        n = int(np.count_nonzero(st.valid))
        assert extras == {}
        assert {len(v) for v in arrays.values()} == {n}
        assert arrays["t"][0] >= 0 and np.all(np.diff(arrays["t"]) > 0)
        np.testing.assert_array_equal(arrays["phi"], np.asarray(st.phi)[np.asarray(st.valid, bool)])


def test_an_effect_with_a_missing_parameter_names_it(ride):
    states, params = ride
    with pytest.raises(ConfigError, match="rolling_resistance.c_rr"):
        extended_fits(states, params, {"rolling_resistance": {}}, GRID)


# --- extended_interval ----------------------------------------------------------------------------------

def test_the_interval_contains_the_fitted_h_and_narrows_with_more_data(ride):
    states, params = ride
    _, per, pooled = extended_fits(states, params, ZERO_ROLLING, GRID)
    lo2, hi2, se2, nb2 = extended_interval(states, params, ZERO_ROLLING, pooled.h_m, 1.0)
    lo1, hi1, se1, nb1 = extended_interval(states[:1], params, ZERO_ROLLING, per[0].h_m, 1.0)
    assert lo2 < pooled.h_m < hi2 and lo1 < per[0].h_m < hi1
    assert lo2 < H_TRUE < hi2
    # 1 s blocks of each recording's valid samples (6 s less its take's one-sided ends too uncertain to use)
    t = states[0].t[states[0].valid]
    assert nb1 == int(np.ceil(t[-1] - t[0])) and nb2 == 2 * nb1
    assert se2 < se1 and hi2 - lo2 < hi1 - lo1
    # symmetric: h -+ t_{B-1} se
    assert (hi2 - pooled.h_m) == pytest.approx(pooled.h_m - lo2)


def test_the_interval_needs_three_blocks(ride):
    states, params = ride
    lo, hi, se, nb = extended_interval(states[:1], params, ZERO_ROLLING, H_TRUE, 3.0)
    assert nb == 2
    assert np.isnan(lo) and np.isnan(hi) and np.isnan(se)
