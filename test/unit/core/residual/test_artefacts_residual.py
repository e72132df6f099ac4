"""The residual analysis on recordings with soft-tissue
sliding, wrong session CoM offsets and coloured pose noise, and no physical effect.

The artefacts come from :mod:`euc_ros.core.ridesim.artefacts`, a generator that shares no code with
the analysis (band-limited sliding of every rider body, partly following the segment's acceleration;
CoM offsets moved 1-3 cm; first-order low-pass pose noise). Artefacts are not a physical effect: no
library effect may be named and no discovered term reported. The noise floor holds the sliding the rigid
links measure, so sliding alone is at the floor: ``none``. Coloured pose noise (orientation noise too, which
the links fold into their bodies' pivots) is partly outside it: ``none`` or ``unexplained``, never a name.
"""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.model.effects import LIBRARY
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.analysis import analyze
from euc_ros.core.residual.noise import make_noise_floor
from euc_ros.core.ridesim.artefacts import SoftTissueArtefacts, apply_artefacts, perturb_session
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.kinematics import reconstruct_states
from euc_ros.core.states.link_sliding import estimate_sliding

pytestmark = pytest.mark.slow


def run(artefacts: SoftTissueArtefacts, offsets=None, seed=11):
    rng = np.random.default_rng(seed)
    states, series, analysed = [], [], None
    for i, (maneuver, runs) in enumerate((("acceleration", 3), ("deceleration", 3))):
        res = simulate_ride(RideConfig(maneuver=maneuver, runs=runs, seed=seed + 101 * i))
        analysed = perturb_session(res.session, np.random.default_rng(seed + 7), offset_error_m=offsets) \
            if offsets else res.session
        for r in res.runs:
            rec, _ = apply_artefacts(r.mocap_clean, artefacts, rng)
            series.append(rec)
            states.append(reconstruct_states(rec, analysed))
    params = EucParams.from_session(analysed)
    floor = make_noise_floor(series, states, analysed, params, sliding=estimate_sliding(series, analysed))
    return analyze(states, params, noise_floor_of=floor).to_json()


@pytest.mark.parametrize("name, artefacts, offsets, verdicts", [
    ("sliding 3 mm + CoM offsets 2 cm off", SoftTissueArtefacts(slide_rms_m=0.003, slide_rot_rms_deg=1.0), (0.02, 0.02),
     ("none",)),
    ("coloured pose noise (1 Hz corner)", SoftTissueArtefacts(slide_rms_m=0.0, slide_rot_rms_deg=0.0,
                                                             noise_corner_hz=1.0), None, ("none", "unexplained")),
])
def test_artefacts_alone_name_no_effect(name, artefacts, offsets, verdicts):
    out = run(artefacts, offsets)
    named = [n for n in out["effect"].split("+") if n in LIBRARY]
    assert named == [], (name, out["effect"], out["selection_steps"][-1])
    assert not out["discovered"], (name, out["discovered"])
    assert out["effect"] in verdicts, (out["effect"], out["rmse_after_nm"], out["noise_floor_nm"])
    # reported honestly: either at the noise floor, or significant and unexplained
    assert out["unexplained"] == (out["effect"] == "unexplained")
    assert out["residual_significant"] or out["effect"] == "none"
