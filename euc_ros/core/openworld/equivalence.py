"""Statistical equivalence of two versions of the analyses on the same rides.

An estimate and its interval are random quantities: a method change that moves the numbers beyond round-off is
the same method to a user when the statistics do not move. :func:`compare` takes the rides two versions
analysed (the same seeds, so the same data) and reports, per ride and pooled:

* the change of h in units of its own standard error (``z = (h_new - h_base) / se``, ``se`` the base interval's
  half-width / 1.96; rides without a bounded base interval are listed, not scored);
* the change of the interval's width;
* coverage (an unbounded end a miss), the explained rate and the false-name rate of each version with their
  binomial standard errors;
* the rides whose verdict flips (a verdict: identifiable and covered for an identification; the effect named,
  explained and false name for a residual).

It passes (:data:`CRITERIA`) when the median ``|z|`` is at most 0.25 and the largest at most 0.5, every rate of
the new version is within one binomial standard error of the base's, and at most 5 % of the rides flip. The
binomial standard error is ``sqrt(p (1 - p) / n)`` at ``p = (k + 1/2) / (n + 1)`` (the Jeffreys prior's mean:
never zero, so a rate of 0/50 still allows one ride to change, as its uncertainty does).

Rides come from the real-ride study's ``rows.jsonl`` (:func:`identify_rides`) and the open-world study's
``results.csv`` (:func:`open_world_rides`).

Examples
--------
>>> a = {"r1": Ride(h=0.60, lo=0.58, hi=0.62, truth=0.61, verdict=("identifiable",))}
>>> b = {"r1": Ride(h=0.601, lo=0.58, hi=0.62, truth=0.61, verdict=("identifiable",))}
>>> rep = compare(a, b)
>>> round(rep["h"]["median_abs_z"], 3), rep["passed"]
(0.098, True)
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: Pass criteria: median and largest |dh| / se, rates within this many binomial SE, share of rides that flip.
CRITERIA = {"median_abs_z": 0.25, "max_abs_z": 0.5, "rate_se": 1.0, "flips": 0.05}
_Z95 = 1.959963984540054


@dataclass(frozen=True)
class Ride:
    """One ride as one version analysed it.

    Parameters
    ----------
    h, lo, hi : float or None
        The estimate of h and its 95 % interval [m] (None: unbounded or missing).
    truth : float or None
        The true h [m].
    verdict : tuple
        What a user reads off the ride (compared as a whole).
    rates : dict of str to bool
        The ride's outcomes counted in rates (``covered``, ``explained``, ``false_name``; missing: not counted).
    """

    h: float | None
    lo: float | None
    hi: float | None
    truth: float | None = None
    verdict: tuple = ()
    rates: dict = field(default_factory=dict)

    @property
    def covered(self) -> bool | None:
        """The truth inside a bounded interval (None without a truth)."""
        if self.truth is None:
            return None
        return self.lo is not None and self.hi is not None and self.lo <= self.truth <= self.hi


def _num(v) -> float | None:
    return float(v) if v is not None and isinstance(v, (int, float)) and math.isfinite(v) else None


def identify_rides(rows: list[dict], label: str = "perturbed_session") -> dict[str, Ride]:
    """The real-ride study's rows (``studies/real_ride_identify.py``), keyed ``identify/<seed>``.

    Parameters
    ----------
    rows : list of dict
        The study's rows (``rows.jsonl``).
    label : str
        The key of the analysis compared in each row.

    Returns
    -------
    dict of str to Ride
        A failed analysis is a ride without an estimate and with the verdict ``("failed",)``.
    """
    out = {}
    for r in rows:
        d = r.get(label) or {}
        if "error" in d:
            out[f"identify/{r['seed']}"] = Ride(None, None, None, r.get("h_true_m"), ("failed",))
            continue
        lo, hi = (d.get("h_ci95_m") or [None, None])
        ride = Ride(_num(d.get("h_m")), _num(lo), _num(hi), _num(r.get("h_true_m")),
                    (bool(d.get("identifiable")),))
        out[f"identify/{r['seed']}"] = Ride(ride.h, ride.lo, ride.hi, ride.truth,
                                            ride.verdict + (ride.covered,), {"covered": ride.covered})
    return out


def open_world_rides(rows: list[dict]) -> dict[str, Ride]:
    """The open-world study's rows (``results.csv``, :func:`~euc_ros.core.openworld.study.read_rows`), keyed by task.

    Parameters
    ----------
    rows : list of dict
        The study's rows.

    Returns
    -------
    dict of str to Ride
        Keyed ``residual/<task>``; a row not ``ok`` is a ride without an estimate and with the verdict
        ``("failed",)``.
    """
    out = {}
    for r in rows:
        key = f"residual/{r['task']}"
        if r.get("status") != "ok":
            out[key] = Ride(None, None, None, _num(r.get("h_true_m")), ("failed",))
            continue
        rates = {"covered": bool(r.get("covered"))} if r.get("covered") is not None else {}
        if r.get("family") != "none" and r.get("explained") is not None:
            rates["explained"] = bool(r["explained"])
        if r.get("false_name") is not None:
            rates["false_name"] = bool(r["false_name"])
        out[key] = Ride(_num(r.get("h_after_m")), _num(r.get("h_after_lo_m")), _num(r.get("h_after_hi_m")),
                        _num(r.get("h_true_m")), (r.get("effect"), r.get("explained"), r.get("false_name")), rates)
    return out


def binomial_se(k: int, n: int) -> float:
    """Binomial standard error ``sqrt(p (1 - p) / n)`` at the Jeffreys mean ``p = (k + 1/2) / (n + 1)``.

    Parameters
    ----------
    k : int
        Rides counted.
    n : int
        Rides in all.

    Returns
    -------
    float
        NaN for no rides.
    """
    if n <= 0:
        return float("nan")
    p = (k + 0.5) / (n + 1.0)
    return math.sqrt(p * (1.0 - p) / n)


def compare(base: dict[str, Ride], new: dict[str, Ride], criteria: dict | None = None) -> dict:
    """Per-ride and pooled statistics of ``new`` against ``base`` on the rides both have (JSON-ready).

    Parameters
    ----------
    base, new : dict of str to Ride
        The rides each version analysed, keyed alike.
    criteria : dict, optional
        Overrides of :data:`CRITERIA`.

    Returns
    -------
    dict
        ``rides`` (per ride: ``z``, ``dh_m``, ``dwidth_m``, ``flip``), ``h`` (``median_abs_z``, ``max_abs_z``,
        ``n``, ``unscored``), ``width`` (median change [m] and relative), ``rates`` (per rate: base and new
        ``k``, ``n``, ``p``, ``se``, ``within``), ``flips`` (the keys and their share), ``only_in`` (rides in
        one version only), ``checks`` (each criterion's pass) and ``passed``.
    """
    crit = dict(CRITERIA, **(criteria or {}))
    keys = sorted(set(base) & set(new))
    per, z, dw, unscored, flips = {}, [], [], [], []
    for k in keys:
        a, b = base[k], new[k]
        row = {"flip": a.verdict != b.verdict}
        if row["flip"]:
            flips.append(k)
        se = (a.hi - a.lo) / (2 * _Z95) if a.lo is not None and a.hi is not None and a.hi > a.lo else None
        if se is not None and a.h is not None and b.h is not None:
            row.update(dh_m=b.h - a.h, z=(b.h - a.h) / se)
            z.append(abs(row["z"]))
        else:
            unscored.append(k)
        if None not in (a.lo, a.hi, b.lo, b.hi):
            row["dwidth_m"] = (b.hi - b.lo) - (a.hi - a.lo)
            dw.append((row["dwidth_m"], a.hi - a.lo))
        per[k] = row
    rates = {}
    for name in sorted({n for k in keys for n in (*base[k].rates, *new[k].rates)}):
        common = [k for k in keys if name in base[k].rates and name in new[k].rates]
        n = len(common)
        ka = sum(bool(base[k].rates[name]) for k in common)
        kb = sum(bool(new[k].rates[name]) for k in common)
        se = binomial_se(ka, n)
        rates[name] = {"n": n, "base": {"k": ka, "p": ka / n if n else None, "se": se},
                       "new": {"k": kb, "p": kb / n if n else None, "se": binomial_se(kb, n)},
                       "within": bool(n == 0 or abs(kb - ka) / n <= crit["rate_se"] * se + 1e-12)}
    h = {"n": len(z), "unscored": unscored,
         "median_abs_z": float(np.median(z)) if z else None, "max_abs_z": float(np.max(z)) if z else None}
    width = {"n": len(dw), "median_change_m": float(np.median([d for d, _ in dw])) if dw else None,
             "median_relative_change": float(np.median([d / w for d, w in dw if w > 0])) if dw else None}
    share = len(flips) / len(keys) if keys else 0.0
    checks = {"median_abs_z": h["median_abs_z"] is None or h["median_abs_z"] <= crit["median_abs_z"],
              "max_abs_z": h["max_abs_z"] is None or h["max_abs_z"] <= crit["max_abs_z"],
              "rates": all(r["within"] for r in rates.values()),
              "flips": share <= crit["flips"]}
    return {"rides": per, "h": h, "width": width, "rates": rates, "flips": {"keys": flips, "share": share},
            "only_in": {"base": sorted(set(base) - set(new)), "new": sorted(set(new) - set(base))},
            "criteria": crit, "checks": checks, "passed": bool(all(checks.values()) and keys)}


def markdown(report: dict, title: str = "Statistical equivalence") -> str:
    """The report as a Markdown page: the verdict, the pooled statistics, the rates and the rides that flip.

    Parameters
    ----------
    report : dict
        :func:`compare`'s result.
    title : str
        The page's heading.

    Returns
    -------
    str
    """
    h, w, c = report["h"], report["width"], report["criteria"]

    def fmt(v, spec=".3f"):
        return "-" if v is None else format(v, spec)

    lines = [f"# {title}", "", f"**{'passed' if report['passed'] else 'failed'}** on {len(report['rides'])} rides "
             f"({', '.join(k for k, ok in report['checks'].items() if not ok) or 'every criterion met'}).", "",
             "| statistic | value | criterion |", "| --- | --- | --- |",
             f"| median |dh| / se | {fmt(h['median_abs_z'])} (n = {h['n']}) | <= {c['median_abs_z']} |",
             f"| largest |dh| / se | {fmt(h['max_abs_z'])} | <= {c['max_abs_z']} |",
             f"| median change of width [mm] | {fmt(_scaled(w['median_change_m'], 1e3), '+.1f')} "
             f"({fmt(_scaled(w['median_relative_change'], 100), '+.0f')} %) | - |",
             f"| verdicts that flip | {len(report['flips']['keys'])} ({100 * report['flips']['share']:.0f} %) | "
             f"<= {100 * c['flips']:.0f} % |", "",
             "| rate | n | base | new | within one SE |", "| --- | --- | --- | --- | --- |"]
    for name, r in report["rates"].items():
        lines.append(f"| {name} | {r['n']} | {r['base']['k']} ({fmt(r['base']['p'], '.2f')} ± "
                     f"{fmt(r['base']['se'], '.2f')}) | {r['new']['k']} ({fmt(r['new']['p'], '.2f')}) | "
                     f"{'yes' if r['within'] else 'no'} |")
    if report["flips"]["keys"]:
        lines += ["", "Rides whose verdict flips: " + ", ".join(report["flips"]["keys"])]
    if h["unscored"]:
        lines += ["", f"Rides without a bounded base interval (not scored in h): {', '.join(h['unscored'])}"]
    return "\n".join(lines) + "\n"


def _scaled(v, k):
    return None if v is None else k * v


def load_rides(folder) -> dict[str, Ride]:
    """The rides of one version's output folder: ``rr/rows.jsonl`` and ``ow/results.csv``, where present.

    Parameters
    ----------
    folder : str or Path
        The folder.

    Returns
    -------
    dict of str to Ride
        Empty when neither file is there.
    """
    from euc_ros.core.openworld.study import read_rows

    folder = Path(folder)
    out: dict[str, Ride] = {}
    rr = folder / "rr" / "rows.jsonl"
    if rr.is_file():
        out.update(identify_rides([json.loads(t) for t in rr.read_text(encoding="utf-8").splitlines() if t.strip()]))
    ow = folder / "ow" / "results.csv"
    if ow.is_file():
        out.update(open_world_rides(read_rows(ow)))
    return out
