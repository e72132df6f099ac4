"""The open-world study: ``euc-ros residual`` on rides of the independent generator with a hidden random law.

Each ride (one seed and one family of :data:`~euc_ros.core.worldsim.open_world_seeds.FAMILIES`) is made
by :func:`make_ride`:

1. the rider, EUC, controllers, excitation and speed profile from the seed
   (:func:`euc_ros.core.worldsim.simulate_ride`), and :data:`RUNS` runs of that rider over the same floor
   (the first the seed's own, the others with profiles and disturbances of their own,
   :func:`euc_ros.core.worldsim.simulate.another_run`): a lab records several runs, and a force fixed in
   the lab can only be told from a passing gust where the runs meet it again;
2. the runs are written without a law (the paper's pose noise, 0.2 mm and 0.5 deg, and soft-tissue
   sliding of a random level 0-10 mm, :func:`write_recording`) and ``euc-ros residual`` measures their
   held-out RMSE, the *floor*;
3. a random law of the family (:func:`euc_ros.core.worldsim.forces.draw_law`) is scaled so that a
   perfect model would cut the RMSE to a random ratio 0.2-0.5 (``floor / sqrt(floor^2 + effect^2)``,
   the effect's RMS evaluated along the first run without the law, as the analysis' filter passes it:
   :func:`seen_effect`, :func:`~euc_ros.core.worldsim.forces.calibrate`);
4. the first run is integrated again with the law (same seed: same rider, controllers and disturbances). The
   controllers respond to the law (a speed-dependent force changes the speed it depends on), so the
   effect along this ride differs from the one along the ride without it (by up to 35 % on tuning
   seeds); the amplitude is corrected once by the ratio of the two and the ride integrated again
   (:data:`REFINE`), which brings the design ratio to the target within :data:`RATIO_TOLERANCE`;
   A law whose peak along the ride exceeds the rider's weight ``m g`` (or ``m g h`` for a pitch torque:
   a vertical force at G shows in the residual only through its lever ``h sin(phi)``, so a small effect
   may need kilonewtons), or under which the ride falls or the integration fails, is replaced by the next
   draw of the ride's stream, at most :data:`MAX_LAW_DRAWS` times; the row records the draws used;
5. the other runs are integrated with the final law, all are written with the same capture noise and
   artefacts, and ``euc-ros residual`` runs on them.

The ``none`` family (controls) skips 2-3. :func:`run_task` turns a ride into a row of :data:`COLUMNS`;
:func:`summarize` makes the per-family table and its goals, :func:`markdown` the report.

The draws of a ride come from ``numpy.random.default_rng([seed, family index, STREAM])``: the same seed
and family give the same ride anywhere.
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math
import platform
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

from euc_ros.core.errors import ConfigError
from euc_ros.core.residual.names import library_effects
from euc_ros.core.worldsim import forces as F
from euc_ros.core.worldsim.open_world_seeds import FAMILIES, SEED_SETS

#: Pose noise of the paper's capture: 0.2 mm per axis, 0.5 deg RMS angle (:class:`~euc_ros.core.worldsim.Capture`).
NOISE_POS_MM, NOISE_ROT_DEG = 0.2, 0.5
#: Range of the soft-tissue sliding level (RMS 3-D pivot sliding of every rider body) [mm].
ARTEFACT_MM = (0.0, 10.0)
#: Orientation sliding per mm of pivot sliding [deg/mm] (the artefact model's default pairs 2 deg with 5 mm).
ARTEFACT_DEG_PER_MM = 0.4
#: Rides with less sliding than this are "clean" in the table [mm].
CLEAN_MM = 1.0
#: Defaults of a study ride: length of each run [s], rate [Hz], integrator tolerance.
#: The tolerance: a 10 s ride integrated at 1e-6 and at 1e-8 differs by at most 4e-9 m in travel and 4e-9 rad in
#: pitch (measured on seed 1000), five orders below the capture's 0.2 mm noise and three below Motive's 6
#: decimals; it takes 40 % of the time of 1e-8.
DURATION_S, RATE_HZ, RTOL = 10.0, 120.0, 1e-6
#: Runs of a ride: a lab records several runs of one rider over the same floor, so what is fixed in the lab
#: is met again and the analysis' folds hold out whole runs (one pass over a field can be told from a
#: passing gust by nothing).
RUNS = 3
#: Corrections of the amplitude along the ride with the law (each one integration more).
REFINE = 1
#: Bound of |design ratio - target| after :data:`REFINE` corrections: on 40 tuning rides (seeds 10-17, every
#: family, 20 s) the largest was 0.042 (a wheel law as a pitch torque), the 90th percentile 0.006.
RATIO_TOLERANCE = 0.05
#: Excitations drawn for a further run before the ride is a failure (a run that falls is drawn again).
MAX_RUN_DRAWS = 5
#: Laws drawn for a ride before it is a failure (a law under which the ride falls is drawn again).
MAX_LAW_DRAWS = 5
#: Second key of the ride's random stream (first: the seed; then the family's index).
STREAM = 20250
#: Explained: the held-out RMSE after / before at most this, by a right library name or discovered terms.
EXPLAINED_RATIO = 0.6
#: Goals of the table.
GOALS = {"false_name_pct_max": 5.0, "coverage_pct_min": 90.0, "width_clean_mm_max": 30.0,
         "controls_no_name_pct_min": 95.0}
#: Spellings a discovered row's ``family`` may use, mapped to the generator's families.
FAMILY_ALIASES = {"lab": "lab_field", "lab_field": "lab_field", "lab field": "lab_field", "position": "lab_field",
                  "field": "lab_field", "wheel": "wheel", "wheel_angle": "wheel", "wheel angle": "wheel",
                  "periodic": "wheel", "speed": "speed", "velocity": "speed", "drift": "drift", "time": "drift",
                  "dynamic": "dynamic", "dynamics": "dynamic", "lag": "dynamic", "filter": "dynamic",
                 "wheel rotation": "wheel"}

#: Columns of results.csv.
COLUMNS = ("task", "family", "seed", "status", "error", "seconds", "ride_seed", "point", "law", "amplitude", "unit",
           "law_draws", "artefact_mm", "ratio_target", "floor_nm", "effect_target_nm", "effect_truth_nm",
           "ratio_design",
           "rmse_before_nm", "before_predicted_nm", "rmse_after_nm", "ratio_measured", "effect", "library_names",
           "right_names", "right_name", "false_name", "discovered_terms", "discovered", "discovered_families",
           "family_match", "explained", "h_true_m", "h_after_m", "h_after_lo_m", "h_after_hi_m", "width_mm",
           "covered", "noise_floor_nm")


# --------------------------------------------------------------------------------------------------
# rides
# --------------------------------------------------------------------------------------------------
def ride_rng(seed: int, family: str) -> np.random.Generator:
    """The ride's random stream for the law, the artefact level and the target ratio."""
    if family not in FAMILIES:
        raise ConfigError(f"must be one of {FAMILIES}, got {family!r}", key="family")
    return np.random.default_rng([int(seed), FAMILIES.index(family), STREAM])


