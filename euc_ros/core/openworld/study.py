"""The open-world study's rides: a hidden random law in rides of the independent generator, traced.

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

The ``none`` family (controls) skips 2-3. :func:`run_task` turns a ride into a row of :data:`COLUMNS`
(``euc-ros residual`` on it, judged against the truth by :mod:`euc_ros.core.openworld.judge`); :func:`tasks`
lists a run's rides, :func:`write_rows` and :func:`read_rows` keep the rows in results.csv.

The draws of a ride come from ``numpy.random.default_rng([seed, family index, STREAM])``: the same seed
and family give the same ride anywhere.
"""
from __future__ import annotations

import csv
import dataclasses
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from euc_ros.core.errors import ConfigError, describe_error
from euc_ros.core.openworld.judge import judge, judge_interval
from euc_ros.core.openworld.lab_design import DESIGNS
from euc_ros.core.worldsim import forces as F
from euc_ros.core.worldsim.open_world_seeds import FAMILIES, SEED_SETS

#: Pose noise of the paper's capture: 0.2 mm per axis, 0.5 deg RMS angle (:class:`~euc_ros.core.worldsim.Capture`).
NOISE_POS_MM, NOISE_ROT_DEG = 0.2, 0.5
#: Range of the soft-tissue sliding level (RMS 3-D pivot sliding of every rider body) [mm].
ARTEFACT_MM = (0.0, 10.0)
#: Orientation sliding per mm of pivot sliding [deg/mm] (the artefact model's default pairs 2 deg with 5 mm).
ARTEFACT_DEG_PER_MM = 0.4
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

#: Columns of results.csv.
COLUMNS = ("task", "family", "seed", "status", "error", "seconds", "ride_seed", "point", "law", "amplitude", "unit",
           "law_draws", "artefact_mm", "ratio_target", "floor_nm", "effect_target_nm", "effect_truth_nm",
           "ratio_design",
           "rmse_before_nm", "before_predicted_nm", "rmse_after_nm", "ratio_measured", "effect", "library_names",
           "right_names", "right_name", "false_name", "discovered_terms", "discovered", "discovered_families",
           "family_match", "explained", "h_true_m", "h_after_m", "h_after_lo_m", "h_after_hi_m", "width_mm",
           "covered", "noise_floor_nm", "artefact_model", "joint_scale", "session")


# --------------------------------------------------------------------------------------------------
# rides
# --------------------------------------------------------------------------------------------------
def ride_rng(seed: int, family: str) -> np.random.Generator:
    """The ride's random stream for the law, the artefact level and the target ratio.

    Parameters
    ----------
    seed : int
        The ride's seed.
    family : str
        One of :data:`~euc_ros.core.worldsim.open_world_seeds.FAMILIES`.

    Returns
    -------
    numpy.random.Generator
        Seeded with ``[seed, family index, STREAM]``.

    Raises
    ------
    ConfigError
        ``family`` is unknown (key ``family``).
    """
    if family not in FAMILIES:
        raise ConfigError(f"must be one of {FAMILIES}, got {family!r}", key="family")
    return np.random.default_rng([int(seed), FAMILIES.index(family), STREAM])


