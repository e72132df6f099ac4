"""Identifiability a lab can act on: every refusal says what the ride had and what h needs, derived.

The sharpness criterion is turned into a needed sensitivity by the quadratic model of the RMSE curve
and into a needed speed change by the split of the sensitivity into speed changes and balance motion
(:mod:`euc_ros.core.identify.excitation`); both are checked here against rides of the simulator at
other speed scales, and the data-amount advice against rides recorded as advised.
"""
# covers: euc_ros/core/identify/excitation.py
# covers: euc_ros/core/identify/interval.py
# covers: euc_ros/core/identify/pipeline.py
from __future__ import annotations

import glob
import math

import numpy as np
import pytest

from euc_ros.core.identify.excitation import (
    measure_excitation,
    more_data_for_blocks,
    more_data_for_seconds,
    needed_sensitivity,
    predicted_sharpness,
    quadratic_error_bound,
)
from euc_ros.core.identify.fit import SHARPNESS_STEP_M, coefficients_for, fit_h, sse_grid
from euc_ros.core.identify.interval import MIN_BLOCKS, MIN_DURATION_S, MIN_SHARPNESS, _times, interval, turning_rms
from euc_ros.core.model.terms import EucParams
from euc_ros.core.ridesim.mocap_synth import MocapNoise
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.kinematics import reconstruct_states

#: Twice the default pose noise: a flatter RMSE curve, so that the simulator's decelerations cross the
#: sharpness criterion within its speed scales.
NOISY = MocapNoise(pos_sigma_m=0.4e-3, rot_rms_deg=1.0, marker_error_m=0.3e-3)


def _fitted(**config):
    ride = simulate_ride(RideConfig(**config))
    params = EucParams.from_session(ride.session)
    states = [reconstruct_states(r.mocap, ride.session) for r in ride.runs]
    fit = fit_h(states, params, models=("3dof",)).pooled["3dof"]
    return states, coefficients_for(states, params, "3dof", None), fit


def _interval(**config):
    states, coefs, fit = _fitted(**config)
    return interval(coefs, fit, window=states[0].window, dt=states[0].dt, turning_ms2=turning_rms(states),
                    states=states)


@pytest.mark.parametrize("speed_scale", [0.3, 1.0, 2.0])
def test_the_rmse_curve_rises_as_the_sensitivity_says(speed_scale):
    """The quadratic model ``RMSE^2 = RMSE0^2 + S^2 (h - h*)^2``: its two-sided rise of the mean square at
    +-0.1 m agrees with the grid's within the bound of its left-out fourth-order terms, and the sharpness
    it predicts with the measured one within the same relative amount."""
    _, coefs, fit = _fitted(runs=1, seed=0, speed_scale=speed_scale)
    exc = measure_excitation(coefs, fit.h_m, fit.rmse_nm)
    coef = coefs[0]
    d = SHARPNESS_STEP_M
    sse0, = sse_grid(coef, np.array([fit.h_m]))
    rise = float(np.mean(sse_grid(coef, np.array([fit.h_m - d, fit.h_m + d])))) / sse0 - 1.0
    predicted = (d * exc.sensitivity_nm_per_m / exc.rmse_nm) ** 2
    bound = quadratic_error_bound(coefs, fit.h_m)
    assert 0 < bound < 0.25                            # kappa ~ 0.12: a bound that means something
    assert abs(rise / predicted - 1.0) <= bound, (rise, predicted, bound)
    sharp = predicted_sharpness(exc.sensitivity_nm_per_m, exc.rmse_nm)
    assert abs(sharp / fit.sharpness - 1.0) <= bound, (sharp, fit.sharpness, bound)
    # the needed sensitivity gives the criterion's sharpness exactly in the quadratic model
    assert predicted_sharpness(needed_sensitivity(exc.rmse_nm, MIN_SHARPNESS), exc.rmse_nm) == pytest.approx(
        MIN_SHARPNESS)


