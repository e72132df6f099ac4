"""Bias and coverage of ``identify``'s headline h, corrected for the pose noise and the filter's distortion,
on noisy rides of both simulators.

For every ride the study runs the library call behind ``euc-ros identify`` (its default: the filter
chosen from the data, :func:`euc_ros.core.identify.cog_height.identify_h`) and records, against the
true h, four estimates: the fit at the chosen filter (identify's ``diagnostics.h_at_chosen_filter_m``),
that fit minus ``eiv_bias_m`` (SIMEX's noise correction alone), the headline h (identify's ``h_m``:
noise and filter distortion corrected) and the noise-free h with the same filter (the distortion
alone), with the intervals of the fit (``diagnostics.h_at_chosen_filter_ci95_m``) and of the headline
(``h_ci95_m``). A result row names them ``h_m`` and ``h_ci95_m`` (the fit at the chosen filter) and
``h_corrected_m`` and ``h_corrected_ci95_m`` (the headline).

Noise, two ways:

* ``file``: the ride written with the capture's white pose noise (0.2 mm, 0.5 deg) and read back,
  as a user's recording. Each ride's error holds the noise's random first-order effect (zero mean,
  millimetres): the mean over rides is the bias, to a standard error of that size.
* ``paired``: the noise-free file plus and minus the same draw of that noise
  (:func:`euc_ros.core.mocap.noise.pose_noise_series`, the capture's noise model). The pair's mean
  cancels the first-order effect exactly, so each ride's mean error is its bias, to the second
  order's scatter: the bias is resolved with few rides.

Rides: :mod:`euc_ros.core.worldsim` (seeds 1.., rates 100/120/240/360 Hz and speed profiles in
turn) and the project's simulator (:mod:`euc_ros.core.ridesim`, 2 runs per ride, maneuvers in
turn, its default noise for ``file``).

Usage (from the repository root)::

    PYTHONPATH=$PWD python studies/h_correction.py --out /tmp/h_correction --seeds 12 --project-seeds 8

``clean``: the noise-free file itself (the filter chosen from it). Writes ``OUT/results.jsonl`` (one
line per ride) and the report (``--report``, default ``docs/studies/h_correction.md``).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
# run as a script, studies/ heads sys.path: the repository root goes first instead
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != REPO / "studies"]
sys.path.insert(0, str(REPO))

from euc_ros.core.identify.cog_height import identify_h  # noqa: E402
from euc_ros.core.identify.fit import pooled_h_of_states  # noqa: E402
from euc_ros.core.identify.options import IntervalOptions  # noqa: E402
from euc_ros.core.io.recordings import load_recording  # noqa: E402
from euc_ros.core.mocap.noise import pose_noise_draws, pose_noise_series  # noqa: E402
from euc_ros.core.model.terms import EucParams  # noqa: E402
from euc_ros.core.session import load_session  # noqa: E402
from euc_ros.core.states.filter_choice import NOISE_POWER, choose_filter  # noqa: E402
from euc_ros.core.states.kinematics import reconstruct_states  # noqa: E402
from euc_ros.core.states.settings import ReconstructionSettings  # noqa: E402

RATES = (100.0, 120.0, 240.0, 360.0)
MANEUVERS = ("deceleration", "acceleration", "constant_speed", "figure_eight")
#: The capture's white pose noise: position per axis [m], rotation per body axis [rad] (0.5 deg RMS angle).
NOISE_POS_M = 0.2e-3
NOISE_ROT_RAD = float(np.radians(0.5) / np.sqrt(3.0))


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


#: ``noise_power`` of the filter's choice (:func:`choose_filter`; ``--noise-power``).
CHOICE = {"noise_power": NOISE_POWER}


def identify(series_list, session, clean=None) -> dict:
    """identify_h's default on ``series_list`` (the filter chosen from them); with ``clean`` (the
    noise-free recordings) also h with the same filter on those."""
    choice = choose_filter(series_list, session, **CHOICE)
    states = []
    for s in series_list:
        st = reconstruct_states(s, session, window_s=choice.window_s, polyorder=choice.polyorder)
        st.meta["series"] = s
        states.append(st)
    ident = identify_h(states, session, filter_choice=choice, reconstruction=ReconstructionSettings(),
                       uncertainty=IntervalOptions(with_budget=False))
    u = ident.uncertainty["uncertainty"]
    nan = float("nan")
    out = {"window_s": choice.window_s, "polyorder": choice.polyorder, "probe": list(choice.probe),
           "probe_ratio": choice.probe_ratio, "h_m": ident.h_at_filter, "h_ci95_m": list(ident.interval_at_filter),
           "eiv_bias_m": u["eiv_bias_m"], "sliding_bias_m": u.get("sliding_bias_m"),
           "h_corrected_m": ident.h if ident.corrected else nan,
           "h_corrected_ci95_m": list(ident.interval) if ident.corrected else [nan, nan]}
    if clean is not None:
        params = EucParams.from_session(session)
        out["h_clean_same_filter_m"] = pooled_h_of_states(
            [reconstruct_states(s, session, window_s=choice.window_s, polyorder=choice.polyorder) for s in clean],
            params)
    return out


def paired(clean, session, seed: int) -> list[dict]:
    """identify on the noise-free recordings plus and minus one draw of the capture's noise."""
    rng = np.random.default_rng(seed)
    draws = [pose_noise_draws(s, rng) for s in clean]
    out = []
    for sign in (1.0, -1.0):
        noisy = [pose_noise_series(s, np.full(len(s.bodies), NOISE_POS_M), np.full(len(s.bodies), NOISE_ROT_RAD),
                                   noise=z, sign=sign).materialize() for s, z in zip(clean, draws)]
        out.append(identify(noisy, session, clean))
    return out