def write_recording(ride, out: Path, name: str, *, seed: int, artefact_mm: float, design=None) -> dict:
    """Write a ride with the paper's pose noise and soft-tissue sliding of ``artefact_mm`` (RMS, 3-D).

    The generator's writer adds the white pose noise; the sliding
    (:func:`euc_ros.core.ridesim.artefacts.apply_artefacts`, band 0.3-3 Hz, half of it following the
    segment's acceleration, orientation sliding :data:`ARTEFACT_DEG_PER_MM` per mm, no further noise) is
    applied to the series read back from the CSV, which is then written again (6 decimals, as Motive).
    Equal ``seed`` gives equal noise and sliding.

    Parameters
    ----------
    ride : Ride
        A ride of the generator (:func:`euc_ros.core.worldsim.simulate_ride`).
    out : Path
        Output folder.
    name : str
        File stem and take name.
    seed : int
        Seed of the noise and the sliding.
    artefact_mm : float
        RMS 3-D pivot sliding of every rider body [mm] (0: none).
    design : LabDesign, optional
        The artefact model (:mod:`~euc_ros.core.openworld.lab_design`; default the classic one above).

    Returns
    -------
    dict
        :func:`~euc_ros.core.worldsim.write_ride`'s paths (``csv``, ``session``, ``truth``) and ``kept_frames``.

    Raises
    ------
    ConfigError
        ``artefact_mm`` is negative or not finite (key ``artefact_mm``).
    """
    from euc_ros.core.io.motive_csv import read_motive_csv, write_motive_csv
    from euc_ros.core.ridesim.artefacts import SoftTissueArtefacts, apply_artefacts
    from euc_ros.core.worldsim import Capture, write_ride

    if not (math.isfinite(artefact_mm) and artefact_mm >= 0):
        raise ConfigError(f"must be a finite number >= 0 mm, got {artefact_mm}", key="artefact_mm")
    cap = Capture(world_up="y", noise_pos_mm=NOISE_POS_MM, noise_rot_deg=NOISE_ROT_DEG, take_name=name)
    paths = write_ride(ride, out, cap, seed=seed, name=name)
    band = artefact_mm if design is None or design.band_sliding else 0.0
    joint = 0.0 if design is None else design.joint_scale
    if band > 0 or joint > 0:
        series = read_motive_csv(paths["csv"], world_up="y")
        art = SoftTissueArtefacts(slide_rms_m=1e-3 * band, slide_rot_rms_deg=ARTEFACT_DEG_PER_MM * band,
                                  noise_pos_rms_m=0.0, noise_rot_rms_deg=0.0, joint_mm_per_deg=joint,
                                  accel_share=0.5 if design is None else design.accel_share)
        slid, _ = apply_artefacts(series, art, np.random.default_rng([int(seed), STREAM, 1]))
        write_motive_csv(slid, paths["csv"], world_up="y", take_name=name, decimals=6)
    return paths


def floor_rmse(session, csv_paths) -> float:
    """Held-out RMSE of the base model [N m] (``euc-ros residual`` without candidates or discovery).

    Parameters
    ----------
    session : str or Path
        The session file.
    csv_paths : str, Path or sequence of them
        The recordings.

    Returns
    -------
    float
        The analysis' ``rmse_before_nm`` [N m].
    """
    from euc_ros.core.residual.pipeline import ResidualOptions, trace_residual

    paths = [csv_paths] if isinstance(csv_paths, (str, Path)) else list(csv_paths)
    data = trace_residual(str(session), [str(c) for c in paths],
                          options=ResidualOptions(candidates=[], discover=False)).data
    return float(data["rmse_before_nm"])


def seen_effect(effect, rate_hz: float) -> np.ndarray:
    """A law's contribution to ``M_d1 - M_d2`` as the analysis sees it.

    Through the Savitzky-Golay filter its states are smoothed with
    (:data:`~euc_ros.core.residual.analysis.RESIDUAL_WINDOW_S`, order
    :data:`~euc_ros.core.residual.analysis.RESIDUAL_POLYORDER`). The residual is linear in the accelerations,
    which the filter smooths, so a law faster than the filter passes (a tyre's harmonics at speed) reaches the
    residual attenuated; a perfect model can only explain what reaches it.

    Parameters
    ----------
    effect : array_like (n,)
        The law's contribution to ``M_d1 - M_d2`` along the ride, sampled at ``rate_hz`` [N m].
    rate_hz : float
        Sample rate [Hz].

    Returns
    -------
    ndarray (n,)
        The effect smoothed by the analysis' filter [N m] (as given when not longer than the window).
    """
    from scipy.signal import savgol_filter

    from euc_ros.core.filters.derivatives import window_samples
    from euc_ros.core.residual.analysis import RESIDUAL_POLYORDER, RESIDUAL_WINDOW_S

    e = np.asarray(effect, dtype=float)
    w = window_samples(1.0 / rate_hz, RESIDUAL_WINDOW_S, None, RESIDUAL_POLYORDER)
    return savgol_filter(e, w, RESIDUAL_POLYORDER, mode="interp") if e.size > w else e


def _runs(seed: int, family: str, spec, n: int, rate_hz: float, rtol: float, force=None) -> list:
    """The ride's further ``n - 1`` runs (the first is the seed's own draw).

    :func:`~euc_ros.core.worldsim.simulate.another_run` (runs of the same rider, EUC, controllers and place;
    their own profiles and disturbances), with ``force``.
    """
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