def test_the_needed_speed_change_identifies_the_ride():
    """A deceleration ride too weak for h asks for k times its speed changes; the same ride with speed
    changes k times as large (speed scale times k) has the criterion's sharpness. The tolerance is the
    quadratic model's error bound at the criterion (the error of scaling only the speed-change part of
    the sensitivity comes on top; measured here, the whole error is about a third of the bound)."""
    k1 = 0.6
    states, coefs, fit = _fitted(seed=1, speed_scale=k1, noise=NOISY)
    iv = interval(coefs, fit, window=states[0].window, dt=states[0].dt, states=states)
    ex = iv.extra["excitation"]
    k = ex["speed_change_factor_needed"]
    assert fit.sharpness < MIN_SHARPNESS and 1.2 < k < 3.0
    assert f"about {_times(k)} times these speed changes in the same time" in iv.reason
    assert f"(about {k * min(ex['speed_change_mps']):.1f}-{k * max(ex['speed_change_mps']):.1f} m/s" in iv.reason
    _, coefs2, fit2 = _fitted(seed=1, speed_scale=k1 * k, noise=NOISY)
    x = (1.0 + MIN_SHARPNESS) ** 2 - 1.0
    tol = quadratic_error_bound(coefs2, fit2.h_m) * x / (2.0 * (1.0 + MIN_SHARPNESS))
    assert abs(fit2.sharpness - MIN_SHARPNESS) <= tol, (fit2.sharpness, tol)
    # scaling all the acceleration alike (S proportional to the total RMS acceleration) asks for less
    # than the speed changes the criterion needs: the balance motion does not grow with them
    naive = ex["sensitivity_needed_nm_per_m"] / ex["sensitivity_nm_per_m"]
    assert naive < k


def test_a_weak_deceleration_is_told_by_how_much_it_falls_short():
    iv = _interval(seed=0, speed_scale=0.4, noise=NOISY)
    ex = iv.extra["excitation"]
    assert not iv.identifiable and "too little excitation" in iv.reason
    assert "ride with speed changes" not in iv.reason
    # what it had, in the message as in the JSON
    dv = ex["speed_change_mps"]
    assert min(dv) > 0.8                               # a deceleration: it has speed changes
    assert f"changed speed by {min(dv):.1f}-{max(dv):.1f} m/s" in iv.reason
    assert f"RMS longitudinal acceleration {ex['accel_rms_mps2']:.2f} m/s^2" in iv.reason
    # what it needs: more of what it has
    k = ex["speed_change_factor_needed"]
    assert k > 1.0 and f"about {_times(k)} times these" in iv.reason
    assert f"an RMS acceleration of about {ex['speed_change_accel_rms_needed_mps2']:.2f} m/s^2" in iv.reason
    assert ex["speed_change_accel_rms_needed_mps2"] > ex["speed_change_accel_rms_mps2"]
    assert ex["accel_rms_needed_mps2"] > ex["accel_rms_mps2"]
    assert ex["sensitivity_needed_nm_per_m"] > ex["sensitivity_nm_per_m"]
    assert all(n > h for n, h in zip(ex["speed_change_needed_mps"], dv))
    assert len(ex["phi_range_deg"]) == 3 and all(2.0 < p < 20.0 for p in ex["phi_range_deg"])


def test_a_short_deceleration_is_told_how_much_more_to_record():
    """Too short: the usable seconds against those needed, and riding as much longer as advised is
    no longer too short."""
    cfg = dict(runs=1, seed=3, duration_s=3.0)
    iv = _interval(**cfg)
    ex = iv.extra["excitation"]
    assert not iv.identifiable and iv.reason.startswith("too short")
    assert "ride with speed changes" not in iv.reason
    assert ex["usable_s"] < ex["usable_s_needed"] == MIN_DURATION_S
    more = MIN_DURATION_S - ex["usable_s"]
    assert f"{ex['usable_s']:.1f} s of usable states" in iv.reason
    assert f"record at least {math.ceil(10 * more - 1e-9) / 10:.1f} s more" in iv.reason
    assert ex["record_more_s"] >= more - 1e-9 and ex["more_runs_needed"] >= 1
    if "too little excitation" in iv.reason:           # the start of a deceleration: more of the same
        assert ex["speed_change_factor_needed"] > 1.0 and "times these" in iv.reason
    longer = _interval(**{**cfg, "duration_s": 3.0 + math.ceil(10 * more) / 10})
    assert "too short" not in longer.reason
    assert longer.extra["excitation"]["usable_s"] >= MIN_DURATION_S - 1e-9


def test_too_few_blocks_are_told_the_blocks_needed_and_more_runs_give_them():
    # 5 s: usable states over more than MIN_DURATION_S but fewer than MIN_BLOCKS blocks of the 1.2 s window
    iv = _interval(runs=1, seed=1, duration_s=5.0)
    ex = iv.extra["excitation"]
    assert not iv.identifiable and iv.reason.startswith("too few independent blocks")
    assert ex["blocks"] == iv.n_blocks < ex["blocks_needed"] == MIN_BLOCKS
    assert f"({ex['blocks']} of {ex['block_s']:.1f} s in {ex['usable_s']:.1f} s of usable states" in iv.reason
    assert ex["record_more_s"] > 0 and ex["more_runs_needed"] >= 1
    assert f"{ex['more_runs_needed']} more run" in iv.reason
    runs = _interval(runs=1 + ex["more_runs_needed"], seed=1, duration_s=5.0)
    assert runs.n_blocks >= MIN_BLOCKS and "blocks" not in runs.reason