def worldsim_ride(seed: int, duration: float, work: Path):
    from euc_ros.core.worldsim import Capture, simulate_ride, write_ride
    from euc_ros.core.worldsim.excitation import PROFILE_KINDS

    rate, kind = RATES[(seed - 1) % len(RATES)], PROFILE_KINDS[(seed - 1) % len(PROFILE_KINDS)]
    ride = simulate_ride(seed, rate, duration=duration, kind=kind)
    rec = {}
    for noise, cap in (("clean", Capture()), ("file", Capture(noise_pos_mm=0.2, noise_rot_deg=0.5))):
        paths = write_ride(ride, work / f"ws{seed}_{noise}", cap, seed=seed, name=f"ws{seed}")
        session = load_session(paths["session"])
        rec[noise] = [load_recording(paths["csv"], session.world_up)]
    return {"sim": "worldsim", "seed": seed, "rate_hz": rate, "kind": kind, "h_true_m": ride.h}, session, rec


def project_ride(seed: int, work: Path):
    from euc_ros.core.ridesim.mocap_synth import MocapNoise
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    maneuver = MANEUVERS[(seed - 1) % len(MANEUVERS)]
    rec = {}
    for noise, nz in (("clean", MocapNoise(pos_sigma_m=0.0, rot_rms_deg=0.0, marker_error_m=0.0)),
                      ("file", MocapNoise())):
        res = simulate_ride(RideConfig(maneuver=maneuver, runs=2, seed=seed, noise=nz))
        d = work / f"ps{seed}_{noise}"
        write_ride(res, d, overwrite=True)
        session = load_session(d / "session.yaml")
        rec[noise] = [load_recording(p, session.world_up) for p in sorted(d.glob("*.csv"))]
    return {"sim": "project", "seed": seed, "maneuver": maneuver, "h_true_m": res.config.h}, session, rec


def run_ride(head: dict, session, rec: dict, out) -> None:
    t0 = time.perf_counter()
    row = dict(head, clean=identify(rec["clean"], session, rec["clean"]),
               file=identify(rec["file"], session, rec["clean"]),
               paired=paired(rec["clean"], session, 1000 + head["seed"]))
    row["seconds"] = time.perf_counter() - t0
    out.write(json.dumps(row) + "\n")
    out.flush()
    f = row["file"]
    log(f"{head['sim']} {head['seed']}: W {f['window_s']:.3f} s, h {1e3 * (f['h_m'] - head['h_true_m']):+.2f} mm, "
        f"corrected {1e3 * (f['h_corrected_m'] - head['h_true_m']):+.2f} mm ({row['seconds']:.0f} s)")


#: Labels of the result rows' intervals in the report: the identify JSON's keys.
INTERVAL_LABELS = {"h_ci95_m": "diagnostics.h_at_chosen_filter_ci95_m", "h_corrected_ci95_m": "h_ci95_m"}


def errors(rows: list[dict], noise: str) -> dict[str, np.ndarray]:
    """Per ride, the errors [mm] of the four estimates (``paired``: the pair's mean) and the coverage
    and width of both intervals (``paired``: each member counts)."""
    est = {"h": lambda r: r["h_m"], "h - SIMEX": lambda r: r["h_m"] - r["eiv_bias_m"],
           "h corrected": lambda r: r["h_corrected_m"], "noise-free, same filter": lambda r: r["h_clean_same_filter_m"]}
    out = {}
    for name, get in est.items():
        vals = []
        for row in rows:
            runs = row[noise] if noise == "paired" else [row[noise]]
            vals.append(1e3 * (np.mean([get(r) for r in runs]) - row["h_true_m"]))
        out[name] = np.array(vals)
    for key in ("h_ci95_m", "h_corrected_ci95_m"):
        cov, width = [], []
        for row in rows:
            for r in (row[noise] if noise == "paired" else [row[noise]]):
                lo, hi = r[key]
                cov.append(bool(lo <= row["h_true_m"] <= hi))
                width.append(1e3 * (hi - lo))
        out[key] = (np.array(cov), np.array(width))
    return out