def _write_runs(rides: list, out: Path, seed: int, artefact_mm: float, design=None) -> dict:
    paths = [write_recording(r, out / f"run_{k + 1:02d}", f"run_{k + 1:02d}", seed=int(seed) * 100 + k,
                             artefact_mm=artefact_mm, design=design) for k, r in enumerate(rides)]
    session = paths[0]["session"]
    if design is not None and design.perturbed:
        from euc_ros.core.openworld.lab_design import analysed_session
        from euc_ros.core.session import load_session, save_session

        session = out / "session_lab.yaml"
        save_session(analysed_session(load_session(paths[0]["session"]), design), session)
    return {"session": session, "session_true": paths[0]["session"], "csvs": [p["csv"] for p in paths],
            "truths": [p["truth"] for p in paths], "csv": paths[0]["csv"], "truth": paths[0]["truth"]}


def lawless_ride(seed: int, out, sliding_mm: float, *, duration: float = DURATION_S, rate_hz: float = RATE_HZ,
                 rtol: float = RTOL, runs: int = RUNS) -> dict:
    """A ride of the generator without a law, written as a lab records it: the runs, pose noise and sliding.

    Parameters
    ----------
    seed : int
        The ride's seed (:func:`~euc_ros.core.worldsim.simulate.simulate_ride`; the further runs as a study
        ride's).
    out : str or Path
        Folder (``run_01/`` ... with the CSV exports; the session beside the first).
    sliding_mm : float
        RMS 3-D pivot sliding of every rider body [mm] (:func:`write_recording`).
    duration, rate_hz, rtol, runs
        Each run's length [s], the rate [Hz], the integrator's tolerance and the number of runs.

    Returns
    -------
    dict
        ``session``, ``csvs``, ``truths`` (paths), ``h_true_m`` and ``ride`` (the first run).
    """
    from euc_ros.core.worldsim.simulate import simulate_ride

    ride0 = simulate_ride(int(seed), rate_hz, duration=duration, rtol=rtol)
    rides = [ride0] + _runs(seed, "none", ride0.spec, runs, rate_hz, rtol)
    paths = _write_runs(rides, Path(out), seed, sliding_mm)
    return {"session": paths["session"], "csvs": paths["csvs"], "truths": paths["truths"],
            "h_true_m": float(ride0.spec.plant.h), "ride": ride0}


def _seen_rms(rides: list, rate_hz: float) -> float:
    return F.rms(np.concatenate([seen_effect(r.truth["effect"], rate_hz) for r in rides]))


def make_ride(seed: int, family: str, out, *, duration: float = DURATION_S, rate_hz: float = RATE_HZ,
              rtol: float = RTOL, floor_fn=floor_rmse, refine: int = REFINE, runs: int = RUNS,
              design: str = "classic") -> dict:
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
    design : str
        How the lab records and describes the ride (:mod:`~euc_ros.core.openworld.lab_design`).

    Returns
    -------
    dict
        ``session`` (the analysed one), ``session_true``, ``csvs``, ``truths`` (paths; ``csv`` and ``truth``
        the first run's), ``design`` (:class:`~euc_ros.core.openworld.lab_design.LabDesign`), ``ride`` (the first
        analysed :class:`Ride`), ``rides``, ``law`` (:class:`ForceLaw` or None), ``artefact_mm``,
        ``ratio_target``, ``floor_nm``, ``calibration``, ``effect_truth_nm`` (RMS over the runs of the law's
        residual contribution as the analysis' filter passes it, :func:`seen_effect`).
    """
    from euc_ros.core.openworld.lab_design import draw_design
    from euc_ros.core.worldsim.simulate import simulate, simulate_ride

    out = Path(out)
    rng = ride_rng(seed, family)
    lab = draw_design(design, seed, FAMILIES.index(family), STREAM)
    artefact_mm = float(rng.uniform(*ARTEFACT_MM))
    ratio = float(rng.uniform(*F.RATIO_RANGE))
    ride0 = simulate_ride(int(seed), rate_hz, duration=duration, rtol=rtol)
    spec, p = ride0.spec, ride0.spec.plant
    rides0 = [ride0] + _runs(seed, family, spec, runs, rate_hz, rtol)
    info = {"artefact_mm": artefact_mm, "ratio_target": None, "floor_nm": None, "calibration": None, "law": None,
            "effect_truth_nm": 0.0, "design": lab}
    if family == "none":
        paths = _write_runs(rides0, out / "ride", seed, artefact_mm, lab)
        return {**paths, "ride": ride0, "rides": rides0, **info}
    p0 = _write_runs(rides0, out / "floor", seed, artefact_mm, lab)
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
    paths = _write_runs(rides, out / "ride", seed, artefact_mm, lab)
    info.update(ratio_target=ratio, floor_nm=floor, calibration=cal, law=law,
                effect_truth_nm=_seen_rms(rides, rate_hz))
    return {**paths, "ride": ride, "rides": rides, **info}


# --------------------------------------------------------------------------------------------------
# a ride's row
# --------------------------------------------------------------------------------------------------
def run_task(task) -> dict:
    """Run one open-world task: ``euc-ros residual`` on its ride, judged against the ride's truth.

    ``task`` has a ``name``, a ``seed`` and ``simulate`` (a campaign task of kind ``open_world``);
    ``task.simulate`` holds ``family`` and optionally ``duration_s``, ``rate_hz``, ``rtol``. Returns a row
    of :data:`COLUMNS`; a failure is a row with ``status: failed`` and the error.

    Parameters
    ----------
    task : object
        The campaign task (``name``, ``seed``, ``simulate``).

    Returns
    -------
    dict
        The ride's row, by column of :data:`COLUMNS`.
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
                          rate_hz=float(o.get("rate_hz", RATE_HZ)), rtol=float(o.get("rtol", RTOL)),
                          design=o.get("design", "classic"))
            data = trace_residual(str(r["session"]), [str(c) for c in r["csvs"]]).data
        ride, law = r["ride"], r["law"]
        row.update(judge(data, family, law))
        row.update(r["design"].describe())
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
            row.update(judge_interval(data.get("h_after_ci95_m"), ride.h))
        row["status"] = "ok"
    except Exception as exc:       # a ride's failure is its row, never the study's end
        row["status"] = "failed"
        row["error"] = describe_error(exc)
    row["seconds"] = round(time.perf_counter() - start, 3)
    return row


