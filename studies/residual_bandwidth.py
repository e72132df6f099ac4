"""The residual at the data's bandwidth: fast hidden laws in rides of the independent generator.

Rides come from :mod:`euc_ros.core.worldsim` as in the open-world study (three runs of one rider over the
same floor, the paper's pose noise, soft-tissue sliding of a random level 0-10 mm:
:func:`euc_ros.core.openworld.study.write_recording`), each with a hidden law of one of these families:

``wheel``
    periodic in the wheel angle ``x / R``: 1-3 of the harmonics 1-3, random weights and phases (the
    generator's ``wheel`` law; its wheel radius 0.18-0.25 m, speeds up to 4 m/s);
``lab_field``
    a sum of 1-4 Gaussian bumps of the travel, widths 0.5-3 m (log-uniform), centred within the track;
``payload``
    a payload on a spring at the point of application: its velocity ``z`` follows the speed through
    ``z'' + 2 zeta w z' + w^2 z = w^2 x_dot`` (``f = w / 2 pi`` 0.8-2.5 Hz, ``zeta`` 0.05-0.2), and the
    force on the rider is the payload's reaction ``-m_p z'`` (:class:`PayloadLaw`);
``none``
    no law (false alarms).

The point of application is drawn as the generator draws it (:func:`euc_ros.core.worldsim.forces.draw_point`).
The amplitude makes the law's residual contribution along the first run, unfiltered, ``floor sqrt(1/r^2 - 1)``
with ``r`` uniform in :data:`RATIO_RANGE` and ``floor`` the held-out RMSE of the same runs without the law
at the default analysis (1.2 s filter).

Each ride is analysed by ``trace_residual`` once per ``--windows`` entry (a window in seconds, or ``auto``:
the residual's own choice of filter) on the same files. A ride is *explained* when the held-out RMSE
after / before is at most 0.6 and the discovered terms are of the law's family (judged as the open-world
study does, :func:`euc_ros.core.openworld.judge.judge`, with ``payload`` judged as ``dynamic``), or, for
``none``, *alarmed* when the analysis reports any effect other than ``none`` and ``unexplained``
(``unexplained`` is the residual above its noise floor with no explanation).

Usage (from the repository root; tuning seeds only, drawn from ``--seed-range``)::

    PYTHONPATH=$PWD python studies/residual_bandwidth.py --per-family 3 --draw 1 --windows 1.2 auto \
        --out /tmp/band

Writes ``OUT/rows.jsonl`` (one analysis of one ride per line, as it finishes) and prints the summary.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
# studies/ holds modules named like installed packages (coverage.py): it must not shadow them
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != REPO / "studies"]
sys.path.insert(0, str(REPO))

from euc_ros.core.errors import ConfigError  # noqa: E402
from euc_ros.core.openworld import study as S  # noqa: E402
from euc_ros.core.openworld.judge import judge  # noqa: E402
from euc_ros.core.residual.families import FAMILIES as FAMILIES_DISC  # noqa: E402
from euc_ros.core.residual.families import OSCILLATORS  # noqa: E402
from euc_ros.core.residual.pipeline import ResidualOptions, trace_residual  # noqa: E402
from euc_ros.core.states.settings import ReconstructionSettings  # noqa: E402
from euc_ros.core.worldsim import forces as F  # noqa: E402

FAMILIES = ("wheel", "lab_field", "payload", "none")
#: Range of the design ratio: a perfect model's RMSE over the RMSE with the law.
RATIO_RANGE = (0.2, 0.4)
#: Payload frequencies [Hz] and damping ratios.
PAYLOAD_HZ = (0.8, 2.5)
PAYLOAD_ZETA = (0.05, 0.2)
#: Lab bumps' widths [m].
BUMP_WIDTH_M = (0.5, 3.0)
#: Tuning seeds: the rides' seeds are drawn from this range (never the open-world study's held-out seeds).
SEED_RANGE = (5000, 6000)
STREAM = 31415


class PayloadLaw(F.ForceLaw):
    """A payload oscillator: the generator's second-order dynamic law whose force is its state's rate.

    The law's states are the payload's velocity ``z0`` and acceleration ``z1``; the force on the rider is
    ``sign * z1 / input_scale`` (the payload's reaction, per unit of the amplitude).
    """

    def _shape(self, t, x, v, z, xp):
        z1 = z[1] if xp is math else np.asarray(z, dtype=float)[..., 1]
        return self.params["sign"] * z1 / self.params["input_scale"]


def draw_law(rng, family: str, p, track, stature) -> F.ForceLaw:
    """A law of one of :data:`FAMILIES` (not ``none``), amplitude 1."""
    pt = F.draw_point(rng, stature)
    if family == "wheel":
        n = int(rng.integers(1, 4))
        harm = np.sort(rng.choice(np.arange(1, 4), n, replace=False))
        w = rng.uniform(0.3, 1.0, n) * rng.choice([-1.0, 1.0], n)
        params = {"R": float(p.R), "harmonics": harm.tolist(), "weights": (w / np.abs(w).sum()).tolist(),
                  "phases": rng.uniform(-np.pi, np.pi, n).tolist()}
        return F.ForceLaw("wheel", pt, 1.0, params)
    if family == "lab_field":
        k = int(rng.integers(1, 5))
        w = rng.uniform(0.3, 1.0, k) * rng.choice([-1.0, 1.0], k)
        params = {"kind": "bumps", "weights": (w / np.abs(w).sum()).tolist(),
                  "scales_m": np.exp(rng.uniform(*np.log(BUMP_WIDTH_M), k)).tolist(),
                  "centres_m": rng.uniform(track[0], track[1], k).tolist(), "multiplier": "none"}
        return F.ForceLaw("lab_field", pt, 1.0, params)
    f = float(rng.uniform(*PAYLOAD_HZ))
    params = {"order": 2, "input": "speed", "input_scale": 1.0, "tau_s": 1.0 / (2 * np.pi * f),
              "zeta": float(rng.uniform(*PAYLOAD_ZETA)), "sign": float(rng.choice([-1.0, 1.0])), "payload_hz": f}
    return PayloadLaw("dynamic", pt, 1.0, params)


def make_ride(seed: int, family: str, out: Path, *, duration: float = S.DURATION_S, rate_hz: float = S.RATE_HZ,
              rtol: float = S.RTOL) -> dict:
    """Simulate and write one ride with a law of ``family`` (module docstring); return its files and truth."""
    from euc_ros.core.worldsim.simulate import simulate, simulate_ride

    rng = np.random.default_rng([int(seed), FAMILIES.index(family), STREAM])
    artefact_mm = float(rng.uniform(*S.ARTEFACT_MM))
    ratio = float(rng.uniform(*RATIO_RANGE))
    ride0 = simulate_ride(int(seed), rate_hz, duration=duration, rtol=rtol)
    spec, p = ride0.spec, ride0.spec.plant
    rides0 = [ride0] + S._runs(seed, "none", spec, S.RUNS, rate_hz, rtol)
    info = {"artefact_mm": artefact_mm, "ratio_target": None, "floor_nm": None, "law": None}
    if family == "none":
        return {**S._write_runs(rides0, out / "ride", seed, artefact_mm), **info}
    p0 = S._write_runs(rides0, out / "floor", seed, artefact_mm)
    floor = S.floor_rmse(p0["session"], p0["csvs"])
    x0 = ride0.stats["x_offset_m"]
    track = (x0 + float(np.min(ride0.truth["x"])), x0 + float(np.max(ride0.truth["x"])))
    err = None
    for _ in range(S.MAX_LAW_DRAWS):
        law = draw_law(rng, family, p, track, spec.info["posture"]["stature"])
        try:
            law, cal = F.calibrate(law, ride0.truth, ride0.t, p, floor, ratio, x0)
            limit = p.m * p.g * (p.h if law.point.kind == "pitch" else 1.0)
            ride = simulate(dataclasses.replace(spec, force=law), rate_hz, rtol=rtol)
            law = law.with_amplitude(law.amplitude * cal["effect_target_nm"] / F.rms(ride.truth["effect"]))
            ride = simulate(dataclasses.replace(spec, force=law), rate_hz, rtol=rtol)
            if float(np.max(np.abs(ride.truth["F_ext"]))) > limit:
                raise ConfigError(f"peak above the rider's weight ({limit:.0f})", key="amplitude")
            rides = [ride] + S._runs(seed, "none", spec, S.RUNS, rate_hz, rtol, force=law)
            break
        except (ConfigError, RuntimeError) as exc:
            err = exc
    else:
        raise ConfigError(f"seed {seed}: no law of {family!r} rides ({err})", key="seed")
    effect = F.rms(np.concatenate([r.truth["effect"] for r in rides]))
    info.update(ratio_target=ratio, floor_nm=floor, law=law, effect_nm=effect, ratio_design=F.ratio_of(floor, effect))
    return {**S._write_runs(rides, out / "ride", seed, artefact_mm), **info}


def kept_ride(seed: int, family: str, folder: Path) -> dict:
    """:func:`make_ride` into ``folder``, or the ride already there (its ``ride.json``)."""
    meta = folder / "ride.json"
    if meta.exists():
        r = json.loads(meta.read_text())
        law = r["law"]
        if law is not None:
            cls = PayloadLaw if family == "payload" else F.ForceLaw
            law = cls(law["family"], F.Point(law["point"]["kind"], law["point"]["height_m"], law["point"]["forward_m"]),
                      law["amplitude"], law["params"])
        return {**r, "law": law}
    r = make_ride(seed, family, folder)
    keep = {k: (str(v) if isinstance(v, Path) else v) for k, v in r.items() if k in
            ("session", "artefact_mm", "ratio_target", "floor_nm", "effect_nm", "ratio_design")}
    keep["csvs"] = [str(c) for c in r["csvs"]]
    keep["law"] = None if r["law"] is None else r["law"].describe()
    meta.write_text(json.dumps(keep))
    return r


def analyse(r: dict, family: str, window, oscillators: bool = False) -> dict:
    """One ``trace_residual`` of a ride's files at a window (seconds or ``auto``), judged.

    ``oscillators``: the discovery's families with :data:`~euc_ros.core.residual.families.OSCILLATORS` added.
    """
    settings = ReconstructionSettings(window_s=window if window == "auto" else float(window))
    start = time.perf_counter()
    options = ResidualOptions(families=FAMILIES_DISC + OSCILLATORS if oscillators else None)
    data = trace_residual(str(r["session"]), [str(c) for c in r["csvs"]], settings, options=options).data
    law = r["law"]
    judged_family = "dynamic" if family == "payload" else family
    row = judge(data, judged_family, law if law is None or family != "payload" else None)
    ratio = float(data["rmse_after_nm"]) / float(data["rmse_before_nm"])
    alarm = str(data.get("effect")) not in ("none", "unexplained")
    disc = data.get("discovered") or []
    return {"window": window, "window_used_s": data["settings"]["window_s"], "effect": data.get("effect"),
            "ratio": ratio, "explained": row["explained"], "false_name": row["false_name"],
            "families_found": sorted({str(d.get("family")) for d in disc}), "alarm": alarm,
            "rmse_before_nm": data["rmse_before_nm"], "noise_floor_nm": data.get("noise_floor_nm"),
            "seconds": round(time.perf_counter() - start, 1)}


def summarize(rows: list[dict]) -> str:
    """The per-family and per-window table of the rows."""
    lines = ["| family | window | n | explained | median after/before | false name | alarm (none) |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    keys = sorted({(r["family"], str(r["window"])) for r in rows if "ratio" in r})
    for fam, win in keys:
        rs = [r for r in rows if r["family"] == fam and str(r["window"]) == win and "ratio" in r]
        expl = "-" if fam == "none" else f"{sum(bool(r['explained']) for r in rs)}/{len(rs)}"
        alarm = f"{sum(r['alarm'] for r in rs)}/{len(rs)}" if fam == "none" else "-"
        lines.append(f"| {fam} | {win} | {len(rs)} | {expl} | {np.median([r['ratio'] for r in rs]):.2f} | "
                     f"{sum(bool(r['false_name']) for r in rs)} | {alarm} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    """Run the study (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", nargs="+", default=list(FAMILIES), choices=FAMILIES)
    ap.add_argument("--per-family", type=int, default=3)
    ap.add_argument("--draw", type=int, default=1, help="seed of the draw of the rides' seeds from --seed-range")
    ap.add_argument("--seed-range", default=f"{SEED_RANGE[0]}:{SEED_RANGE[1]}")
    ap.add_argument("--windows", nargs="+", default=["1.2", "auto"])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--keep", type=Path, help="folder that keeps the rides' files (made once, reused)")
    ap.add_argument("--oscillators", action="store_true", help="add the oscillator families to the discovery")
    a = ap.parse_args(argv)
    lo, hi = (int(v) for v in a.seed_range.split(":"))
    # the seeds of every family are drawn whichever are run: a family's rides do not depend on --families
    seeds = np.random.default_rng(a.draw).choice(np.arange(lo, hi), a.per_family * len(FAMILIES), replace=False)
    a.out.mkdir(parents=True, exist_ok=True)
    rows = []
    with open(a.out / "rows.jsonl", "a", encoding="utf-8") as f:
        for fam in a.families:
            i = FAMILIES.index(fam)
            for seed in seeds[i * a.per_family:(i + 1) * a.per_family]:
                base = {"family": fam, "seed": int(seed)}
                with tempfile.TemporaryDirectory(prefix="euc_band_") as tmp:
                    try:
                        r = kept_ride(int(seed), fam, a.keep / f"{fam}_{seed}" if a.keep else Path(tmp))
                    except Exception as exc:   # a ride's failure is its row
                        rows.append({**base, "error": f"{type(exc).__name__}: {exc}"})
                        f.write(json.dumps(rows[-1]) + "\n")
                        f.flush()
                        continue
                    base.update(artefact_mm=r["artefact_mm"], ratio_design=r.get("ratio_design"),
                                law=None if r["law"] is None else r["law"].describe())
                    for w in a.windows:
                        try:
                            rows.append({**base, "oscillators": a.oscillators,
                                         **analyse(r, fam, w, a.oscillators)})
                        except Exception as exc:
                            rows.append({**base, "window": w, "error": f"{type(exc).__name__}: {exc}"})
                        f.write(json.dumps(rows[-1], default=str) + "\n")
                        f.flush()
                        print(fam, seed, {k: rows[-1].get(k) for k in ("window", "effect", "ratio", "explained",
                                                                         "families_found", "error")}, flush=True)
    print(summarize(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