def write_recording(ride, out: Path, name: str, *, seed: int, artefact_mm: float) -> dict:
    """Write a ride with the paper's pose noise and soft-tissue sliding of ``artefact_mm`` (RMS, 3-D).

    The generator's writer adds the white pose noise; the sliding
    (:func:`euc_ros.core.ridesim.artefacts.apply_artefacts`, band 0.3-3 Hz, half of it following the
    segment's acceleration, orientation sliding :data:`ARTEFACT_DEG_PER_MM` per mm, no further noise) is
    applied to the series read back from the CSV, which is then written again (6 decimals, as Motive).
    Equal ``seed`` gives equal noise and sliding.
    """
    from euc_ros.core.io.motive_csv import read_motive_csv, write_motive_csv
    from euc_ros.core.ridesim.artefacts import SoftTissueArtefacts, apply_artefacts
    from euc_ros.core.worldsim import Capture, write_ride

    if not (math.isfinite(artefact_mm) and artefact_mm >= 0):
        raise ConfigError(f"must be a finite number >= 0 mm, got {artefact_mm}", key="artefact_mm")
    cap = Capture(world_up="y", noise_pos_mm=NOISE_POS_MM, noise_rot_deg=NOISE_ROT_DEG, take_name=name)
    paths = write_ride(ride, out, cap, seed=seed, name=name)
    if artefact_mm > 0:
        series = read_motive_csv(paths["csv"], world_up="y")
        art = SoftTissueArtefacts(slide_rms_m=1e-3 * artefact_mm, slide_rot_rms_deg=ARTEFACT_DEG_PER_MM * artefact_mm,
                                  noise_pos_rms_m=0.0, noise_rot_rms_deg=0.0)
        slid, _ = apply_artefacts(series, art, np.random.default_rng([int(seed), STREAM, 1]))
        write_motive_csv(slid, paths["csv"], world_up="y", take_name=name, decimals=6)
    return paths


