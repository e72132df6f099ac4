"""The one anthropometric table of euc_ros: rider segment parameters from body mass, height and sex.

Everything that needs the rider's segments takes them from here: ``euc-ros session init``
(:mod:`euc_ros.core.model.session_template`) and the default session of
:func:`euc_ros.core.session.default_session`, which is the ride simulator's default rider. The module is
data and the geometry of stacking the table's segments; it holds no model code, so the analysis and the
simulator (independent of the analysis by design) may both read it.

The session file describes the rider by rigid bodies at the pivots of the recording contract (top of
helmet, shoulder, elbow, wrist, hip, knee, ankle): for each, a mass fraction of the rider mass and the
offset of its centre of mass from the pivot in the body frame (x forward, y left, z up when standing).
This module computes them, and the rider's pitch inertia about the CoG, from the segment table of

    P. de Leva (1996), "Adjustments to Zatsiorsky-Seluyanov's segment inertia parameters",
    Journal of Biomechanics 29(9), 1223-1230, Table 4 (segment mass, CoM position and radii of
    gyration of young adult males and females, with the mean segment lengths).

How the table is mapped onto the rigid bodies:

* lengths are the table's mean lengths scaled by ``height / stature`` of the table's sample;
* ``H`` is the head and neck (vertex to C7); its pivot is the top of the helmet, ``helmet_m`` above
  the vertex;
* ``CHR``/``CHL`` each carry half the trunk (C7 to mid-hip); the pivot is the shoulder joint,
  taken :data:`SHOULDER_BELOW_C7` (scaled) below C7, the half-trunk CoM
  :data:`CHEST_HALF_MEDIAL` (scaled) towards the midline from it;
* ``UAR``/``UAL`` the upper arm (pivot: elbow); ``LAR``/``LAL`` the forearm **and the hand** (pivot:
  wrist), their CoM the mass-weighted mean of the two;
* ``HR``/``HL`` are the hip bodies: their mass is in the trunk and thighs of the table, so their
  fraction is 0 (they are tracked for the skeleton and the up-axis checks);
* ``TR``/``TL`` the thigh (pivot: knee); ``LR``/``LL`` the shank **and the foot** (pivot: ankle),
  the foot's CoM from the heel, :data:`HEEL_TO_ANKLE` of the foot length behind the ankle, and half
  the ankle height below the ankle.

The segments stand on each other (ankle, knee, hip, C7, vertex) with the ankle where the scaled lengths
put the vertex at the given height (about 4 cm above the floor for the table's males, 8 cm for its
females).

The pitch inertia is that of the standing rider (arms hanging) about its CoG, from each segment's
transverse radius of gyration and the parallel-axis terms. A rider crouched on an EUC has a smaller
one; the value is a starting point, like every nominal value of a session.

Examples
--------
>>> seg = rider_segments(70.0, 1.75, "male")
>>> round(sum(s.mass_fraction for s in seg.values()), 6)
1.0
>>> sorted(seg)[:3]
['CHL', 'CHR', 'H']
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from euc_ros.core.errors import ConfigError

REFERENCE = ("P. de Leva (1996), Adjustments to Zatsiorsky-Seluyanov's segment inertia parameters, "
             "J. Biomech. 29(9):1223-1230, Table 4")

#: Mean stature of the table's samples [m].
STATURE_M = {"male": 1.741, "female": 1.735}


@dataclass(frozen=True)
class TableSegment:
    """One row of the segment table.

    Parameters
    ----------
    mass_pct : float
        Segment mass, % of body mass.
    com_pct : float
        CoM from the proximal (first named) end point, % of the segment length.
    r_transverse_pct : float
        Radius of gyration about the transverse (medio-lateral, pitch) axis, % of the length.
    length_mm : float
        Mean segment length [mm].
    """

    mass_pct: float
    com_pct: float
    r_transverse_pct: float
    length_mm: float


#: de Leva (1996) Table 4, per sex: segment -> (mass %, CoM % from the first end point, transverse radius
#: of gyration %, mean length mm). End points: head VERT->CERV, trunk CERV->MIDH, upper arm SJC->EJC,
#: forearm EJC->WJC, hand WJC->MET3, thigh HJC->KJC, shank KJC->LMAL, foot HEEL->TTIP.
TABLE: dict[str, dict[str, TableSegment]] = {
    "male": {
        "head": TableSegment(6.94, 59.76, 37.6, 242.9),
        "trunk": TableSegment(43.46, 44.86, 34.7, 603.3),
        "upper_arm": TableSegment(2.71, 57.72, 26.9, 281.7),
        "forearm": TableSegment(1.62, 45.74, 26.5, 268.9),
        "hand": TableSegment(0.61, 79.00, 51.3, 86.2),
        "thigh": TableSegment(14.16, 40.95, 32.9, 422.2),
        "shank": TableSegment(4.33, 44.59, 24.9, 434.0),
        "foot": TableSegment(1.37, 44.15, 24.5, 258.1),
    },
    "female": {
        "head": TableSegment(6.68, 58.94, 35.9, 243.7),
        "trunk": TableSegment(42.57, 41.51, 33.9, 614.8),
        "upper_arm": TableSegment(2.55, 57.54, 26.0, 275.1),
        "forearm": TableSegment(1.38, 45.59, 25.7, 264.3),
        "hand": TableSegment(0.56, 74.74, 45.4, 78.0),
        "thigh": TableSegment(14.78, 36.12, 36.4, 368.5),
        "shank": TableSegment(4.81, 44.16, 26.7, 432.3),
        "foot": TableSegment(1.29, 40.14, 27.9, 228.3),
    },
}

#: Shoulder joint centre below C7, for the table's stature [m] (scaled with height).
SHOULDER_BELOW_C7 = 0.075
#: Half-trunk CoM towards the midline from the shoulder joint, for the table's stature [m] (scaled).
CHEST_HALF_MEDIAL = 0.10
#: Heel behind the ankle, fraction of the foot length.
HEEL_TO_ANKLE = 0.22

#: The rider's rigid bodies of the recording contract, with what each carries.
BODIES = {
    "H": "head and neck; pivot: top of the helmet",
    "CHR": "right half of the trunk; pivot: right shoulder",
    "CHL": "left half of the trunk; pivot: left shoulder",
    "UAR": "right upper arm; pivot: right elbow",
    "UAL": "left upper arm; pivot: left elbow",
    "LAR": "right forearm and hand; pivot: right wrist",
    "LAL": "left forearm and hand; pivot: left wrist",
    "HR": "right hip (no mass: it is in the trunk and thigh); pivot: right hip",
    "HL": "left hip (no mass: it is in the trunk and thigh); pivot: left hip",
    "TR": "right thigh; pivot: right knee",
    "TL": "left thigh; pivot: left knee",
    "LR": "right shank and foot; pivot: right ankle",
    "LL": "left shank and foot; pivot: left ankle",
}


@dataclass(frozen=True)
class BodySegment:
    """Mass fraction of the rider and CoM offset from the pivot in the body frame [m].

    Parameters
    ----------
    mass_fraction : float
        Fraction of the rider's mass in this segment.
    com_offset : tuple of float
        The segment's CoM offset from its pivot, body frame (x, y, z) [m].
    """

    mass_fraction: float
    com_offset: tuple[float, float, float]


def _check(mass: float, height: float, sex: str) -> str:
    sex = str(sex).lower()
    if sex in ("m", "f"):
        sex = {"m": "male", "f": "female"}[sex]
    if sex not in TABLE:
        raise ConfigError(f"sex must be male or female (the table's two samples), got {sex!r}", key="sex")
    if not 20.0 <= mass <= 250.0:
        raise ConfigError(f"body mass {mass:g} kg is not plausible (20-250 kg)", key="mass")
    if not 1.0 <= height <= 2.3:
        hint = "; the value looks like centimetres" if 100.0 <= height <= 230.0 else ""
        raise ConfigError(f"height {height:g} m is not plausible (1.0-2.3 m){hint}", key="height")
    return sex


def segment_lengths(height: float, sex: str) -> dict[str, float]:
    """The table's mean segment lengths scaled to ``height`` [m], by table segment name.

    Parameters
    ----------
    height : float
        Rider's standing height [m].
    sex : str
        ``"male"`` or ``"female"`` (the table's columns).

    Returns
    -------
    dict of str to float
        Segment length [m] by table segment name.
    """
    k = height / STATURE_M[sex]
    return {name: row.length_mm * 1e-3 * k for name, row in TABLE[sex].items()}


def ankle_height(L: dict[str, float], height: float) -> float:
    """Ankle height that puts the vertex at ``height`` on the stacked segments [m].

    Parameters
    ----------
    L : dict of str to float
        Segment lengths [m] by table segment name (:func:`segment_lengths`).
    height : float
        Rider's standing height [m].

    Returns
    -------
    float
        Ankle height above the floor [m].
    """
    return height - (L["shank"] + L["thigh"] + L["trunk"] + L["head"])


def rider_segments(mass: float, height: float, sex: str, *, helmet_m: float = 0.0) -> dict[str, BodySegment]:
    """Mass fractions and CoM offsets of the 13 rider bodies.

    Parameters
    ----------
    mass : float
        Body mass [kg] (the fractions do not depend on it; it is checked for plausibility).
    height : float
        Standing height [m].
    sex : {"male", "female"}
    helmet_m : float
        Height of the helmet's top above the vertex [m] (the head body's pivot is on the helmet).

    Returns
    -------
    dict
        Body name -> :class:`BodySegment`, in the order of :data:`BODIES`.
    """
    sex = _check(mass, height, sex)
    t, L, k = TABLE[sex], segment_lengths(height, sex), height / STATURE_M[sex]
    frac = {n: row.mass_pct / 100.0 for n, row in t.items()}
    total = frac["head"] + frac["trunk"] + 2 * sum(frac[n] for n in ("upper_arm", "forearm", "hand", "thigh",
                                                                       "shank", "foot"))
    frac = {n: f / total for n, f in frac.items()}       # the table sums to 100 % within its rounding

    def c(n):   # CoM from the proximal end [m]
        return t[n].com_pct / 100.0 * L[n]

    head_z = -(helmet_m + c("head"))
    chest_z = -(c("trunk") - SHOULDER_BELOW_C7 * k)
    medial = CHEST_HALF_MEDIAL * k
    upper_arm_z = L["upper_arm"] - c("upper_arm")                  # above the elbow
    fa, hd = frac["forearm"], frac["hand"]
    lower_arm_z = (fa * (L["forearm"] - c("forearm")) - hd * c("hand")) / (fa + hd)
    thigh_z = L["thigh"] - c("thigh")
    sh, ft = frac["shank"], frac["foot"]
    foot_x = c("foot") - HEEL_TO_ANKLE * L["foot"]
    foot_z = -0.5 * ankle_height(L, height)
    leg = (ft * foot_x / (sh + ft), 0.0, (sh * (L["shank"] - c("shank")) + ft * foot_z) / (sh + ft))
    out = {
        "H": BodySegment(frac["head"], (0.0, 0.0, head_z)),
        "CHR": BodySegment(frac["trunk"] / 2, (0.0, medial, chest_z)),
        "CHL": BodySegment(frac["trunk"] / 2, (0.0, -medial, chest_z)),
        "UAR": BodySegment(frac["upper_arm"], (0.0, 0.0, upper_arm_z)),
        "UAL": BodySegment(frac["upper_arm"], (0.0, 0.0, upper_arm_z)),
        "LAR": BodySegment(fa + hd, (0.0, 0.0, lower_arm_z)),
        "LAL": BodySegment(fa + hd, (0.0, 0.0, lower_arm_z)),
        "HR": BodySegment(0.0, (0.0, 0.0, 0.0)),
        "HL": BodySegment(0.0, (0.0, 0.0, 0.0)),
        "TR": BodySegment(frac["thigh"], (0.0, 0.0, thigh_z)),
        "TL": BodySegment(frac["thigh"], (0.0, 0.0, thigh_z)),
        "LR": BodySegment(sh + ft, leg),
        "LL": BodySegment(sh + ft, leg),
    }
    return {n: BodySegment(s.mass_fraction, tuple(float(round(v, 4)) for v in s.com_offset))
            for n, s in out.items()}


@dataclass(frozen=True)
class StandingRider:
    """Whole-body values of the standing rider (arms hanging).

    Parameters
    ----------
    inertia_pitch : float
        Pitch moment of inertia about the CoG [kg m^2].
    cog_height : float
        CoG height above the floor [m].
    cog_above_ankle : float
        CoG height above the ankle joints [m] (the model's h for an upright rider; crouched lower).
    """

    inertia_pitch: float
    cog_height: float
    cog_above_ankle: float


def standing_rider(mass: float, height: float, sex: str) -> StandingRider:
    """Pitch inertia and CoG height of the rider standing upright, arms hanging (see the module notes).

    Parameters
    ----------
    mass : float
        Rider's mass [kg].
    height : float
        Rider's standing height [m].
    sex : str
        ``"male"`` or ``"female"`` (or ``"m"``, ``"f"``; any case).

    Returns
    -------
    StandingRider
        Pitch inertia about the CoG and CoG heights.

    Raises
    ------
    ConfigError
        When the mass, height or sex is outside what the table covers.
    """
    sex = _check(mass, height, sex)
    t, L, k = TABLE[sex], segment_lengths(height, sex), height / STATURE_M[sex]
    ankle = ankle_height(L, height)
    knee = ankle + L["shank"]
    hip = knee + L["thigh"]
    c7 = hip + L["trunk"]
    shoulder = c7 - SHOULDER_BELOW_C7 * k
    elbow = shoulder - L["upper_arm"]
    wrist = elbow - L["forearm"]
    # (name, count, CoM x, CoM z): segments hang from their proximal end point, the head stands on C7
    rows = [("head", 1, 0.0, c7 + (1 - t["head"].com_pct / 100) * L["head"]),
            ("trunk", 1, 0.0, c7 - t["trunk"].com_pct / 100 * L["trunk"]),
            ("upper_arm", 2, 0.0, shoulder - t["upper_arm"].com_pct / 100 * L["upper_arm"]),
            ("forearm", 2, 0.0, elbow - t["forearm"].com_pct / 100 * L["forearm"]),
            ("hand", 2, 0.0, wrist - t["hand"].com_pct / 100 * L["hand"]),
            ("thigh", 2, 0.0, hip - t["thigh"].com_pct / 100 * L["thigh"]),
            ("shank", 2, 0.0, knee - t["shank"].com_pct / 100 * L["shank"]),
            ("foot", 2, (t["foot"].com_pct / 100 - HEEL_TO_ANKLE) * L["foot"], 0.5 * ankle)]
    m = np.array([t[n].mass_pct / 100 * cnt for n, cnt, _, _ in rows])
    m = m / m.sum() * mass
    x = np.array([r[2] for r in rows])
    z = np.array([r[3] for r in rows])
    own = np.array([cnt * (t[n].mass_pct / 100) * (t[n].r_transverse_pct / 100 * L[n]) ** 2 for n, cnt, _, _ in rows])
    own = own / sum(t[n].mass_pct / 100 * cnt for n, cnt, _, _ in rows) * mass
    xg, zg = float(m @ x / mass), float(m @ z / mass)
    inertia = float(own.sum() + m @ ((x - xg) ** 2 + (z - zg) ** 2))
    return StandingRider(inertia_pitch=inertia, cog_height=zg, cog_above_ankle=zg - ankle)