def summary(rows: list[dict]) -> str:
    lines = ["| rides | noise | estimate | mean err [mm] | SE [mm] | mean / SE |", "|---|---|---|---|---|---|"]
    cov_lines = ["| rides | noise | interval | covers | median width [mm] |", "|---|---|---|---|---|"]
    for sim in ("worldsim", "project"):
        sel = [r for r in rows if r["sim"] == sim]
        if not sel:
            continue
        for noise in ("clean", "file", "paired"):
            if not all(noise in r for r in sel):
                continue
            e = errors(sel, noise)
            for name in ("h", "h - SIMEX", "h corrected", "noise-free, same filter"):
                v = e[name][np.isfinite(e[name])]        # h corrected: none without a probe filter
                se = v.std(ddof=1) / np.sqrt(v.size) if v.size > 1 else float("nan")
                lines.append(f"| {sim} ({v.size}) | {noise} | {name} | {v.mean():+.3f} | {se:.3f} | "
                             f"{v.mean() / se:+.1f} |")
            for key in ("h_ci95_m", "h_corrected_ci95_m"):
                cov, width = e[key]
                cov, width = cov[~np.isnan(width)], width[~np.isnan(width)]        # none: not computed
                cov_lines.append(f"| {sim} | {noise} | `{INTERVAL_LABELS[key]}` | {cov.sum()}/{cov.size} | "
                                 f"{np.median(width):.2f} |")
    return "\n".join(lines + [""] + cov_lines)


def report(rows: list[dict], command: str, compare: tuple[list[dict], str] | None = None) -> str:
    """The Markdown report: what is compared, the summary tables and the command that made them
    (``compare``: the rows and command of a run with the other ``--noise-power``, tabled after)."""
    extra = [] if compare is None else [
        "## The same rides with the filter of the smallest mean-square error of the accelerations", "",
        f"`choose_filter(noise_power=1)`: the noise counted by its relative variance, as an estimate without "
        f"SIMEX would have it. Generated by `studies/h_correction.py` ({compare[1]}).", "",
        summary(compare[0]), ""]
    return "\n".join([
        "# The headline (corrected) h: bias and coverage on noisy rides of both simulators", "",
        "`euc-ros identify` (its default, the filter chosen from the data) reports as its headline `h_m`, with "
        "`h_ci95_m`, h corrected for the pose noise by SIMEX at the chosen filter and at the probe filter, then "
        "extrapolated in the filter's distortion to zero (`euc_ros.core.identify.cog_height.distortion_corrected`); "
        "the fit at the chosen filter is a diagnostic (`diagnostics.h_at_chosen_filter_m` with "
        "`diagnostics.h_at_chosen_filter_ci95_m`). Estimates compared, errors against the true h in mm: `h` (the "
        "fit at the chosen filter), `h - SIMEX` (that fit minus `uncertainty.eiv_bias_m`), `h corrected` (the "
        "headline `h_m`), and `noise-free, same filter` (h of the noise-free recording with the filter chosen on "
        "the noisy one: the filter's distortion alone).", "",
        "Noise: `clean` = the noise-free file (Motive's 6 decimals); `file` = the ride written with white pose "
        "noise of 0.2 mm and 0.5 deg (the project's simulator: its default noise), each ride's error holding "
        "the noise's random first-order effect; `paired` = the noise-free file plus and minus one draw of that "
        "noise, whose mean cancels the first-order effect (each member's interval counts for coverage).", "",
        f"Generated by `studies/h_correction.py` ({command}).", "",
        summary(rows), "", *extra])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seeds", type=int, default=12, help="generator rides (seeds F..F+N-1)")
    ap.add_argument("--first-seed", type=int, default=1, help="F, the first generator seed (1)")
    ap.add_argument("--project-seeds", type=int, default=8, help="project simulator rides (seeds 1..N)")
    ap.add_argument("--duration", type=float, default=20.0, help="generator ride length [s]")
    ap.add_argument("--summary-only", action="store_true", help="summarize OUT/results.jsonl")
    ap.add_argument("--noise-power", type=int, default=NOISE_POWER, choices=(1, 2),
                    help=f"how the filter's choice counts the noise ({NOISE_POWER}, identify's)")
    ap.add_argument("--report", type=Path, default=REPO / "docs" / "studies" / "h_correction.md")
    ap.add_argument("--compare", type=Path, default=None, metavar="DIR",
                    help="also table DIR/results.jsonl and DIR/command.txt (a run with the other --noise-power)")
    args = ap.parse_args(argv)
    CHOICE["noise_power"] = args.noise_power
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "results.jsonl"
    if not args.summary_only:
        with path.open("w", encoding="utf-8") as out:
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                run_ride(*worldsim_ride(seed, args.duration, args.out), out)
            for seed in range(1, args.project_seeds + 1):
                run_ride(*project_ride(seed, args.out), out)
    rows = [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines() if line.strip()]
    print(summary(rows))
    command = "python studies/h_correction.py --out DIR " + " ".join(
        f"--{k} {v}" for k, v in (("first-seed", args.first_seed), ("seeds", args.seeds),
                                   ("project-seeds", args.project_seeds), ("duration", f"{args.duration:g}"),
                                   ("noise-power", args.noise_power)))
    (args.out / "command.txt").write_text(command, encoding="utf-8")
    compare = None
    if args.compare is not None:
        other = (args.compare / "results.jsonl").read_text(encoding="utf-8").splitlines()
        compare = ([json.loads(line) for line in other if line.strip()],
                   (args.compare / "command.txt").read_text(encoding="utf-8"))
    args.report.write_text(report(rows, command, compare), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
