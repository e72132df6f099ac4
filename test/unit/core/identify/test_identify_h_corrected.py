"""identify's headline h, corrected for the pose noise and the filter's distortion, is unbiased on noisy
rides of the independent generator, and its interval contains the truth; the uncorrected h at the chosen
filter (a diagnostic) is not."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import t as student

from euc_ros.core.identify.cog_height import identify_h
from euc_ros.core.identify.options import IntervalOptions
from euc_ros.core.io.recordings import load_recording
from euc_ros.core.mocap.noise import pose_noise_draws, pose_noise_series
from euc_ros.core.session import load_session
from euc_ros.core.states.filter_choice import choose_filter
from euc_ros.core.states.kinematics import reconstruct_states

#: The capture's white pose noise (the paper's): position per axis [m], rotation per body axis [rad].
NOISE = (0.2e-3, float(np.radians(0.5) / np.sqrt(3.0)))
#: Rides, seeds and frame rates drawn once from default_rng(7) (not picked).
_RNG = np.random.default_rng(7)
RIDES = [(int(s), float(r)) for s, r in zip(_RNG.integers(1, 10_000, 5), _RNG.choice([100.0, 120.0], 5))]
#: False-alarm rate of the test of zero mean error (two-sided).
ALPHA = 0.05
#: ``|mean| < K * SE`` holds with probability 1 - ALPHA for an unbiased estimate (Student's t, n - 1 dof).
K = float(student.ppf(1.0 - ALPHA / 2.0, len(RIDES) - 1))


def _identify(series, session):
    choice = choose_filter([series], session)
    st = reconstruct_states(series, session, window_s=choice.window_s, polyorder=choice.polyorder)
    st.meta["series"] = series
    return identify_h([st], session, filter_choice=choice,
                      uncertainty=IntervalOptions(with_budget=False, sliding=False))


@pytest.fixture(scope="module")
def errors(tmp_path_factory):
    """Per ride, the errors [m] of the h at the chosen filter, of that h - SIMEX bias (the noise corrected,
    not the filter's distortion) and of the headline (corrected) h, each the mean over an antithetic pair of
    noisy recordings (the noise-free file plus and minus one draw of the noise): the pair cancels the
    noise's first-order (zero-mean) effect on h, so its mean is the estimate's bias plus a small
    scatter; and whether each member's interval of the corrected h contains the truth. (About 20 s
    for all tests here: a bias test needs several independent rides, each identified twice.)"""
    from euc_ros.core.worldsim import Capture, simulate_ride, write_ride

    out = {"h": [], "simex": [], "corrected": [], "covered": []}
    for seed, rate in RIDES:
        ride = simulate_ride(seed, rate, duration=12.0)
        paths = write_ride(ride, tmp_path_factory.mktemp(f"ws{seed}"), Capture(), seed=seed, name=f"ws{seed}")
        session = load_session(paths["session"])
        clean = load_recording(paths["csv"], session.world_up)
        z = pose_noise_draws(clean, np.random.default_rng(seed))
        b = len(clean.bodies)
        pair = [_identify(pose_noise_series(clean, np.full(b, NOISE[0]), np.full(b, NOISE[1]), noise=z,
                                            sign=sign).materialize(), session) for sign in (1.0, -1.0)]
        assert all(p.corrected for p in pair)     # the headline h is the corrected one
        out["h"].append(np.mean([p.h_at_filter for p in pair]) - ride.h)
        out["simex"].append(np.mean([p.h_at_filter - p.uncertainty["uncertainty"]["eiv_bias_m"] for p in pair])
                            - ride.h)
        out["corrected"].append(np.mean([p.h for p in pair]) - ride.h)
        out["covered"] += [p.interval[0] <= ride.h <= p.interval[1] for p in pair]
    return {k: np.asarray(v) for k, v in out.items()}


def _t(e: np.ndarray) -> float:
    return float(e.mean() / (e.std(ddof=1) / np.sqrt(e.size)))


def test_corrected_h_is_unbiased_on_noisy_generator_rides(errors):
    assert abs(_t(errors["corrected"])) < K, (_t(errors["corrected"]), errors["corrected"])


@pytest.mark.parametrize("estimate", ["h", "simex"])
def test_uncorrected_h_fails_the_same_test(errors, estimate):
    # on these rides the test sees the bias of h (noise and distortion, t = -3.0) and of h - SIMEX bias
    # (the filter's distortion, t = -3.1): the distortion's correction is what makes it pass
    assert abs(_t(errors[estimate])) > K, (_t(errors[estimate]), errors[estimate])


def test_corrected_interval_covers_the_truth(errors):
    # 10 intervals of 95 %: 8 or more cover the truth with probability 0.99 (binomial)
    assert errors["covered"].sum() >= 8, errors["covered"]
