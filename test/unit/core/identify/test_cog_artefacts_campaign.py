"""Campaign, the part a test can afford (one seed; the full campaign is studies/artefact_campaign.py).

What the campaign measured and this test pins (docs/cog_artefacts.md): no CoG method reaches the
issue's h goals (10 mm at 3 mm sliding, 20 mm at 10 mm) on these 7 s runs, so the test asserts what
holds instead, with margins taken from the spread over the campaign's three seeds:

* independent sliding of 10 mm: the skeleton's RMSE of M_d1 - M_d2 is at most 0.8 of the per-segment
  CoG's (measured 0.60-0.72) and its h error smaller in magnitude (measured -70..-79 mm against
  -114..-150 mm);
* where the goal is not met, identify's 95 % interval (block bootstrap, white-noise and sliding
  SIMEX biases) contains the true h, or identify refuses h as not identifiable;
* swapped and flipped bodies are excluded (the chain finds every injected body-frame it can see).
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

from euc_ros.core.ridesim.simulate import DEFAULT_H_M

# the experiment harnesses live in studies/ at the repository root, outside the package
sys.path.insert(0, str(Path(__file__).resolve().parents[4]))
from studies.cog_artefacts import Case, evaluate, simulate_clean  # noqa: E402

pytestmark = pytest.mark.slow

SEED = 11


@pytest.fixture(scope="module")
def ride():
    return simulate_clean(SEED)


def test_independent_sliding_skeleton_beats_segments_and_the_interval_holds(ride):
    session, cleans = ride
    rows = {r["method"]: r for r in evaluate(cleans, session, Case(0.010, accel_share=0.0), SEED)}
    seg, sk = rows["segments"], rows["skeleton"]
    assert sk["rmse_nm"] <= 0.8 * seg["rmse_nm"], (sk["rmse_nm"], seg["rmse_nm"])
    assert abs(sk["h_err_mm"]) < abs(seg["h_err_mm"])
    assert abs(seg["h_err_mm"]) > 20.0          # the goal is not met: the interval must say so
    iv = evaluate(cleans, session, Case(0.010, accel_share=0.0), SEED, methods=("segments",),
                  with_interval=True)[0]
    lo, hi = iv["h_ci95_m"]
    assert (lo <= DEFAULT_H_M <= hi) or not iv["identifiable"], iv
    assert iv["sliding_bias_m"] < -0.02        # the sliding's bias is measured (h reads low)


def test_swaps_and_flips_are_excluded(ride):
    session, cleans = ride
    rows = {r["method"]: r for r in evaluate(cleans[:2], session, Case(0.003, swaps=2, flips=2), SEED)}
    sk = rows["skeleton"]
    assert rows["segments"]["faults_excluded"] == 0
    # every injected body-frame is found, except a swap whose jump the sliding hides: at most a few
    assert 0.7 * sk["fault_frames_injected"] <= sk["faults_excluded"] <= sk["fault_frames_injected"] + 5, sk
