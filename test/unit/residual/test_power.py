"""Issue 12, bullet 2: statistical power and false discoveries with 3 runs of 7 s.

Every library family that can show in the residual of straight rides, at a magnitude whose model cuts
the held-out RMSE by 25-40 % (:data:`~euc_ros.core.residual.campaign.POWER_MAGNITUDES`, calibrated
with ``tools/residual_power.py --calibrate``), on seeds the calibration did not use; and no-effect
rides. The full study (10 seeds per family, 30 no-effect rides) is ``tools/residual_power.py``; its
table is in the README. Here two seeds per family: each must be detected (named, or named as a
statistical twin with the truth reported as tied to it in ``ambiguous_with``), and no absent effect
may be named untied; no-effect rides may name nothing.

Not here: wheel_radius_error (it cannot show in the residual: found by geometry,
``test_undeclared_effects.py``) and tilt_gravity (needs aggressive turns, not 7 s straight runs).
"""
from __future__ import annotations

import pytest

from euc_ros.core.residual.campaign import POWER_MAGNITUDES, power_trial

pytestmark = pytest.mark.slow

SEEDS = (300, 301)


@pytest.mark.parametrize("family", list(POWER_MAGNITUDES))
def test_family_is_detected_at_a_third_of_the_rmse(family):
    for seed in SEEDS:
        r = power_trial(family, seed)
        assert 0.2 <= r["cut"], (seed, r)       # the magnitude is in the 25-40 % range (with spread)
        assert r["detected_or_tied"], (seed, r["effect"], r["ambiguous_with"])
        assert not r["false_named"], (seed, r["effect"])


@pytest.mark.parametrize("seed", [310, 311, 312, 313])
def test_no_effect_rides_name_nothing(seed):
    r = power_trial(None, seed)
    assert not r["false_named"], r["effect"]