def floor_rmse(session, csv_paths) -> float:
    """Held-out RMSE of the base model [N m] (``euc-ros residual`` without candidates or discovery)."""
    from euc_ros.core.residual.pipeline import ResidualOptions, trace_residual

    paths = [csv_paths] if isinstance(csv_paths, (str, Path)) else list(csv_paths)
    data = trace_residual(str(session), [str(c) for c in paths],
                          options=ResidualOptions(candidates=[], discover=False)).data
    return float(data["rmse_before_nm"])


def seen_effect(effect, rate_hz: float) -> np.ndarray:
    """A law's contribution to ``M_d1 - M_d2`` as the analysis sees it: through the Savitzky-Golay filter its
    states are smoothed with (:data:`~euc_ros.core.residual.analysis.RESIDUAL_WINDOW_S`, order
    :data:`~euc_ros.core.residual.analysis.RESIDUAL_POLYORDER`). The residual is linear in the accelerations,
    which the filter smooths, so a law faster than the filter passes (a tyre's harmonics at speed) reaches
    the residual attenuated; a perfect model can only explain what reaches it."""
    from scipy.signal import savgol_filter

    from euc_ros.core.filters.derivatives import window_samples
    from euc_ros.core.residual.analysis import RESIDUAL_POLYORDER, RESIDUAL_WINDOW_S

    e = np.asarray(effect, dtype=float)
    w = window_samples(1.0 / rate_hz, RESIDUAL_WINDOW_S, None, RESIDUAL_POLYORDER)
    return savgol_filter(e, w, RESIDUAL_POLYORDER, mode="interp") if e.size > w else e


def _runs(seed: int, family: str, spec, n: int, rate_hz: float, rtol: float, force=None) -> list:
    """The ride's further ``n - 1`` runs (the first is the seed's own draw):
    :func:`~euc_ros.core.worldsim.simulate.another_run` (runs of the same rider, EUC, controllers and place; their own
    profiles and disturbances), with ``force``."""
    from euc_ros.core.worldsim.simulate import another_run, simulate

    out = []
    for k in range(1, n):
        # a run that falls is drawn again (its own sub-seeds), as simulate_ride does for the first
        for attempt in range(MAX_RUN_DRAWS):
            key = [int(seed), FAMILIES.index(family), STREAM, 100 + k] + ([attempt] if attempt else [])
            sp = another_run(spec, key)
            try:
                out.append(simulate(dataclasses.replace(sp, force=force), rate_hz, rtol=rtol))
                break
            except ConfigError:
                if attempt == MAX_RUN_DRAWS - 1:
                    raise
    return out


def _write_runs(rides: list, out: Path, seed: int, artefact_mm: float) -> dict:
    paths = [write_recording(r, out / f"run_{k + 1:02d}", f"run_{k + 1:02d}", seed=int(seed) * 100 + k,
                             artefact_mm=artefact_mm) for k, r in enumerate(rides)]
    return {"session": paths[0]["session"], "csvs": [p["csv"] for p in paths], "truths": [p["truth"] for p in paths],
            "csv": paths[0]["csv"], "truth": paths[0]["truth"]}


def _seen_rms(rides: list, rate_hz: float) -> float:
    return F.rms(np.concatenate([seen_effect(r.truth["effect"], rate_hz) for r in rides]))


