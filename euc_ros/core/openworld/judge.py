"""Judging the open-world study's analyses against the truth: a ride's verdicts and the per-family table.

A ride's hidden law is known (:mod:`euc_ros.core.worldsim.forces`), so what ``euc-ros residual`` says about
it can be scored: :func:`right_library_names` are the library effects that name the law's leading part,
:func:`judge` reads the analysis' JSON into the row's judged columns (a right or a false name, the discovered
terms and their family, whether the effect is *explained*), :func:`judge_interval` whether the interval of h
holds the true h, and :func:`summarize` makes the per-family table of a run's rows with its :data:`GOALS`.
Numbers only: the report and its figure are formatted by the command, ``euc-ros campaign open-world``.
"""
from __future__ import annotations

import math

import numpy as np

from euc_ros.core.residual.names import library_effects
from euc_ros.core.worldsim import forces as F
from euc_ros.core.worldsim.open_world_seeds import FAMILIES

#: Rides with less sliding than this are "clean" in the table [mm].
CLEAN_MM = 1.0
#: Rides with at most this much sliding are a lab's usual rides: their median width has its own goal [mm].
USUAL_MM = 5.0
#: Rides with less sliding than this have their own explained goal [mm].
LOW_SLIDING_MM = 3.0
#: Explained: the held-out RMSE after / before at most this, by a right library name or discovered terms.
EXPLAINED_RATIO = 0.6
#: Goals of the table.
GOALS = {"false_name_pct_max": 5.0, "coverage_pct_min": 90.0, "width_clean_mm_max": 30.0,
         "width_usual_mm_max": 60.0, "controls_no_name_pct_min": 95.0, "controls_none_pct_min": 90.0,
         "explained_pct_min": 60.0, "explained_low_sliding_pct_min": 80.0}
#: Spellings a discovered row's ``family`` may use, mapped to the generator's families.
FAMILY_ALIASES = {"lab": "lab_field", "lab_field": "lab_field", "lab field": "lab_field", "position": "lab_field",
                  "field": "lab_field", "wheel": "wheel", "wheel_angle": "wheel", "wheel angle": "wheel",
                  "periodic": "wheel", "speed": "speed", "velocity": "speed", "drift": "drift", "time": "drift",
                  "dynamic": "dynamic", "dynamics": "dynamic", "lag": "dynamic", "filter": "dynamic",
                 "wheel rotation": "wheel", "oscillator": "dynamic"}


def right_library_names(law: F.ForceLaw | None) -> tuple[str, ...]:
    """Library effects whose law is the hidden law's leading part (naming one is not a false name).

    * an odd speed law, or a speed-driven first-order lag: ``rolling_resistance``, ``viscous_friction``,
      ``aero_drag`` (forces that grow with speed and oppose or follow it);
    * a horizontal drift or a horizontal lab field not multiplied by the speed: ``ground_slope`` (its
      leading part is a constant horizontal force);
    * a vertical drift at the rider's CoG: ``rider_mass_error`` (a constant vertical force at G is a
      weight).

    Everything else has no library counterpart (a wheel-periodic law, an even speed law, a pitch torque).

    Parameters
    ----------
    law : ForceLaw or None
        The ride's hidden law (:func:`euc_ros.core.worldsim.forces.draw_law`); None for a control ride.

    Returns
    -------
    tuple of str
        The library effect names (empty: none is right, every name is a false one).
    """
    if law is None:
        return ()
    fam, pt, P = law.family, law.point.kind, law.params
    horizontal = pt in ("contact", "cog_x", "rider_x")
    if (fam == "speed" and P["parity"] == "odd") or (fam == "dynamic" and P["input"] == "speed" and P["order"] == 1):
        return ("rolling_resistance", "viscous_friction", "aero_drag")
    if horizontal and (fam == "drift" or (fam == "lab_field" and P["multiplier"] == "none")):
        return ("ground_slope",)
    if fam == "drift" and pt == "cog_z":
        return ("rider_mass_error",)
    return ()


def _family_of(row: dict) -> str | None:
    fam = row.get("family")
    if fam is None:
        return None
    return FAMILY_ALIASES.get(str(fam).strip().lower(), str(fam).strip().lower())