def test_a_wide_interval_is_told_the_recording_its_random_part_needs():
    from euc_ros.core.identify.interval import MAX_CI_WIDTH_M, _width_text

    # 18 cm, 12 of them random over 10 s: the random part must shrink to 9 cm, (12/9)^2 = 1.78 times the
    # time, 7.8 s more, two more runs of 5 s
    text, more_s, runs = _width_text(0.18, 0.12, (5.0, 5.0))
    assert more_s == pytest.approx(10.0 * (0.12 / (MAX_CI_WIDTH_M - 0.06)) ** 2 - 10.0) and runs == 2
    assert "18 cm wide" in text and "record about 7.8 s more, or 2 more runs like these" in text
    # bias terms wider than the limit: no amount of the same data helps
    text, more_s, runs = _width_text(0.20, 0.03, (5.0, 5.0))
    assert (more_s, runs) == (0.0, 0) and "bias terms alone take 17 cm" in text


def test_the_data_amounts_needed():
    # one take of 576 samples, 3 blocks of 145: 4 samples more give the fourth block, or one run like it
    assert more_data_for_blocks([3], [576], 145, 4, 0.01) == (pytest.approx(0.04), 1)
    # two takes of one block each: the longer grows by two blocks' worth, or two runs like them
    assert more_data_for_blocks([1, 1], [150, 200], 145, 4, 0.01) == (pytest.approx(2.35), 2)
    # a take shorter than a block counts as one
    assert more_data_for_blocks([1], [100], 145, 4, 0.01) == (pytest.approx(4.8), 3)
    assert more_data_for_blocks([3, 3], [500, 500], 145, 4, 0.01) == (0.0, 0)
    assert more_data_for_seconds([1.5, 1.0], 4.0) == (pytest.approx(1.5), 2)
    assert more_data_for_seconds([3.0, 2.0], 4.0) == (0.0, 0)


def test_the_default_ride_is_identifiable_with_its_margins_in_the_json(tmp_path):
    """The simulator's default ride (three 7-s decelerations), through ``euc-ros identify``'s pipeline:
    identifiable, with what it had and what h needs in ``uncertainty.excitation`` beside the keys the
    JSON had."""
    from euc_ros.core.identify.pipeline import identify_recordings
    from euc_ros.core.ridesim.writers import write_ride

    write_ride(simulate_ride(RideConfig(seed=0)), tmp_path)
    recs = sorted(glob.glob(str(tmp_path / "deceleration_*.csv")))
    assert len(recs) == 3
    run = identify_recordings(tmp_path / "session.yaml", recs)
    data = run.data
    assert data["identifiable"] is True and data["identifiability_reason"] is None, data["identifiability_reason"]
    u = data["uncertainty"]
    for key in ("bootstrap_ci95_m", "block_s", "n_blocks", "eiv_bias_m", "sharpness", "turning_rms_ms2"):
        assert key in u
    ex = u["excitation"]
    assert ex["blocks"] == u["n_blocks"] >= ex["blocks_needed"]
    assert ex["usable_s"] >= ex["usable_s_needed"] and ex["record_more_s"] == 0 and ex["more_runs_needed"] == 0
    assert ex["sensitivity_nm_per_m"] > ex["sensitivity_needed_nm_per_m"]
    assert 0 <= ex["speed_change_factor_needed"] < 1 and ex["accel_rms_mps2"] > ex["accel_rms_needed_mps2"]
    assert len(ex["speed_change_mps"]) == 3 and all(v > 2.0 for v in ex["speed_change_mps"])


def test_a_missing_effect_is_not_advised_as_too_little_excitation(tmp_path):
    """A 2.5 deg slope nobody declared leaves a residual no excitation could bound: the advice would ask for
    accelerations no rider can hold, so it names the likelier cause (an effect the model lacks) instead of
    only asking for more speed change; a clean ride of the same manoeuvre gets no such line."""
    from euc_ros.core.identify.interval import MAX_RIDE_ACCEL_RMS_MPS2
    from euc_ros.core.identify.pipeline import identify_recordings
    from euc_ros.core.ridesim.effects import EffectSet
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    for name, effects in (("slope", {"ground_slope": {"alpha_deg": 2.5}}), ("flat", {})):
        folder = tmp_path / name
        write_ride(simulate_ride(RideConfig(runs=2, seed=7, effects=EffectSet(effects))), folder)
        data = identify_recordings(folder / "session.yaml", sorted(folder.glob("deceleration_*.csv"))).data
        needed = data["uncertainty"]["excitation"]["speed_change_accel_rms_needed_mps2"]
        said = "effect the 3-DoF model lacks" in (data["identifiability_reason"] or "")
        assert said == (name == "slope") == (needed > MAX_RIDE_ACCEL_RMS_MPS2), (name, needed, data["identifiable"])