def make_ride(seed: int, family: str, out, *, duration: float = DURATION_S, rate_hz: float = RATE_HZ,
              rtol: float = RTOL, floor_fn=floor_rmse, refine: int = REFINE, runs: int = RUNS) -> dict:
    """Simulate and write one study ride (module docstring); return its files and truth.

    Parameters
    ----------
    seed : int
    family : str
        One of :data:`FAMILIES` (``none``: no law).
    out : str or Path
        Folder (the runs without the law go to ``out/floor``, the analysed runs to ``out/ride``).
    duration, rate_hz, rtol : float
        Length of each run [s], rate [Hz] and integrator tolerance.
    floor_fn : callable
        ``floor_fn(session, csvs) -> RMSE [N m]`` of the runs without the law.
    refine : int
        Corrections of the amplitude along the first run with the law (module docstring, step 4).
    runs : int
        Runs of the rider over the same floor (:data:`RUNS`).

    Returns
    -------
    dict
        ``session``, ``csvs``, ``truths`` (paths; ``csv`` and ``truth`` the first run's), ``ride`` (the first
        analysed :class:`Ride`), ``rides``, ``law`` (:class:`ForceLaw` or None), ``artefact_mm``,
        ``ratio_target``, ``floor_nm``, ``calibration``, ``effect_truth_nm`` (RMS over the runs of the law's
        residual contribution as the analysis' filter passes it, :func:`seen_effect`).
    """
    from euc_ros.core.worldsim.simulate import simulate, simulate_ride

    out = Path(out)
    rng = ride_rng(seed, family)
    artefact_mm = float(rng.uniform(*ARTEFACT_MM))
    ratio = float(rng.uniform(*F.RATIO_RANGE))
    ride0 = simulate_ride(int(seed), rate_hz, duration=duration, rtol=rtol)
    spec, p = ride0.spec, ride0.spec.plant
    rides0 = [ride0] + _runs(seed, family, spec, runs, rate_hz, rtol)
    info = {"artefact_mm": artefact_mm, "ratio_target": None, "floor_nm": None, "calibration": None, "law": None,
            "effect_truth_nm": 0.0}
    if family == "none":
        paths = _write_runs(rides0, out / "ride", seed, artefact_mm)
        return {**paths, "ride": ride0, "rides": rides0, **info}
    p0 = _write_runs(rides0, out / "floor", seed, artefact_mm)
    floor = float(floor_fn(p0["session"], p0["csvs"]))
    x0 = ride0.stats["x_offset_m"]
    track = (x0 + float(np.min(ride0.truth["x"])), x0 + float(np.max(ride0.truth["x"])))
    rejected = []
    for _ in range(MAX_LAW_DRAWS):
        law = F.draw_law(rng, family, R=p.R, track_m=track, duration=duration,
                         stature=spec.info["posture"]["stature"])
        try:
            law, cal = F.calibrate(law, ride0.truth, ride0.t, p, floor, ratio, x0,
                                   view=lambda e: seen_effect(e, rate_hz))
            peak = float(np.max(np.abs(F.values_on(law, ride0.truth, ride0.t, x0))))
            limit = p.m * p.g * (p.h if law.point.kind == "pitch" else 1.0)
            if peak > limit:
                raise ConfigError(f"peak {peak:.0f} {law.point.unit} above the rider's weight ({limit:.0f})",
                                  key="amplitude")
            ride = simulate(dataclasses.replace(spec, force=law), rate_hz, rtol=rtol)
            cal["amplitudes"] = [law.amplitude]
            cal["effects_nm"] = [_seen_rms([ride], rate_hz)]
            for _ in range(refine):
                law = law.with_amplitude(law.amplitude * cal["effect_target_nm"] / cal["effects_nm"][-1])
                ride = simulate(dataclasses.replace(spec, force=law), rate_hz, rtol=rtol)
                cal["amplitudes"].append(law.amplitude)
                cal["effects_nm"].append(_seen_rms([ride], rate_hz))
            rides = [ride] + _runs(seed, family, spec, runs, rate_hz, rtol, force=law)
            break
        except (ConfigError, RuntimeError) as exc:      # a run falls, or the integration fails
            rejected.append({"law": law.describe(), "error": str(exc)})
    else:
        raise ConfigError(f"seed {seed}: the ride falls or fails under {MAX_LAW_DRAWS} laws of {family!r} "
                          f"(last: {rejected[-1]['error']})", key="seed")
    cal["rejected_laws"] = rejected
    ride.spec.info["requested_seed"] = int(seed)
    paths = _write_runs(rides, out / "ride", seed, artefact_mm)
    info.update(ratio_target=ratio, floor_nm=floor, calibration=cal, law=law,
                effect_truth_nm=_seen_rms(rides, rate_hz))
    return {**paths, "ride": ride, "rides": rides, **info}