def judge(data: dict, family: str, law: F.ForceLaw | None) -> dict:
    """What the analysis' JSON says about a ride with a known hidden law (the row's judged columns).

    Parameters
    ----------
    data : dict
        The JSON of ``euc-ros residual`` on the ride: ``rmse_before_nm`` and ``rmse_after_nm`` (required),
        ``effect``, ``discovered`` (rows with ``family``, ``formula`` or ``function``, ``coordinate``,
        ``point``) and ``noise_floor_nm``.
    family : str
        The ride's family (:data:`~euc_ros.core.worldsim.open_world_seeds.FAMILIES`; ``"none"``: a control).
    law : ForceLaw or None
        The hidden law (None for a control).

    Returns
    -------
    dict
        ``effect``, ``library_names``, ``right_names``, ``right_name`` and ``false_name`` (a library name
        in / not in :func:`right_library_names`), ``discovered_terms``, ``discovered``,
        ``discovered_families`` and ``family_match`` (both None without discovered rows or when one has no
        ``family``),
        ``rmse_before_nm``, ``rmse_after_nm`` [N m], ``ratio_measured`` (after / before), ``explained``
        (None for a control; else the ratio is at most :data:`EXPLAINED_RATIO` with a right name, or with
        discovered terms whose families include ``family`` or are not given) and ``noise_floor_nm``.

    Raises
    ------
    KeyError
        ``data`` lacks ``rmse_before_nm`` or ``rmse_after_nm``.
    """
    names = library_effects(data.get("effect", "none"))
    right = set(right_library_names(law))
    disc = list(data.get("discovered") or [])
    fams = [_family_of(r) for r in disc]
    has_key = bool(disc) and all(f is not None for f in fams)
    before, after = float(data["rmse_before_nm"]), float(data["rmse_after_nm"])
    ratio = after / before if before > 0 else float("nan")
    family_match = (family in fams) if has_key else None
    by_disc = bool(disc) and (family_match is not False)
    by_name = any(n in right for n in names)
    explained = None if family == "none" else bool(ratio <= EXPLAINED_RATIO and (by_name or by_disc))
    return {"effect": data.get("effect"), "library_names": names, "right_names": sorted(right),
            "right_name": by_name, "false_name": any(n not in right for n in names),
            "discovered_terms": len(disc),
            "discovered": [f"{r.get('formula', r.get('function'))} ({r.get('coordinate')} at {r.get('point')})"
                           for r in disc],
            "discovered_families": fams if has_key else None, "family_match": family_match,
            "rmse_before_nm": before, "rmse_after_nm": after, "ratio_measured": ratio, "explained": explained,
            "noise_floor_nm": data.get("noise_floor_nm")}


def judge_interval(ci, h_true: float) -> dict:
    """Whether the analysis' interval of h (``h_after_ci95_m``) holds the true h (the row's interval columns).

    An end the data do not bound (None) is open: the interval does not inform on that side, so it counts as a
    miss, and the width is infinite.

    Parameters
    ----------
    ci : sequence of (float or None), or None
        ``[low, high]`` [m]; None: both ends open.
    h_true : float
        The ride's true h [m].

    Returns
    -------
    dict
        ``h_after_lo_m``, ``h_after_hi_m`` (the ends as given) [m], ``width_mm`` [mm] and ``covered``.
    """
    ci = ci or [None, None]
    lo = -math.inf if ci[0] is None else float(ci[0])
    hi = math.inf if ci[1] is None else float(ci[1])
    return {"h_after_lo_m": ci[0], "h_after_hi_m": ci[1], "width_mm": 1e3 * (hi - lo),
            "covered": bool(math.isfinite(hi - lo) and lo <= h_true <= hi)}


# --------------------------------------------------------------------------------------------------
# the per-family table
# --------------------------------------------------------------------------------------------------
def _pct(flags) -> float | None:
    flags = [bool(f) for f in flags if f is not None]
    return 100.0 * sum(flags) / len(flags) if flags else None


def median(values) -> float | None:
    """Median of the given numbers (an infinite width, an unbounded interval, counts as the largest).

    Parameters
    ----------
    values : iterable of (float or None)
        The numbers; None and NaN are left out.

    Returns
    -------
    float or None
        None when no number is left.
    """
    v = [float(x) for x in values if x is not None and not math.isnan(float(x))]
    return float(np.median(v)) if v else None


