"""The range of h the rider's recorded body allows: a hand-built rider, and the independent generator's riders.

The generator (:mod:`euc_ros.core.worldsim`) has conventions of its own (hip bodies with mass, its own segment
lengths and CoM offsets); its riders' true h must lie inside the range taken from their recorded joints alone.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.io.recordings import load_recording
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.session import load_session
from euc_ros.core.states.admissible import FOOT_COM_M, HAND_COM_M, SEGMENT_ENDS, admissible_h
from euc_ros.core.worldsim.simulate import simulate_ride
from euc_ros.core.worldsim.writers import Capture, write_ride

#: Seeds drawn once from the tuning range (0-99) by a fixed generator (not picked).
SEEDS = [int(s) for s in np.random.default_rng(404).choice(100, 3, replace=False)]


def _standing(session, heights: dict, n: int = 5) -> MocapSeries:
    """A rider standing upright on an upright EUC: every body at ``heights[b]`` above the hinge A, at x = y = 0."""
    bodies = [session.euc.body] + list(heights)
    c = np.asarray(session.euc.pivot_to_wheel_center, float)
    E = -c + np.array([0.0, 0.0, session.euc.l0])            # C = E + c, A = C + l0 z = origin
    pos = np.stack([np.tile(E, (n, 1))] + [np.tile([0.0, 0.0, z], (n, 1)) for z in heights.values()])
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(bodies), n, 1))
    return MocapSeries(t=np.arange(n) / 100.0, frame=np.arange(n), bodies=bodies, position=pos, quat=quat,
                       tracked=np.ones((len(bodies), n), bool), mean_marker_error=np.full((len(bodies), n), np.nan))


def test_a_standing_rider_by_hand():
    from euc_ros.core.session import default_session

    session = default_session()
    heights = {"H": 1.70, "CHR": 1.40, "CHL": 1.40, "UAR": 1.10, "UAL": 1.10, "LAR": 0.85, "LAL": 0.85,
               "HR": 0.85, "HL": 0.85, "TR": 0.45, "TL": 0.45, "LR": 0.0, "LL": 0.0}
    adm = admissible_h([_standing(session, heights)], session, fraction_tolerance=0.0)
    f = {b: s.mass_fraction for b, s in session.rider.segments.items()}
    # by hand: each segment from its lower to its upper joint (all on the vertical through A)
    ends = {"H": (1.40, 1.70), "CHR": (0.85, 1.70), "CHL": (0.85, 1.70), "UAR": (1.10, 1.40), "UAL": (1.10, 1.40),
            "LAR": (0.85 - HAND_COM_M, 1.10), "LAL": (0.85 - HAND_COM_M, 1.10), "HR": (0.85, 1.40),
            "HL": (0.85, 1.40), "TR": (0.45, 0.85), "TL": (0.45, 0.85), "LR": (-FOOT_COM_M, 0.45),
            "LL": (-FOOT_COM_M, 0.45)}
    lo = sum(f[b] * ends[b][0] for b in f)
    hi = sum(f[b] * ends[b][1] for b in f)
    assert adm.low_m == pytest.approx(lo, abs=1e-12) and adm.high_m == pytest.approx(hi, abs=1e-12)
    # the rider's real CoG, wherever on its segments the CoM lie, is inside
    assert adm.low_m < sum(f[b] * np.mean(ends[b]) for b in f) < adm.high_m
    # moving mass between the legs and the upper body widens the range
    wider = admissible_h([_standing(session, heights)], session, fraction_tolerance=0.02)
    assert wider.low_m < adm.low_m and wider.high_m > adm.high_m


def test_nothing_without_the_bodies_it_needs():
    from euc_ros.core.session import default_session

    session = default_session()
    heights = {b: 1.0 for b in SEGMENT_ENDS if b != "TL"}
    assert admissible_h([_standing(session, heights)], session) is None


@pytest.mark.slow
@pytest.mark.parametrize("seed", SEEDS)
def test_the_generators_true_h_is_inside(seed, tmp_path):
    ride = simulate_ride(seed, 120.0, duration=4.0)
    paths = write_ride(ride, tmp_path, Capture(), seed=seed)
    session = load_session(paths["session"])
    adm = admissible_h([load_recording(paths["csv"], session.world_up)], session)
    h = float(ride.spec.plant.h)
    assert adm is not None and adm.low_m < h < adm.high_m, (adm, h)
    # informative: well inside the default search range 0.1-1.2 m's width (measured 0.55-0.69 m on 6 rides)
    assert adm.high_m - adm.low_m < 0.8