# --------------------------------------------------------------------------------------------------
# judging the analysis
# --------------------------------------------------------------------------------------------------
def right_library_names(law: F.ForceLaw | None) -> tuple[str, ...]:
    """Library effects whose law is the hidden law's leading part (naming one is not a false name).

    * an odd speed law, or a speed-driven first-order lag: ``rolling_resistance``, ``viscous_friction``,
      ``aero_drag`` (forces that grow with speed and oppose or follow it);
    * a horizontal drift or a horizontal lab field not multiplied by the speed: ``ground_slope`` (its
      leading part is a constant horizontal force);
    * a vertical drift at the rider's CoG: ``rider_mass_error`` (a constant vertical force at G is a
      weight).

    Everything else has no library counterpart (a wheel-periodic law, an even speed law, a pitch torque).
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
    """What the analysis' JSON says about a ride with a known hidden law (the row's judged columns)."""
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


def run_task(task) -> dict:
    """Run one open-world task (a campaign :class:`~euc_ros.cli.campaign_tasks.Task` of kind ``open_world``).

    ``task.simulate`` holds ``family`` and optionally ``duration_s``, ``rate_hz``, ``rtol``. Returns a row
    of :data:`COLUMNS`; a failure is a row with ``status: failed`` and the error.
    """
    from euc_ros.core.residual.pipeline import trace_residual

    o = task.simulate
    family = o["family"]
    row = {c: None for c in COLUMNS}
    row.update(task=task.name, family=family, seed=task.seed)
    start = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="euc_openworld_") as tmp:
            r = make_ride(task.seed, family, Path(tmp), duration=float(o.get("duration_s", DURATION_S)),
                          rate_hz=float(o.get("rate_hz", RATE_HZ)), rtol=float(o.get("rtol", RTOL)))
            data = trace_residual(str(r["session"]), [str(c) for c in r["csvs"]]).data
        ride, law = r["ride"], r["law"]
        row.update(judge(data, family, law))
        row.update(ride_seed=ride.spec.info.get("seed"), artefact_mm=r["artefact_mm"], ratio_target=r["ratio_target"],
                   floor_nm=r["floor_nm"], effect_truth_nm=r["effect_truth_nm"], h_true_m=float(ride.h),
                   h_after_m=float(data["h_after_m"]))
        if law is not None:
            row.update(law_draws=1 + len(r["calibration"]["rejected_laws"]),
                       point=json.dumps(law.point.describe()), law=json.dumps(law.params), amplitude=law.amplitude,
                       unit=law.point.unit, effect_target_nm=r["calibration"]["effect_target_nm"],
                       ratio_design=F.ratio_of(r["floor_nm"], r["effect_truth_nm"]),
                       before_predicted_nm=math.hypot(r["floor_nm"], r["effect_truth_nm"]))
        if "h_after_ci95_m" in data:
            # an end the data do not bound (None) is open: it holds the truth on its side, and the width is infinite
            ci = data.get("h_after_ci95_m") or [None, None]
            lo = -math.inf if ci[0] is None else float(ci[0])
            hi = math.inf if ci[1] is None else float(ci[1])
            row.update(h_after_lo_m=ci[0], h_after_hi_m=ci[1], width_mm=1e3 * (hi - lo),
                       covered=bool(lo <= ride.h <= hi))
        row["status"] = "ok"
    except Exception as exc:       # a ride's failure is its row, never the study's end
        row["status"] = "failed"
        row["error"] = f"{type(exc).__name__}: {exc}" if str(exc) else traceback.format_exc(limit=1).strip()
    row["seconds"] = round(time.perf_counter() - start, 3)
    return row


def tasks(seed_set: str, per_family: int, families=FAMILIES, *, duration: float = DURATION_S,
          rate_hz: float = RATE_HZ, rtol: float = RTOL) -> list[tuple[str, int, dict]]:
    """One task per family and seed: the first ``per_family`` seeds of ``seed_set`` (``tuning``, ``report``),
    as ``(name, seed, options)`` (a campaign task of kind ``open_world``)."""

    if seed_set not in SEED_SETS:
        raise ConfigError(f"must be one of {tuple(SEED_SETS)}, got {seed_set!r}", key="--seeds")
    seeds = SEED_SETS[seed_set]
    if not 1 <= per_family <= len(seeds):
        raise ConfigError(f"must be in 1..{len(seeds)}, got {per_family}", key="--per-family")
    unknown = [f for f in families if f not in FAMILIES]
    if unknown:
        raise ConfigError(f"unknown famil{'ies' if len(unknown) > 1 else 'y'} {unknown} (known: {FAMILIES})",
                          key="--families")
    if not (duration > 0 and rate_hz > 0 and 0 < rtol < 1):
        raise ConfigError(f"need duration > 0, rate > 0 and 0 < rtol < 1, got {duration}, {rate_hz}, {rtol}",
                          key="--duration")
    opts = {"duration_s": duration, "rate_hz": rate_hz, "rtol": rtol}
    return [(f"{fam}_{s:06d}", int(s), {"family": fam, **opts}) for fam in families for s in seeds[:per_family]]


# --------------------------------------------------------------------------------------------------
# table and report
# --------------------------------------------------------------------------------------------------
def write_rows(rows: list[dict], path) -> Path:
    """results.csv: one line per ride (:data:`COLUMNS`; lists as JSON)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (json.dumps(r.get(k)) if isinstance(r.get(k), (list, dict)) else r.get(k)) for k in COLUMNS})
    return path