def summarize(rows: list[dict]) -> dict:
    """Per-family table: counts, explained / false-name / coverage percentages, interval widths, and the goals.

    Parameters
    ----------
    rows : list of dict
        A run's rows (:data:`~euc_ros.core.openworld.study.COLUMNS`, as
        :func:`~euc_ros.core.openworld.study.run_task` makes them); a row whose ``status`` is not ``"ok"``
        is a failure.

    Returns
    -------
    dict
        ``families`` (family -> statistics and ``goals_met``), ``goals`` (the thresholds),
        ``explained_ratio``, ``clean_mm`` [mm], ``family_key`` (whether the discovered rows carried a
        ``family``; None without any) and ``failures`` (``task`` and ``error`` of each failed row).
    """
    out = {"goals": dict(GOALS), "explained_ratio": EXPLAINED_RATIO, "clean_mm": CLEAN_MM, "families": {},
           "failures": [{"task": r["task"], "error": r["error"]} for r in rows if r["status"] != "ok"]}
    disc_rows = [r for r in rows if r["status"] == "ok" and r.get("discovered_terms")]
    out["family_key"] = (all(r.get("discovered_families") is not None for r in disc_rows) if disc_rows else None)
    for fam in FAMILIES:
        fr = [r for r in rows if r["family"] == fam]
        if not fr:
            continue
        ok = [r for r in fr if r["status"] == "ok"]
        clean = [r for r in ok if r["artefact_mm"] is not None and r["artefact_mm"] < CLEAN_MM]
        usual = [r for r in ok if r["artefact_mm"] is not None and r["artefact_mm"] <= USUAL_MM]
        low = [r for r in ok if r["artefact_mm"] is not None and r["artefact_mm"] < LOW_SLIDING_MM]
        s = {"n": len(ok), "failed": len(fr) - len(ok), "n_clean": len(clean), "n_usual": len(usual),
             "n_low_sliding": len(low),
             "explained_pct": _pct(r["explained"] for r in ok) if fam != "none" else None,
             "explained_low_sliding_pct": _pct(r["explained"] for r in low) if fam != "none" else None,
             "none_pct": _pct(r["effect"] == "none" for r in ok) if fam == "none" else None,
             "false_name_pct": _pct(r["false_name"] for r in ok),
             "no_name_pct": _pct(not r["library_names"] for r in ok),
             "coverage_pct": _pct(r["covered"] for r in ok),
             "coverage_clean_pct": _pct(r["covered"] for r in clean),
             "width_median_mm": median(r["width_mm"] for r in ok),
             "width_clean_median_mm": median(r["width_mm"] for r in clean),
             "width_usual_median_mm": median(r["width_mm"] for r in usual),
             "floor_median_nm": median(r["floor_nm"] if fam != "none" else r["rmse_before_nm"] for r in ok),
             "ratio_design_median": median(r["ratio_design"] for r in ok),
             "ratio_measured_median": median(r["ratio_measured"] for r in ok),
             "before_vs_predicted_median": median(r["rmse_before_nm"] / r["before_predicted_nm"] for r in ok
                                                   if r.get("before_predicted_nm")),
             "effects": {}}
        for r in ok:
            s["effects"][r["effect"]] = s["effects"].get(r["effect"], 0) + 1
        g = {"false_name": s["false_name_pct"] is not None and s["false_name_pct"] <= GOALS["false_name_pct_max"],
             "coverage": s["coverage_pct"] is not None and s["coverage_pct"] >= GOALS["coverage_pct_min"],
             "width_clean": (s["width_clean_median_mm"] <= GOALS["width_clean_mm_max"]
                             if s["width_clean_median_mm"] is not None else None),
             "width_usual": (s["width_usual_median_mm"] <= GOALS["width_usual_mm_max"]
                             if s["width_usual_median_mm"] is not None else None)}
        if fam == "none":
            g["controls_no_name"] = (s["no_name_pct"] is not None
                                     and s["no_name_pct"] >= GOALS["controls_no_name_pct_min"])
            g["controls_none"] = s["none_pct"] is not None and s["none_pct"] >= GOALS["controls_none_pct_min"]
        else:
            g["explained"] = s["explained_pct"] is not None and s["explained_pct"] >= GOALS["explained_pct_min"]
            g["explained_low_sliding"] = (s["explained_low_sliding_pct"] >= GOALS["explained_low_sliding_pct_min"]
                                          if s["explained_low_sliding_pct"] is not None else None)
        s["goals_met"] = g
        out["families"][fam] = s
    return out
