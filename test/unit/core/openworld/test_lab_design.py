"""The lab design of a study ride: its draws, and what it writes (a lab's session, its artefact model)."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.errors import ConfigError
from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.core.openworld import lab_design as ld
from euc_ros.core.openworld import study as st
from euc_ros.core.session import load_session


def test_the_draws_are_a_function_of_the_ride_and_cover_every_model():
    draws = [ld.draw_design("lab", s, 0, st.STREAM) for s in range(60)]
    assert draws == [ld.draw_design("lab", s, 0, st.STREAM) for s in range(60)]
    # each of 3 models misses 60 draws with chance (2/3)^60 ~ 3e-11
    assert {d.model for d in draws} == set(ld.MODELS)
    for d in draws:
        assert d.perturbed and d.band_sliding == (d.model != "joint")
        assert (d.joint_scale == 0) == (d.model == "acceleration")
        assert d.joint_scale == 0 or ld.JOINT_SCALE[0] <= d.joint_scale <= ld.JOINT_SCALE[1]
        assert d.accel_share == (1.0 if d.model == "acceleration" else 0.5)
    classic = ld.draw_design("classic", 3, 0, st.STREAM)
    assert (classic.model, classic.perturbed, classic.joint_scale, classic.accel_share) == ("classic", False, 0.0, 0.5)
    with pytest.raises(ConfigError, match="--design"):
        ld.draw_design("field", 3, 0, st.STREAM)


def test_a_lab_ride_is_analysed_with_a_lab_session_and_recorded_with_its_model(tmp_path):
    """The same seed in both designs: the classic ride's session is the generator's, the lab ride's a perturbed
    copy of it (CoM offsets 1-2 cm off, fractions summing alike, masses within 0.5 kg); the ride's own draws
    (its sliding level) are the classic one's."""
    seed = next(s for s in range(100) if ld.draw_design("lab", s, 0, st.STREAM).model == "joint")
    classic = st.make_ride(seed, "none", tmp_path / "c", duration=2.0, runs=1)
    lab = st.make_ride(seed, "none", tmp_path / "l", duration=2.0, runs=1, design="lab")
    assert classic["session"] == classic["session_true"] and lab["session"] != lab["session_true"]
    assert classic["artefact_mm"] == lab["artefact_mm"]
    truth, est = load_session(lab["session_true"]), load_session(lab["session"])
    _, f0, o0 = truth.segment_arrays()
    _, f1, o1 = est.segment_arrays()
    moved = np.linalg.norm(o1 - o0, axis=1)
    assert np.all((moved >= ld.OFFSET_ERROR_M[0] - 1e-9) & (moved <= ld.OFFSET_ERROR_M[1] + 1e-9))
    assert f1.sum() == pytest.approx(f0.sum()) and not np.allclose(f1, f0)
    assert abs(est.rider.mass - truth.rider.mass) <= ld.MASS_ERROR_KG
    # the joint model has no band-limited sliding: its recording differs from the classic one's
    a, b = read_motive_csv(classic["csv"], world_up="y"), read_motive_csv(lab["csv"], world_up="y")
    assert a.bodies == b.bodies and not np.allclose(a.position, b.position)
    assert lab["design"].describe() == {"artefact_model": "joint", "joint_scale": lab["design"].joint_scale,
                                        "session": "perturbed"}
