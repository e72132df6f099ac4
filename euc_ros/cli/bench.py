"""`euc-ros bench [--quick] --json OUT`: the benchmarks, each against a floor measured in the same run.

Runs, in order: Motive CSV parse rate, offline throughput of identify and residual (CSV and bag),
unicycle simulation real-time factor (in process and lockstep over topics), recorder messages per
second into MCAP, live pipeline latency, replay timing of ``euc-ros play``, and the NatNet/CSV fuzz
job; each with its peak memory.
Writes the results as JSON to OUT and as a Markdown table to OUT with the suffix ``.md`` (or
``--markdown``), and prints the table. See ``docs/benchmarks.md``.

The live benchmarks reserve a free ROS domain (domain_coordinator) and restrict discovery to this
host, so a running ROS system is neither disturbed nor measured. Recordings are generated once into
``--cache-dir`` (default ``~/.cache/euc_ros/bench``).

``--quick`` runs every benchmark on less data (:data:`QUICK_HELP`); the result and its table say that
its figures are indicative, and give each benchmark's wall time.

Exit codes: 0 every benchmark ran (targets missed are reported, not errors); 1 a benchmark failed;
2 a user error.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

from euc_ros.bench import BENCHMARKS
from euc_ros.bench.common import DEFAULT_CACHE, BenchContext, environ, machine_info
from euc_ros.bench.report import QUICK_NOTE, to_markdown
from euc_ros.cli.outputs import Output, check_outputs
from euc_ros.core.errors import ConfigError

HELP = "benchmarks against their floors (latency, throughput, parse, recorder, simulation, replay, fuzz)"
QUICK_HELP = ("short variants: each benchmark on less data against the same floor, so the figures are indicative. "
              "About 5 minutes on a 2-core machine, not less: the run starts 28 fresh interpreters (their imports, "
              "and for identify and residual an untimed warm-up run, 3-6 s, that keeps the one-time costs out "
              "of the figures) and 16 sets of ROS processes (start-up, discovery and shut-down, about 7 s each, around "
              "streams of 1-10 s), and less data does not shorten those. The first run also generates its "
              "recordings (a few seconds)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``euc-ros bench``."""
    parser.add_argument("--quick", action="store_true", help=QUICK_HELP)
    parser.add_argument("--json", metavar="OUT", required=True, type=Path, help="write the results as JSON to OUT")
    parser.add_argument("--markdown", metavar="OUT.md", type=Path, default=None,
                        help="Markdown table (default: OUT with the suffix .md)")
    parser.add_argument("--only", nargs="+", choices=BENCHMARKS, metavar="NAME", default=None,
                        help=f"run only these ({', '.join(BENCHMARKS)})")
    parser.add_argument("--cache-dir", type=Path, default=DEFAULT_CACHE, metavar="DIR",
                        help=f"generated recordings, reused between runs (default {DEFAULT_CACHE})")
    parser.add_argument("--keep-tmp", action="store_true", help="keep the scratch directory (bags, probe files)")
    parser.add_argument("--realtime", type=int, nargs="?", const=10, default=None, metavar="PRIO",
                        help="live benchmarks (live_sweep, soak): run the latency-critical processes at SCHED_FIFO "
                             "PRIO (default 10 when given): the pipeline container and the probe, and in the floor "
                             "its source, relays and probe alike; the monitor and recorder stay at normal priority. "
                             "Needs CAP_SYS_NICE (root); without it every process says so and runs normally")


def run_benchmarks(names, *, quick: bool, cache_dir: Path, tmp_dir: Path, log=None, realtime: int | None = None
                   ) -> dict:
    """Run the named benchmarks; returns the result dict written as JSON (``benchmarks``, ``machine``...)."""
    from domain_coordinator import domain_id

    ctx = BenchContext(quick=quick, cache_dir=Path(cache_dir), tmp_dir=Path(tmp_dir), realtime=realtime,
                       command="euc_ros.cli.main:main", campaign="euc_ros.cli.campaign_tasks")
    if log is not None:
        ctx.log = log
    ctx.cache_dir.mkdir(parents=True, exist_ok=True)
    result = {"quick": quick, "realtime": realtime, "started_utc": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
              "machine": machine_info(), "load_average_start": [round(x, 2) for x in os.getloadavg()],
              "benchmarks": []}
    if quick:
        result["note"] = QUICK_NOTE
    t0 = time.monotonic()
    with domain_id() as did, environ({"ROS_DOMAIN_ID": str(did), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}):
        for name in names:
            ctx.log(f"[bench] {name}")
            tb = time.monotonic()
            try:
                res = importlib.import_module(f"euc_ros.bench.{name}").run(ctx)
            except Exception as exc:   # one failed benchmark must not lose the others
                res = {"name": name, "error": f"{type(exc).__name__}: {exc}", "figures": [], "peak_rss_mb": {}}
                ctx.log(f"[bench] {name} failed: {res['error']}")
            res["total_s"] = time.monotonic() - tb   # with the recordings generated on a first run
            res.setdefault("wall_s", res["total_s"])
            ctx.log(f"[bench] {name} done in {res['total_s']:.1f} s ({res['wall_s']:.1f} s measuring)")
            result["benchmarks"].append(res)
    result["wall_s"] = time.monotonic() - t0
    result["load_average_end"] = [round(x, 2) for x in os.getloadavg()]
    return result


def main(args: argparse.Namespace) -> int:
    """Run the benchmarks, write JSON and Markdown, print the table."""
    names = [n for n in BENCHMARKS if args.only is None or n in args.only]
    md_path = args.markdown or args.json.with_suffix(".md")

    check_outputs([Output("--json", args.json), Output("--markdown", md_path)])
    for p in (args.json, md_path):
        if p.parent and not p.parent.exists():
            try:
                p.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ConfigError(f"cannot create the directory: {exc.strerror}", path=p.parent) from None
    tmp = Path(tempfile.mkdtemp(prefix="euc_bench_"))
    try:
        result = run_benchmarks(names, quick=args.quick, cache_dir=args.cache_dir, tmp_dir=tmp,
                                realtime=getattr(args, "realtime", None))
    finally:
        if args.keep_tmp:
            print(f"scratch kept in {tmp}", file=sys.stderr)
        else:
            shutil.rmtree(tmp, ignore_errors=True)
    md = to_markdown(result)
    try:
        args.json.write_text(json.dumps(result, indent=1, default=str) + "\n", encoding="utf-8")
        md_path.write_text(md, encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot write: {exc.strerror}", path=exc.filename) from None
    print(md)
    print(f"wrote {args.json} and {md_path}")
    return 1 if any(b.get("error") for b in result["benchmarks"]) else 0
