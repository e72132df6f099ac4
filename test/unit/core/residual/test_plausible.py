"""A library effect is named only with plausible parameters, and near-confounded effects are ties.

Simulated rides (:mod:`euc_ros.core.ridesim`, which shares no model code with the analysis) of three runs:

* a quadratic drag at the tyre contact, ``-3 x_dot |x_dot|`` N: the library's aero_drag fits it only with a
  drag area the residual's lever arms fix (below), well above a rider's: refused, the discovered terms or
  ``unexplained`` instead; with the plausible range widened by the caller it is named again;
* a genuine aero_drag of 0.5 m^2: still named;
* a rider pitch-inertia error of 8 kg m^2: a tie with rider_mass_error, each with its h;
* no effect: nothing named, nothing refused, no tie.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from euc_ros.cli.residual_report import verdict_lines
from euc_ros.core.errors import ConfigError
from euc_ros.core.model.candidate import PLAUSIBLE_SOURCES
from euc_ros.core.model.effects import (
    AIR_DENSITY,
    LIBRARY,
    AeroDrag,
    TimeVaryingH,
    make_candidates,
    parse_plausible,
)
from euc_ros.core.model.terms import EucParams
from euc_ros.core.residual.analysis import analyze
from euc_ros.core.ridesim.effects import make_effects
from euc_ros.core.ridesim.external import ExternalForce
from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
from euc_ros.core.states.kinematics import reconstruct_states

#: True rider CoG height of the simulated rides [m].
H_TRUE = 0.61
#: Two accelerations and a deceleration of 7 s.
MANEUVERS = (("acceleration", 2), ("deceleration", 1))
DRAG_NAMES = ["aero_drag", "viscous_friction", "rolling_resistance"]
C_CONTACT = 3.0


def ride(effects=None, external=(), seed=11):
    effects = effects or {}
    eff = make_effects(list(effects), {k: v for p in effects.values() for k, v in p.items()})
    states, session = [], None
    for i, (maneuver, runs) in enumerate(MANEUVERS):
        res = simulate_ride(RideConfig(maneuver=maneuver, runs=runs, seed=seed + 101 * i, effects=eff,
                                       external=external))
        session = res.session
        for r in res.runs:
            st = reconstruct_states(r.mocap, session)
            st.meta.update(series=r.mocap, session=session)   # the poses, for refits with other filters
            states.append(st)
    return states, EucParams.from_session(session)


def named(out):
    return [n for n in out["effect"].split("+") if n in LIBRARY]


@pytest.fixture(scope="module")
def contact_drag_ride():
    return ride(external=(ExternalForce("contact_drag", {"c_n_s2_per_m2": C_CONTACT}),))


def test_quadratic_drag_at_the_contact_is_not_named_aero_drag(contact_drag_ride):
    states, params = contact_drag_ride
    out = analyze(states, params, candidates=make_candidates(DRAG_NAMES)).to_json()
    assert "aero_drag" not in named(out), out["effect"]
    assert out["residual_significant"]
    assert out["discovered"] or out["unexplained"], out["effect"]
    refused = [r for r in out["refused"] if r["effect"] == "aero_drag"]
    assert refused and refused[0]["parameter"] == "cda_m2"
    assert refused[0]["value"] > AeroDrag.params[0].plausible[1]
    assert any(w.startswith("refused aero_drag: cda_m2=") for w in out["analysis_warnings"])
    lines = verdict_lines(out)
    assert len(lines) == len(out["refused"]) + len(out["ties"])
    assert [ln for ln in lines if ln.startswith("refused aero_drag: cda_m2=")], lines
    # the residual sees a horizontal force at height z above the contact through w = [R, 1, 1]: R F at the
    # contact, (R - l0 + h) F at the rider's CoG (upright rider); the drag area that gives the contact's
    # moment is then 2 c R / (rho (R - l0 + h)); 10 %: the rider's own pitching speed in |v_G| v_G
    cda = 2 * C_CONTACT * params.R / (AIR_DENSITY * (params.R - params.l0 + H_TRUE))
    assert refused[0]["value"] == pytest.approx(cda, rel=0.1)


def test_a_wider_plausible_range_names_it_again(contact_drag_ride):
    """The caller's range replaces the library's: the same fit is then named (the range is the only gate)."""
    states, params = contact_drag_ride
    out = analyze(states, params, candidates=make_candidates(["aero_drag"]), discovery=False,
                  plausible={"aero_drag.cda_m2": (0.2, 2.0)}).to_json()
    assert out["effect"] == "aero_drag" and not out["refused"]
    assert out["effect_parameters"]["cda_m2"] > 1.0


def test_a_plausible_aero_drag_is_still_named():
    states, params = ride({"aero_drag": {"cda_m2": 0.5}})
    out = analyze(states, params, candidates=make_candidates(DRAG_NAMES)).to_json()
    assert named(out) == ["aero_drag"] and not out["refused"], (out["effect"], out["refused"])
    assert out["effect_parameters"]["cda_m2"] == pytest.approx(0.5, rel=0.25)


def test_a_rider_inertia_error_ties_with_a_mass_error_with_the_h_of_each():
    states, params = ride({"rider_inertia_error": {"delta_j_kgm2": 8.0}})
    out = analyze(states, params, candidates=make_candidates(["rider_mass_error", "rider_inertia_error"])).to_json()
    assert out["effect"] in ("rider_mass_error", "rider_inertia_error") and out["effect_is_tie"]
    # the two named ones tie, each with its h (a discovered alternative may tie with them too: on these runs of one
    # manoeuvre the time since the start stands in for the speed, and a shared drift of a vertical force with a
    # speed term holds out as well)
    both = {"rider_mass_error", "rider_inertia_error"}
    tie = next(t for t in out["ties"] if both <= set(t["effects"]))
    tried = {t["effect"]: t["h_m"] for t in out["selection_steps"][0]["tried"]}
    assert {e: h for e, h in zip(tie["effects"], tie["h_m"]) if e in both} == pytest.approx(tried)
    # the h range spans the tie (the two h differ: a mass error moves h, an inertia error does not)
    lo, hi = out["h_range_m"]
    assert lo == pytest.approx(min(tie["h_m"])) and hi == pytest.approx(max(tie["h_m"]))
    assert lo <= min(tried.values()) and hi >= max(tried.values())
    assert abs(tried["rider_inertia_error"] - H_TRUE) < 0.010 and hi - lo > 0.03
    # the final model's interval holds the h of every tied explanation
    ci = out["h_after_ci95_m"]
    assert ci[0] < min(tie["h_m"]) and ci[1] > max(tie["h_m"]), (ci, tie["h_m"])
    assert both - {out["effect"]} <= set(out["ambiguous_with"])
    (line,) = verdict_lines(out)
    assert line.startswith("tie: ") and "rider_mass_error (h " in line and "rider_inertia_error (h " in line


def test_no_effect_names_nothing_refuses_nothing_and_ties_nothing():
    states, params = ride(seed=23)
    out = analyze(states, params, candidates=make_candidates(["aero_drag", "rider_mass_error",
                                                              "rider_inertia_error"])).to_json()
    assert out["effect"] == "none" and not out["refused"] and not out["ties"] and not out["effect_is_tie"]


def test_every_library_parameter_has_a_plausible_range_with_a_source_inside_its_bounds():
    for cls in LIBRARY.values():
        for q in cls().checked:
            assert q.plausible is not None, (cls.name, q.name)
            assert q.low <= q.plausible[0] <= q.plausible[1] <= q.high, (cls.name, q.name)
            assert PLAUSIBLE_SOURCES.get(f"{cls.name}.{q.name}"), (cls.name, q.name)


def test_plausible_overrides_are_checked():
    assert parse_plausible(["aero_drag.cda_m2=0.1:1.5"]) == {"aero_drag.cda_m2": (0.1, 1.5)}
    for bad in ("aero_drag.cda_m2=0.1", "aero_drag=0.1:1", "aero_drag.cda_m2=a:b"):
        with pytest.raises(ConfigError):
            parse_plausible([bad])
    for bad in ({"aero_drag.cd": (0.1, 1.0)}, {"drag.cda_m2": (0.1, 1.0)}, {"aero_drag.cda_m2": (1.0, 0.1)}):
        with pytest.raises(ConfigError):
            make_candidates(["aero_drag"], bad)
    (c,) = make_candidates(["time_varying_h"], {"time_varying_h.amplitude_m": (0.0, 0.3)})
    # a_sin, a_cos of amplitude 0.25 m: inside the override, outside the library's 0.2 m
    theta = [0.15, 0.2, 4.0]
    assert c.implausible(theta) == []
    (records,) = [TimeVaryingH().implausible(theta)]
    assert [r["parameter"] for r in records] == ["amplitude_m"] and records[0]["value"] == pytest.approx(0.25)


def test_the_docs_table_gives_the_librarys_plausible_ranges():
    text = (Path(__file__).resolve().parents[4] / "docs" / "effects.md").read_text()
    rows = {(m[0], m[1]): (float(m[2]), float(m[3]))
            for m in re.findall(r"^\| `(\w+)` \| `(\w+)` \|[^|]*\|[^|]*\| \*\*(\S+) to (\S+)\*\* \|", text, re.M)}
    expected = {(cls.name, q.name): q.plausible for cls in LIBRARY.values() for q in cls().checked}
    assert rows == expected
