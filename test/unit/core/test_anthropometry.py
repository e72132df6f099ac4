"""Rider segments from de Leva's table: the table's integrity, the whole body against measured values,
and the session bodies' offsets against the stacked standing body (two routes to one CoG)."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.anthropometry import (
    BODIES,
    SHOULDER_BELOW_C7,
    STATURE_M,
    TABLE,
    ankle_height,
    rider_segments,
    segment_lengths,
    standing_rider,
)
from euc_ros.core.errors import ConfigError
from euc_ros.core.session import MASS_FRACTION_TOL

PAIRED = ("upper_arm", "forearm", "hand", "thigh", "shank", "foot")


@pytest.mark.parametrize("sex", ["male", "female"])
def test_the_table_sums_to_the_whole_body(sex):
    t = TABLE[sex]
    total = t["head"].mass_pct + t["trunk"].mass_pct + 2 * sum(t[n].mass_pct for n in PAIRED)
    assert total == pytest.approx(100.0, abs=0.05)     # the published table's own rounding


@pytest.mark.parametrize("sex", ["male", "female"])
def test_the_bodies_take_the_whole_table_within_the_session_tolerance(sex):
    """The table's own fractions, mapped onto the 13 bodies without renormalising, sum to 1 within the
    session file's tolerance (docs/session.md), so the renormalisation only spreads the table's rounding."""
    t = TABLE[sex]
    raw = {"H": t["head"].mass_pct, "CHR": t["trunk"].mass_pct / 2, "CHL": t["trunk"].mass_pct / 2}
    for side in "RL":
        raw |= {f"UA{side}": t["upper_arm"].mass_pct, f"LA{side}": t["forearm"].mass_pct + t["hand"].mass_pct,
                f"H{side}": 0.0, f"T{side}": t["thigh"].mass_pct, f"L{side}": t["shank"].mass_pct + t["foot"].mass_pct}
    assert sorted(raw) == sorted(BODIES)
    assert abs(sum(raw.values()) / 100 - 1) <= MASS_FRACTION_TOL
    seg = rider_segments(70.0, 1.75, sex)
    assert sum(s.mass_fraction for s in seg.values()) == pytest.approx(1.0, abs=1e-12)
    for body, pct in raw.items():
        assert seg[body].mass_fraction == pytest.approx(pct / 100, abs=MASS_FRACTION_TOL / 13)


@pytest.mark.parametrize("sex, mass, height", [("male", 65, 1.70), ("male", 95, 1.92), ("female", 55, 1.60)])
def test_whole_body_cog_height_is_where_bodies_have_it(sex, mass, height):
    # measured standing CoM heights of adults: 0.54-0.58 of the stature (Dempster; Winter, Biomechanics and
    # Motor Control of Human Movement, Table 4.1 gives 0.55-0.57)
    r = standing_rider(mass, height, sex)
    assert 0.54 <= r.cog_height / height <= 0.58
    # radius of gyration of the whole standing body in pitch: 0.2-0.28 of the stature for adults
    k = np.sqrt(r.inertia_pitch / mass) / height
    assert 0.2 <= k <= 0.28, k


@pytest.mark.parametrize("sex", ["male", "female"])
def test_session_bodies_put_the_cog_where_the_stacked_body_has_it(sex):
    mass, height = 70.0, 1.75
    seg = rider_segments(mass, height, sex, helmet_m=0.03)
    L, k = segment_lengths(height, sex), height / STATURE_M[sex]
    ankle = ankle_height(L, height)
    knee, hip = ankle + L["shank"], ankle + L["shank"] + L["thigh"]
    c7 = hip + L["trunk"]
    shoulder = c7 - SHOULDER_BELOW_C7 * k
    elbow = shoulder - L["upper_arm"]
    wrist = elbow - L["forearm"]
    # every pivot of the standing rider (body frames = world frame), then pivot + offset, mass-weighted
    pivots = {"H": height + 0.03, "CHR": shoulder, "CHL": shoulder, "UAR": elbow, "UAL": elbow, "LAR": wrist,
              "LAL": wrist, "HR": hip, "HL": hip, "TR": knee, "TL": knee, "LR": ankle, "LL": ankle}
    f = np.array([seg[b].mass_fraction for b in pivots])
    z = np.array([pivots[b] + seg[b].com_offset[2] for b in pivots])
    assert f.sum() == pytest.approx(1.0, abs=1e-12)
    # offsets are rounded to 0.1 mm in the file
    assert float(f @ z) == pytest.approx(standing_rider(mass, height, sex).cog_height, abs=1e-4)


def test_chest_halves_lean_towards_the_midline_and_limbs_are_symmetric():
    seg = rider_segments(70.0, 1.75, "male")
    assert seg["CHR"].com_offset[1] > 0 > seg["CHL"].com_offset[1]      # y left: the right half's CoM is left of it
    for r, left in (("UAR", "UAL"), ("LAR", "LAL"), ("TR", "TL"), ("LR", "LL")):
        assert seg[r] == seg[left]
    assert seg["HR"].mass_fraction == seg["HL"].mass_fraction == 0.0
    assert seg["LAR"].mass_fraction == pytest.approx((1.62 + 0.61) / 100, abs=1e-4)   # the hand is included


@pytest.mark.parametrize("kw, key, words", [
    (dict(mass=70, height=175, sex="male"), "height", "centimetres"),
    (dict(mass=7000, height=1.75, sex="male"), "mass", "not plausible"),
    (dict(mass=70, height=1.75, sex="x"), "sex", "male or female"),
])
def test_implausible_measures_name_the_key(kw, key, words):
    with pytest.raises(ConfigError, match=words) as err:
        rider_segments(**kw)
    assert err.value.key == key
