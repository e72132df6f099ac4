"""Statistical power and false discoveries with 3 runs of 7 s.

Every library family that can show in the residual of straight rides, at a magnitude whose model cuts
the held-out RMSE by 25-40 % (:data:`~studies.campaign.POWER_MAGNITUDES`, calibrated
with ``studies/residual_power.py --calibrate``), on seeds the calibration and the README's study did not
use; and no-effect rides. The full study (10 seeds per family, 30 no-effect rides) is
``studies/residual_power.py``; its table is in the README.

Each trial is its own test (it records its outcome); the last test checks the rates over all of them,
so one marginal seed on another CPU cannot fail the suite while a method that lost its power does:
detected (named, or a statistical twin named with the truth listed as tied) in at least 85 % of the
trials of every family (the README measures 9/10 or 10/10 each with blocks from the noise's correlation
and the max-T correction; 5/10 for time_varying_h before); an absent library effect named without the
truth among its ties: only a first-order twin of the truth, at most once; no effect named on no-effect
rides. The false-discovery rate itself (100 no-effect rides at four levels) is ``residual_power.py --fdr``.

Not here: wheel_radius_error (it cannot show in the residual: found by geometry,
``test_undeclared_effects.py``) and tilt_gravity (needs aggressive turns, not 7 s straight runs).
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

# the experiment harnesses live in studies/ at the repository root, outside the package
sys.path.insert(0, str(Path(__file__).resolve().parents[4]))
from studies.campaign import POWER_MAGNITUDES, power_trial  # noqa: E402

pytestmark = pytest.mark.slow

SEEDS = (300, 301)
NULL_SEEDS = (310, 311, 312, 313)
#: Families whose detection the README measures below 90 % (reported there with the reason): none since the
#: blocks follow the noise's correlation and the step's candidates share a max-T correction.
LOW_POWER: tuple = ()
#: First-order twins (README, limits): the one may be named for the other at these small magnitudes.
TWINS = {"viscous_friction": {"mocap_time_offset"}, "mocap_time_offset": {"viscous_friction"},
         "rider_mass_error": {"rider_inertia_error"}, "rider_inertia_error": {"rider_mass_error"}}
OUTCOMES: dict = {}


@pytest.mark.parametrize("family, seed", [(f, s) for f in POWER_MAGNITUDES for s in SEEDS])
def test_trial(family, seed):
    r = power_trial(family, seed)
    OUTCOMES[(family, seed)] = r
    assert 0.15 <= r["cut"] or not r["detected_or_tied"], r    # the magnitude is a real, partial cut
    # a wrong name may only be the family's statistical twin (README limits)
    assert set(r["false_named"]) <= TWINS.get(family, set()), (family, seed, r["effect"])


@pytest.mark.parametrize("seed", NULL_SEEDS)
def test_no_effect_rides_name_nothing(seed):
    r = power_trial(None, seed)
    assert not r["false_named"], r["effect"]


def test_detection_rate():
    rows = [r for (f, _), r in OUTCOMES.items() if f not in LOW_POWER]
    if len(rows) < len(SEEDS) * (len(POWER_MAGNITUDES) - len(LOW_POWER)):
        pytest.skip("needs every trial of this module (run the whole file)")
    detected = sum(r["detected_or_tied"] for r in rows)
    assert detected >= 0.85 * len(rows), [(r["family"], r["seed"], r["effect"]) for r in rows if not r["detected_or_tied"]]  # noqa: E501
    # twins named for the truth without listing it as tied: measured 1 in 80 trials (README; the tie test is
    # one-sided at AMBIGUITY_ALPHA = 0.05, so two twins the data cannot separate come out untied ~5 % of the time)
    assert sum(bool(r["false_named"]) for r in OUTCOMES.values()) <= 1