def read_rows(path) -> list[dict]:
    """The rows of a results.csv written by :func:`write_rows`, with their types (to redo the table)."""
    def value(text: str):
        if text == "":
            return None
        if text in ("inf", "-inf", "nan"):
            return float(text)
        try:
            return json.loads(text)
        except ValueError:
            return {"True": True, "False": False}.get(text, text)

    with open(path, newline="", encoding="utf-8") as f:
        rows = [{k: value(v) for k, v in r.items()} for r in csv.DictReader(f)]
    for r in rows:   # names and JSON texts stay text
        for k in ("task", "family", "status", "error", "effect", "unit"):
            r[k] = None if r[k] is None else str(r[k])
        for k in ("point", "law"):
            r[k] = None if r[k] is None else json.dumps(r[k])
    return rows


def _pct(flags) -> float | None:
    flags = [bool(f) for f in flags if f is not None]
    return 100.0 * sum(flags) / len(flags) if flags else None


def _median(values) -> float | None:
    """Median of the given numbers (an infinite width, an unbounded interval, counts as the largest)."""
    v = [float(x) for x in values if x is not None and not math.isnan(float(x))]
    return float(np.median(v)) if v else None


def summarize(rows: list[dict]) -> dict:
    """Per-family table: counts, explained / false-name / coverage percentages, interval widths, and the goals.

    Returns
    -------
    dict
        ``families`` (family -> statistics), ``goals`` (the thresholds), ``family_key`` (whether the
        discovered rows carried a ``family``), ``failures``.
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
        s = {"n": len(ok), "failed": len(fr) - len(ok), "n_clean": len(clean),
             "explained_pct": _pct(r["explained"] for r in ok) if fam != "none" else None,
             "false_name_pct": _pct(r["false_name"] for r in ok),
             "no_name_pct": _pct(not r["library_names"] for r in ok),
             "coverage_pct": _pct(r["covered"] for r in ok),
             "coverage_clean_pct": _pct(r["covered"] for r in clean),
             "width_median_mm": _median(r["width_mm"] for r in ok),
             "width_clean_median_mm": _median(r["width_mm"] for r in clean),
             "floor_median_nm": _median(r["floor_nm"] if fam != "none" else r["rmse_before_nm"] for r in ok),
             "ratio_design_median": _median(r["ratio_design"] for r in ok),
             "ratio_measured_median": _median(r["ratio_measured"] for r in ok),
             "before_vs_predicted_median": _median(r["rmse_before_nm"] / r["before_predicted_nm"] for r in ok
                                                   if r.get("before_predicted_nm")),
             "effects": {}}
        for r in ok:
            s["effects"][r["effect"]] = s["effects"].get(r["effect"], 0) + 1
        g = {"false_name": s["false_name_pct"] is not None and s["false_name_pct"] <= GOALS["false_name_pct_max"],
             "coverage": s["coverage_pct"] is not None and s["coverage_pct"] >= GOALS["coverage_pct_min"],
             "width_clean": (s["width_clean_median_mm"] <= GOALS["width_clean_mm_max"]
                             if s["width_clean_median_mm"] is not None else None)}
        if fam == "none":
            g["controls_no_name"] = (s["no_name_pct"] is not None
                                     and s["no_name_pct"] >= GOALS["controls_no_name_pct_min"])
        s["goals_met"] = g
        out["families"][fam] = s
    return out


def _fmt(v, spec: str = ".0f", unit: str = "") -> str:
    if isinstance(v, (int, float)) and math.isinf(v):
        return "unbounded"
    return "-" if v is None else f"{v:{spec}}{unit}"


def _mark(ok) -> str:
    return "" if ok is None else (" ✓" if ok else " ✗")


def table_lines(summ: dict) -> list[str]:
    """The per-family Markdown table (goals marked ✓ met, ✗ missed)."""
    lines = ["| family | n (failed) | explained | false name | no name | coverage 95 % | median width [mm] | "
             "median width, clean [mm] (n) | floor [N m] | ratio design / measured | before / predicted |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for fam, s in summ["families"].items():
        g = s["goals_met"]
        lines.append(
            f"| {fam} | {s['n']} ({s['failed']}) | {_fmt(s['explained_pct'], '.0f', ' %')} | "
            f"{_fmt(s['false_name_pct'], '.0f', ' %')}{_mark(g['false_name'])} | "
            f"{_fmt(s['no_name_pct'], '.0f', ' %')}{_mark(g.get('controls_no_name'))} | "
            f"{_fmt(s['coverage_pct'], '.0f', ' %')}{_mark(g['coverage'])} | {_fmt(s['width_median_mm'], '.1f')} | "
            f"{_fmt(s['width_clean_median_mm'], '.1f')}{_mark(g['width_clean'])} ({s['n_clean']}) | "
            f"{_fmt(s['floor_median_nm'], '.2f')} | {_fmt(s['ratio_design_median'], '.2f')} / "
            f"{_fmt(s['ratio_measured_median'], '.2f')} | {_fmt(s['before_vs_predicted_median'], '.2f')} |")
    return lines


def figure(rows: list[dict], summ: dict, path) -> Path:
    """Three panels: the per-family percentages; the measured against the design ratio; the h error in
    units of the interval's half width against the artefact level."""
    from euc_ros.cli.plots import pyplot, save_figure

    plt = pyplot()
    fams = list(summ["families"])
    fig, ax = plt.subplots(1, 3, figsize=(13.0, 3.8))
    keys = (("explained_pct", "explained"), ("false_name_pct", "false name"), ("coverage_pct", "coverage"))
    x = np.arange(len(fams))
    for k, (key, label) in enumerate(keys):
        vals = [summ["families"][f][key] if summ["families"][f][key] is not None else 0.0 for f in fams]
        ax[0].bar(x + (k - 1) * 0.27, vals, 0.27, label=label)
    ax[0].axhline(GOALS["coverage_pct_min"], color="k", lw=0.8, ls="--")
    ax[0].axhline(GOALS["false_name_pct_max"], color="k", lw=0.8, ls=":")
    ax[0].set_xticks(x, fams, rotation=30, fontsize=8)
    ax[0].set_ylabel("% of rides")
    ax[0].set_ylim(0, 105)
    ax[0].legend(fontsize=7, loc="upper right")
    ok = [r for r in rows if r["status"] == "ok"]
    colors = {f: plt.get_cmap("tab10")(i) for i, f in enumerate(FAMILIES)}
    for f in fams:
        rr = [r for r in ok if r["family"] == f and r.get("ratio_design") is not None]
        if rr:
            ax[1].scatter([r["ratio_design"] for r in rr], [r["ratio_measured"] for r in rr], s=14, color=colors[f],
                          label=f)
    ax[1].plot([0, 1], [0, 1], "k-", lw=0.6)
    ax[1].axhline(EXPLAINED_RATIO, color="k", lw=0.8, ls="--")
    ax[1].set_xlim(0, 1)
    ax[1].set_ylim(0, 1.1)
    ax[1].set_xlabel("design ratio floor / sqrt(floor² + effect²)")
    ax[1].set_ylabel("measured RMSE after / before")
    ax[1].legend(fontsize=7)
    for f in fams:
        rr = [r for r in ok if r["family"] == f and r.get("width_mm") and r.get("h_after_lo_m") is not None
              and r.get("h_after_hi_m") is not None]
        if rr:
            z = np.clip([(r["h_after_m"] - r["h_true_m"]) / (0.5 * (r["h_after_hi_m"] - r["h_after_lo_m"]))
                         for r in rr], -4.0, 4.0)
            ax[2].scatter([r["artefact_mm"] for r in rr], z, s=14, color=colors[f], label=f)
    ax[2].axhline(1.0, color="k", lw=0.8, ls="--")
    ax[2].axhline(-1.0, color="k", lw=0.8, ls="--")
    ax[2].set_ylim(-4.2, 4.2)
    ax[2].set_xlabel("soft-tissue sliding [mm]")
    ax[2].set_ylabel("h error / interval half-width")
    ax[2].set_title("h error in half-widths (clipped at 4)", fontsize=9)
    ax[1].set_title("calibration and outcome", fontsize=9)
    ax[0].set_title("per family (goals dashed)", fontsize=9)
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, Path(path))


