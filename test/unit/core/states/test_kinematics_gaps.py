"""Gaps that cost no data: occlusions and dropped frames leave h where the same ride without them puts it.

A 30 s ride of the independent generator (seed drawn at random from the tuning seeds by a fixed generator) is
written twice with the paper's pose noise: once whole, once with 6 occlusion gaps (one body blank for 2-20
frames) and 1 % dropped frames. The samples the Savitzky-Golay stretches leave out beside the gaps come from
least-squares fits through them (:func:`~euc_ros.core.filters.masked_savgol.masked_savgol`): h moves by at most
3 mm, and at least 90 % of the frames give states (the take's own first and last half-windows, 4 %, and the
missing frames are what is left out). Measured on seeds 1-4 at the 1.2 s window: 0.01-0.51 mm and 93 %,
against 73-77 % without the fits.
"""
# covers: euc_ros/core/filters/masked_savgol.py
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.identify.fit import fit_h
from euc_ros.core.io.recordings import load_recording
from euc_ros.core.model.terms import EucParams
from euc_ros.core.session import load_session
from euc_ros.core.states.kinematics import reconstruct_states
from euc_ros.core.worldsim import Capture, simulate_ride, write_ride

pytestmark = pytest.mark.slow

SEED = int(np.random.default_rng(4029).integers(0, 100))
NOISE = dict(noise_pos_mm=0.2, noise_rot_deg=0.5)


@pytest.fixture(scope="module")
def rides(tmp_path_factory):
    ride = simulate_ride(SEED, 120.0, duration=30.0)
    out = {}
    for tag, cap in (("whole", Capture(**NOISE)), ("gaps", Capture(**NOISE, occlusions=6, drop_rate=0.01))):
        paths = write_ride(ride, tmp_path_factory.mktemp(tag), cap, seed=SEED, name="r")
        session = load_session(paths["session"])
        series = load_recording(paths["csv"], session.world_up)
        states = reconstruct_states(series, session, window_s=1.2, polyorder=6)
        h = fit_h([states], EucParams.from_session(session), models=("3dof",)).pooled["3dof"].h_m
        out[tag] = (series, states, h)
    return ride, out


def test_gaps_move_h_by_at_most_3_mm_and_cost_only_their_frames(rides):
    ride, out = rides
    h_whole = out["whole"][2]
    series, gaps, h_gaps = out["gaps"]
    assert abs(h_gaps - h_whole) <= 3e-3, (h_whole, h_gaps)
    assert gaps.valid.sum() / ride.t.size >= 0.90
    # every recorded frame with its bodies, away from the take's own ends, gives a state but a few (a fit
    # whose variance the gaps inflate more than 4 times)
    half = gaps.window // 2
    inside = (series.frame - series.frame[0] >= half) & (series.frame[-1] - series.frame >= half)
    seen = inside & np.isfinite(gaps.phi_hinge)
    assert gaps.valid[seen].mean() >= 0.97, gaps.valid[seen].mean()