def tasks(seed_set: str, per_family: int, families=FAMILIES, *, duration: float = DURATION_S,
          rate_hz: float = RATE_HZ, rtol: float = RTOL, design: str | None = None) -> list[tuple[str, int, dict]]:
    """One task per family and seed.

    The first ``per_family`` seeds of ``seed_set`` (``tuning``, ``report``), as ``(name, seed, options)`` (a
    campaign task of kind ``open_world``).

    Parameters
    ----------
    seed_set : str
        A key of :data:`~euc_ros.core.worldsim.open_world_seeds.SEED_SETS`.
    per_family : int
        Seeds per family (1 to the set's size).
    families : sequence of str
        Families of :data:`~euc_ros.core.worldsim.open_world_seeds.FAMILIES`.
    duration : float
        Length of each run [s].
    rate_hz : float
        Sample rate [Hz].
    rtol : float
        Integrator tolerance (0-1).
    design : str, optional
        How the rides are recorded and described (:data:`~euc_ros.core.openworld.lab_design.DESIGNS`; default
        ``lab`` for the held-out seeds, ``classic`` for the others).

    Returns
    -------
    list of (str, int, dict)
        ``(name, seed, options)`` per task, name ``<family>_<seed:06d>``.

    Raises
    ------
    ConfigError
        An unknown seed set or family, ``per_family`` out of range, or a duration, rate or tolerance out of
        range (keyed by the command-line option).
    """
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
    design = design or ("lab" if seed_set == "held-out" else "classic")
    if design not in DESIGNS:
        raise ConfigError(f"must be one of {DESIGNS}, got {design!r}", key="--design")
    opts = {"duration_s": duration, "rate_hz": rate_hz, "rtol": rtol, "design": design}
    return [(f"{fam}_{s:06d}", int(s), {"family": fam, **opts}) for fam in families for s in seeds[:per_family]]


# --------------------------------------------------------------------------------------------------
# the rows of results.csv
# --------------------------------------------------------------------------------------------------
def write_rows(rows: list[dict], path) -> Path:
    """Write results.csv: one line per ride (:data:`COLUMNS`; lists and dicts as JSON).

    Parameters
    ----------
    rows : list of dict
        The rows (:func:`run_task`).
    path : str or Path
        The file (its folder is made).

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (json.dumps(r.get(k)) if isinstance(r.get(k), (list, dict)) else r.get(k)) for k in COLUMNS})
    return path


def read_rows(path) -> list[dict]:
    """The rows of a results.csv written by :func:`write_rows`, with their types (to redo the table).

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    list of dict
        Per ride, its values by column: numbers, booleans and JSON values parsed, None for empty cells, names
        and the ``point`` and ``law`` JSON texts as text.
    """
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
        for k in ("task", "family", "status", "error", "effect", "unit", "artefact_model", "session"):
            if k in r:         # a results.csv of another version may lack a column
                r[k] = None if r[k] is None else str(r[k])
        for k in ("point", "law"):
            r[k] = None if r[k] is None else json.dumps(r[k])
    return rows