def markdown(summ: dict, rows: list[dict], meta: dict, figure_path: Path | None, md_path: Path) -> str:
    """The report: how it was run, the table with its goals, the outcomes by family, the failures."""
    import os

    ok = [r for r in rows if r["status"] == "ok"]
    secs = [r["seconds"] for r in rows if r.get("seconds") is not None]
    lines = ["# Open-world study: hidden random laws in rides of the independent generator", "",
             "Each ride hides a random force law of one family in a ride of `euc_ros.core.worldsim` (its own "
             "dynamics, controllers and writer) and runs `euc-ros residual` on it. The laws, their points of "
             "application and the amplitude calibration are in `euc_ros/core/worldsim/forces.py`, the study in "
             "`euc_ros/cli/open_world.py`; the seeds were fixed in `euc_ros/core/worldsim/open_world_seeds.py` "
             "before any run.", "",
             *([f"**{meta['note']}**", ""] if meta.get("note") else []),
             "## How it was run", "",
             f"* command: `{meta['command']}`",
             f"* seeds: `{meta['seed_set']}` set, the first {meta['per_family']} per family "
             f"({meta['seed_range']}); families {', '.join(meta['families'])}",
             f"* rides: {meta['duration_s']:g} s at {meta['rate_hz']:g} Hz, integrator rtol {meta['rtol']:g}; "
             f"pose noise {NOISE_POS_MM} mm and {NOISE_ROT_DEG} deg; soft-tissue sliding uniform {ARTEFACT_MM[0]:g}-"
             f"{ARTEFACT_MM[1]:g} mm ({ARTEFACT_DEG_PER_MM} deg per mm); design ratio uniform "
             f"{F.RATIO_RANGE[0]}-{F.RATIO_RANGE[1]}",
             f"* date {meta['date']}, machine {meta['machine']}, {meta['where']}; "
             f"{len(rows)} rides in {meta['wall_s'] / 60:.1f} min, "
             f"median {_median(secs) or 0:.1f} s per ride and process", "",
             "## Results", "", *table_lines(summ), "",
             f"*explained*: held-out RMSE after / before <= {EXPLAINED_RATIO} by a right library name "
             "(`right_library_names`) or by discovered terms"
             + (" of the hidden family (the discovered rows' `family`)" if summ.get("family_key") else
                " (the discovered rows carried no `family`: any discovered term counts)")
             + ". *false name*: a library effect that is not a right name for the ride's law (controls: any). "
             "*no name*: no library effect named. *coverage*: the true h inside `h_after_ci95_m`. *clean*: "
             f"sliding below {CLEAN_MM:g} mm. *floor*: the held-out RMSE of the same ride without the law. "
             "*ratio design / measured*: medians of floor / sqrt(floor² + effect²) (the effect's RMS along the "
             "analysed ride) and of the analysis' RMSE after / before. *before / predicted*: median of the "
             "measured RMSE before over sqrt(floor² + effect²), the calibration's check. Goals: false name <= "
             f"{GOALS['false_name_pct_max']:g} %, coverage >= {GOALS['coverage_pct_min']:g} %, median clean width <= "
             f"{GOALS['width_clean_mm_max']:g} mm, controls naming nothing >= {GOALS['controls_no_name_pct_min']:g} % "
             "(✓ met, ✗ missed).", ""]
    if figure_path is not None:
        rel = os.path.relpath(figure_path, md_path.parent)
        lines += [f"![open-world study]({rel})", ""]
    lines += ["## Outcomes by family", "", "| family | the analysis' effect (rides) |", "| --- | --- |"]
    for fam, s in summ["families"].items():
        eff = ", ".join(f"`{k}` {v}" for k, v in sorted(s["effects"].items(), key=lambda kv: -kv[1]))
        lines.append(f"| {fam} | {eff or '-'} |")
    lines.append("")
    if summ["failures"]:
        lines += ["## Failures", ""] + [f"* {f['task']}: {f['error']}" for f in summ["failures"]] + [""]
    lines += ["## Rides", "", "| ride | point | artefact [mm] | design ratio | effect | after / before | "
              "h - true [mm] | width [mm] |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in ok:
        pt = json.loads(r["point"])["kind"] if r.get("point") else "-"
        dh = 1e3 * (r["h_after_m"] - r["h_true_m"])
        lines.append(f"| {r['task']} | {pt} | {r['artefact_mm']:.1f} | {_fmt(r['ratio_design'], '.2f')} | "
                     f"`{r['effect']}` | {r['ratio_measured']:.2f} | {dh:+.1f} | {_fmt(r['width_mm'], '.1f')} |")
    return "\n".join(lines) + "\n"


def machine() -> str:
    import os

    return f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, {platform.system()}"
