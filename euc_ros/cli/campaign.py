"""`euc-ros campaign`: identify (and residual) over a folder of sessions or many simulated seeds, on Dask."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from euc_ros.cli import campaign_tasks as cmp
from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import ConfigError

HELP = "run identify (and residual) over many sessions or simulated seeds on a Dask cluster"

EPILOG = """examples:
  euc-ros campaign sessions lab_days/ --out results/            # every lab_days/*/session.yaml + recordings
  euc-ros campaign seeds 0:200 --effect ground_slope --residual --out study/   # a coverage/power study
  euc-ros campaign sessions lab_days/ --scheduler tcp://10.0.0.5:8786 --out results/
  euc-ros campaign open-world --seeds report --per-family 50 --out ow/   # hidden random laws, per-family table

A session folder holds session.yaml and its recordings (Motive .csv, bag folders, .mcap). The results
are results.csv (one row per task), summary.json and summary.png. A failed task is a row with its
session or seed and the error; the others go on. Tasks on a worker that dies are run again.

open-world: rides of the independent generator (euc_ros.core.worldsim), each with a random hidden force
law of a family (lab_field, wheel, speed, drift, dynamic; none for controls), soft-tissue sliding 0-10 mm
and the paper's pose noise, traced with euc-ros residual. Its seeds are fixed in
euc_ros/core/worldsim/open_world_seeds.py: "tuning" for development, "report" for the reported table.
It writes results.csv, summary.json, the Markdown table (--table) and its figure (--figure).
"""


def _seeds(text: str) -> list[int]:
    """``0:100`` (range), ``3,7,9`` or ``5``."""
    try:
        if ":" in text:
            a, b = text.split(":", 1)
            return list(range(int(a), int(b)))
        return [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"seeds are START:STOP or a comma list, got {text!r}") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros campaign``."""
    parser.epilog = EPILOG
    sub = parser.add_subparsers(dest="mode", metavar="MODE", required=True)
    s = sub.add_parser("sessions", help="one task per session folder", epilog=EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("root", help="folder whose sub-folders are sessions (or one session folder per argument)",
                   nargs="+")
    z = sub.add_parser("seeds", help="one task per seed: a simulated ride, identified (and traced)", epilog=EPILOG,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    z.add_argument("seeds", type=_seeds, help="START:STOP or a comma list")
    z.add_argument("--maneuver", default="deceleration")
    z.add_argument("--runs", type=int, default=1, help="runs per ride [1]")
    z.add_argument("--duration", type=float, default=None, metavar="S", help="duration per run [s]")
    z.add_argument("--h", type=float, default=0.61, help="true h [m] [0.61]")
    z.add_argument("--effect", action="append", default=[], metavar="NAME", help="hidden effect (repeatable)")
    z.add_argument("--param", action="append", default=[], metavar="NAME=VALUE", help="effect parameter")
    z.add_argument("--no-noise", action="store_true", help="noise-free poses")
    from euc_ros.core.openworld.study import DURATION_S as OW_DURATION_S
    from euc_ros.core.openworld.study import RATE_HZ as OW_RATE_HZ
    from euc_ros.core.openworld.study import RTOL as OW_RTOL

    w = sub.add_parser("open-world", help="hidden random laws in generator rides: a per-family table",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    w.add_argument("--seeds", choices=("tuning", "report", "held-out"), default="tuning",
                   help="the fixed seed set (euc_ros/core/worldsim/open_world_seeds.py): tuning for development, "
                        "report (the published table; a development set now), held-out (the next table, run "
                        "once) [tuning]")
    w.add_argument("--per-family", type=int, default=50, metavar="N", help="rides per family: the set's first N [50]")
    w.add_argument("--families", type=lambda t: [f.strip() for f in t.split(",") if f.strip()], default=None,
                   metavar="A,B", help="families (default: none,lab_field,wheel,speed,drift,dynamic)")
    w.add_argument("--duration", type=float, default=None, metavar="S",
                   help=f"length of each of a ride's runs [s] [{OW_DURATION_S:g}]")
    w.add_argument("--rate", type=float, default=None, metavar="HZ", help=f"frame rate [Hz] [{OW_RATE_HZ:g}]")
    w.add_argument("--rtol", type=float, default=None, help=f"integrator relative tolerance [{OW_RTOL:g}]")
    w.add_argument("--design", choices=("classic", "lab"), default=None,
                   help="how the rides are recorded and described: classic (band-limited sliding, the generator's "
                        "session) or lab (acceleration-driven, joint-angle or mixed sliding, a perturbed session) "
                        "[lab for held-out, classic otherwise]")
    w.add_argument("--table", default=None, metavar="MD", help="Markdown report [OUT/open_world.md]")
    w.add_argument("--figure", default=None, metavar="PNG", help="its figure [OUT/open_world.png]")
    w.add_argument("--reuse", action="append", default=[], metavar="RESULTS.csv",
                   help="rows of an earlier run (its results.csv, or rows.jsonl of a run cut short) kept instead of "
                        "running their rides again: a run "
                        "cut short, or a larger --per-family than before, continues (rows are pure functions of "
                        "seed and family; repeatable)")
    for p in (s, z):
        p.add_argument("--residual", action="store_true", help="also run euc-ros residual")
    for p in (s, z, w):
        p.add_argument("--out", required=True, metavar="DIR", help="results folder (results.csv, summary.*)")
        p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="a running Dask scheduler (tcp://host:8786); default a local cluster")
        p.add_argument("--workers", type=int, default=None, help="local cluster worker processes [CPU count]")
        p.add_argument("--serial", action="store_true", help="no Dask: one task after the other in this process")
        p.add_argument("--no-progress", action="store_true", help="no progress bar")


def tasks_from_args(args) -> list[cmp.Task]:
    """The campaign's tasks from the command line.

    ``open-world``: the open-world study's tasks; ``sessions``: one per session folder (a folder with
    session.yaml) in ``--root``; else one per simulated seed.

    Parameters
    ----------
    args : argparse.Namespace

    Returns
    -------
    list of Task

    Raises
    ------
    ConfigError
        A root that is not a folder, no session folder, or a ``--param`` that is not ``NAME=VALUE``.
    """
    if args.mode == "open-world":
        from euc_ros.core.openworld import study

        specs = study.tasks(args.seeds, args.per_family, args.families or study.FAMILIES,
                            duration=args.duration or study.DURATION_S, rate_hz=args.rate or study.RATE_HZ,
                            rtol=args.rtol or study.RTOL, design=args.design)
        return [cmp.Task(name, "open_world", seed=seed, simulate=opts) for name, seed, opts in specs]
    if args.mode == "sessions":
        folders = []
        for root in map(Path, args.root):
            if not root.is_dir():
                raise ConfigError("not a folder", path=root)
            folders += [root] if (root / "session.yaml").exists() else sorted(
                p for p in root.iterdir() if p.is_dir() and (p / "session.yaml").exists())
        if not folders:
            raise ConfigError("no session folder (a folder with session.yaml) here", path=args.root[0])
        return cmp.session_tasks(folders, residual=args.residual)
    params = {}
    for item in args.param:
        k, sep, v = item.partition("=")
        if not sep:
            raise ConfigError(f"expected NAME=VALUE, got {item!r}", key="--param")
        params[k] = v
    return cmp.seed_tasks(args.seeds, {"maneuver": args.maneuver, "runs": args.runs, "duration_s": args.duration,
                                       "h": args.h, "effects": args.effect, "params": params,
                                       "noise": not args.no_noise}, residual=args.residual)


def _figure(rows: list[dict], path: Path) -> Path:
    from euc_ros.cli.figures import pyplot, save_figure

    plt = pyplot()
    ok = [r for r in rows if r["status"] == "ok"]
    fig, ax = plt.subplots(figsize=(max(5.0, 0.25 * len(ok) + 2), 3.6))
    y = list(range(len(ok)))
    h = [r["h_m"] for r in ok]
    lo = [r["h_m"] - r["h_ci95_lo_m"] if r["h_ci95_lo_m"] is not None else 0.0 for r in ok]
    hi = [r["h_ci95_hi_m"] - r["h_m"] if r["h_ci95_hi_m"] is not None else 0.0 for r in ok]
    ax.errorbar(y, h, yerr=[lo, hi], fmt="o", ms=3, lw=1, label="h with its 95 % interval")
    truth = [(i, r["h_true_m"]) for i, r in enumerate(ok) if r.get("h_true_m") is not None]
    if truth:
        ax.plot(*zip(*truth, strict=True), "k_", ms=10, label="true h")
    ax.set_xlabel("task")
    ax.set_ylabel("h [m]")
    ax.set_title(f"{len(ok)} of {len(rows)} tasks ok", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), frameon=False, ncols=2)
    return save_figure(fig, path)


def main(args: argparse.Namespace) -> int:
    """Run the campaign; 0 when every task succeeded, 1 when some failed (they are in the table)."""
    out = Path(args.out)
    outputs = [Output("--out", out, "dir")]
    if args.mode == "open-world":
        outputs += [Output("--table", args.table), Output("--figure", args.figure)]
    check_outputs(outputs, getattr(args, "root", []))
    tasks = tasks_from_args(args)
    kept = []
    if getattr(args, "reuse", None):
        from euc_ros.core.openworld import study

        names = {t.name for t in tasks}
        earlier = {}
        for path in args.reuse:
            if not Path(path).is_file():
                raise ConfigError(f"{path}: no such results file", key="--reuse")
            rows_then = ([json.loads(line) for line in Path(path).read_text(encoding="utf-8").splitlines() if line]
                         if str(path).endswith(".jsonl") else study.read_rows(path))
            earlier.update({r["task"]: r for r in rows_then if r["status"] == "ok" and r["task"] in names})
        kept = [earlier[n] for n in sorted(earlier)]
        tasks = [t for t in tasks if t.name not in earlier]
    bar = None
    if not args.no_progress:
        from tqdm import tqdm

        bar = tqdm(total=len(tasks), desc="campaign", unit="task", file=sys.stderr)

    # every row as it comes (a run cut short keeps what it made: --reuse reads this file too)
    out.mkdir(parents=True, exist_ok=True)
    partial = out / "rows.jsonl"
    partial.write_text("", encoding="utf-8")

    def progress(done, total, row):
        with open(partial, "a", encoding="utf-8") as f:
            f.write(json.dumps(row, default=str) + "\n")
        if bar is not None:
            bar.update(1)
        if row["status"] != "ok":
            print(f"campaign: {row['task']} failed: {row['error']}", file=sys.stderr)

    cluster = args.scheduler or f"a local cluster of {args.workers or 'CPU-count'} worker processes"
    where = "serially" if args.serial else f"on {cluster}"
    print(f"campaign: {len(tasks)} task(s) {where}", file=sys.stderr)
    start = time.perf_counter()
    rows = cmp.run_campaign(tasks, scheduler=args.scheduler, workers=args.workers, serial=args.serial,
                            progress=progress) if tasks else []
    if kept:
        rows = sorted(kept + rows, key=lambda r: r["task"])
        print(f"campaign: {len(kept)} row(s) reused from {', '.join(args.reuse)}", file=sys.stderr)
    if bar is not None:
        bar.close()
    out.mkdir(parents=True, exist_ok=True)
    if args.mode == "open-world":
        return _open_world_outputs(args, rows, out, where, time.perf_counter() - start)
    cmp.write_table(rows, out / "results.csv")
    summ = cmp.summary(rows)
    (out / "summary.json").write_text(json.dumps(summ, indent=2) + "\n", encoding="utf-8")
    if any(r["status"] == "ok" for r in rows):
        _figure(rows, out / "summary.png")
    line = f"campaign: {summ['ok']} of {summ['tasks']} ok"
    if "h_error_mean_m" in summ:
        line += (f"; h error {1e3 * summ['h_error_mean_m']:+.2f} +- {1e3 * summ['h_error_se_m']:.2f} mm (SE)"
                 + (f", 95 % interval covers the truth in {100 * summ['coverage_95']:.0f} %"
                    if summ.get("coverage_95") is not None else ""))
    print(line + f"; results in {out}")
    return 0 if summ["failed"] == 0 else 1


def _open_world_outputs(args, rows: list[dict], out: Path, where: str, wall_s: float) -> int:
    """results.csv, summary.json, the Markdown table and its figure of an open-world run."""
    from euc_ros.cli import open_world as report
    from euc_ros.core.openworld import study
    from euc_ros.core.openworld.judge import summarize
    from euc_ros.core.worldsim.open_world_seeds import SEED_SETS

    study.write_rows(rows, out / "results.csv")
    summ = summarize(rows)
    seeds = SEED_SETS[args.seeds][:args.per_family]
    opts = {"--families": ",".join(args.families) if args.families else None, "--duration": args.duration,
            "--rate": args.rate, "--rtol": args.rtol, "--design": args.design, "--workers": args.workers}
    command = (f"euc-ros campaign open-world --seeds {args.seeds} --per-family {args.per_family} --out {args.out}"
               + "".join(f" {k} {v}" for k, v in opts.items() if v is not None) + (" --serial" if args.serial else ""))
    meta = {"command": command, "seed_set": args.seeds, "per_family": args.per_family,
            "seed_range": f"seeds {seeds[0]}-{seeds[-1]}", "families": args.families or list(study.FAMILIES),
            "duration_s": args.duration or study.DURATION_S, "rate_hz": args.rate or study.RATE_HZ,
            "rtol": args.rtol or study.RTOL,
            "date": time.strftime("%Y-%m-%d"), "machine": report.machine(), "where": where, "wall_s": wall_s}
    if args.seeds != "report":
        meta["note"] = ("A run on the tuning seeds (development and pilots), not the reported study: that is "
                        "`euc-ros campaign open-world --seeds report --per-family 50 --out DIR "
                        "--table docs/studies/open_world.md --figure docs/figures/open_world.png`.")
    summ["meta"] = meta
    (out / "summary.json").write_text(json.dumps(summ, indent=2) + "\n", encoding="utf-8")
    md = Path(args.table) if args.table else out / "open_world.md"
    png = Path(args.figure) if args.figure else out / "open_world.png"
    fig = report.figure(rows, summ, png) if any(r["status"] == "ok" for r in rows) else None
    md.parent.mkdir(parents=True, exist_ok=True)
    md.write_text(report.markdown(summ, rows, meta, fig, md), encoding="utf-8")
    print("\n".join(report.table_lines(summ)))
    failed = sum(r["status"] != "ok" for r in rows)
    print(f"open-world: {len(rows) - failed} of {len(rows)} rides ok; results in {out}, table {md}")
    return 0 if failed == 0 else 1
