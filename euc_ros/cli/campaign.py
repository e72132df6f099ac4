"""`euc-ros campaign`: identify (and residual) over a folder of sessions or many simulated seeds, on Dask."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from euc_ros.cli import campaign_tasks as cmp
from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import ConfigError

HELP = "run identify (and residual) over many sessions or simulated seeds on a Dask cluster"

EPILOG = """examples:
  euc-ros campaign sessions lab_days/ --out results/            # every lab_days/*/session.yaml + recordings
  euc-ros campaign seeds 0:200 --effect ground_slope --residual --out study/   # a coverage/power study
  euc-ros campaign sessions lab_days/ --scheduler tcp://10.0.0.5:8786 --out results/

A session folder holds session.yaml and its recordings (Motive .csv, bag folders, .mcap). The results
are results.csv (one row per task), summary.json and summary.png. A failed task is a row with its
session or seed and the error; the others go on. Tasks on a worker that dies are run again.
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
    for p in (s, z):
        p.add_argument("--residual", action="store_true", help="also run euc-ros residual")
        p.add_argument("--out", required=True, metavar="DIR", help="results folder (results.csv, summary.*)")
        p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="a running Dask scheduler (tcp://host:8786); default a local cluster")
        p.add_argument("--workers", type=int, default=None, help="local cluster worker processes [CPU count]")
        p.add_argument("--serial", action="store_true", help="no Dask: one task after the other in this process")
        p.add_argument("--no-progress", action="store_true", help="no progress bar")


def tasks_from_args(args) -> list[cmp.Task]:
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
    from euc_ros.cli.plots import pyplot, save_figure

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
    check_outputs([Output("--out", out, "dir")], getattr(args, "root", []))
    tasks = tasks_from_args(args)
    bar = None
    if not args.no_progress:
        from tqdm import tqdm

        bar = tqdm(total=len(tasks), desc="campaign", unit="task", file=sys.stderr)

    def progress(done, total, row):
        if bar is not None:
            bar.update(1)
        if row["status"] != "ok":
            print(f"campaign: {row['task']} failed: {row['error']}", file=sys.stderr)

    where = "serially" if args.serial else (args.scheduler or f"a local cluster of {args.workers or 'CPU-count'} "
                                                               "worker processes")
    print(f"campaign: {len(tasks)} task(s) {where}", file=sys.stderr)
    rows = cmp.run_campaign(tasks, scheduler=args.scheduler, workers=args.workers, serial=args.serial,
                            progress=progress)
    if bar is not None:
        bar.close()
    out.mkdir(parents=True, exist_ok=True)
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
