#!/usr/bin/env python3
"""Compare two versions of the analyses by their statistics on the same rides, not by their bytes.

    .venv/bin/python tools/equivalence.py --base HEAD~3 --out /tmp/eq

runs, with the code of ``--base`` (checked out into a temporary git worktree) and with the working tree:

* the real-ride identification study (``studies/real_ride_identify.py``: independent-generator rides with 2-4 mm
  of soft-tissue sliding, identified with a session whose CoM offsets are 1-2 cm off) on ``--identify-seeds``;
* the open-world study (``euc-ros campaign open-world --seeds tuning``: hidden laws of every family, traced by
  ``residual``) on the first ``--per-family`` tuning seeds of each family;

then compares them (:mod:`euc_ros.core.openworld.equivalence`): |dh| in units of its standard error, interval
widths, coverage, explained and false-name rates with their binomial standard errors, verdict flips. Writes
``OUT/base/``, ``OUT/new/`` (each version's rows), ``OUT/equivalence.json`` and ``OUT/equivalence.md``. Exit
code 0 when the criteria hold, 1 when not, 2 on errors. ``--compare A B`` compares two output folders already
made (``A/rr/rows.jsonl``, ``A/ow/results.csv``) without running anything. Only tuning seeds are used.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CLI = "import sys; from euc_ros.cli.main import main; sys.exit(main(sys.argv[1:]))"


def run_version(source: Path, out: Path, identify_seeds: str, per_family: int, workers: int) -> None:
    """Both studies with the code at ``source`` into ``out/rr`` and ``out/ow``."""
    env = dict(os.environ, PYTHONPATH=str(source))
    out.mkdir(parents=True, exist_ok=True)
    steps = []
    if identify_seeds:
        steps.append([sys.executable, str(source / "studies" / "real_ride_identify.py"), "--seeds", identify_seeds,
                      "--out", str(out / "rr")])
    if per_family > 0:
        steps.append([sys.executable, "-c", CLI, "campaign", "open-world", "--seeds", "tuning", "--per-family",
                      str(per_family), "--out", str(out / "ow"), "--workers", str(workers), "--no-progress"])
    for cmd in steps:
        done = subprocess.run(cmd, env=env, cwd=tempfile.gettempdir(), capture_output=True, text=True)
        if done.returncode != 0:
            sys.stderr.write(f"error: {' '.join(cmd[-8:])} failed with the code of {source}:\n{done.stderr[-2000:]}\n")
            raise SystemExit(2)


def main(argv=None) -> int:
    """Run (or only compare) and write the report."""
    sys.path.insert(0, str(REPO))
    from euc_ros.core.openworld.equivalence import compare, load_rides, markdown

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--base", help="git revision to compare the working tree with")
    p.add_argument("--compare", nargs=2, type=Path, metavar=("BASE_DIR", "NEW_DIR"),
                   help="compare two output folders already made instead of running")
    p.add_argument("--out", type=Path, help="output folder (with --base)")
    p.add_argument("--identify-seeds", default="100:124",
                   help="real-ride seeds A:B (tuning; '' for none) [100:124: 24 rides]")
    p.add_argument("--per-family", type=int, default=4, help="open-world tuning seeds per family (0: none) [4]")
    p.add_argument("--workers", type=int, default=2, help="open-world campaign workers [2]")
    args = p.parse_args(argv)
    if args.compare:
        base_dir, new_dir = args.compare
        out = args.out or new_dir
    elif args.base and args.out:
        out = args.out
        with tempfile.TemporaryDirectory() as tmp:
            base_src = Path(tmp) / "base"
            subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(base_src), args.base],
                           check=True)
            try:
                run_version(base_src, out / "base", args.identify_seeds, args.per_family, args.workers)
            finally:
                subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(base_src)], check=False)
        run_version(REPO, out / "new", args.identify_seeds, args.per_family, args.workers)
        base_dir, new_dir = out / "base", out / "new"
    else:
        p.error("give --base REV --out DIR, or --compare BASE_DIR NEW_DIR")
    base, new = load_rides(base_dir), load_rides(new_dir)
    if not base or not new:
        sys.stderr.write(f"error: no rides in {base_dir if not base else new_dir} (rr/rows.jsonl, ow/results.csv)\n")
        return 2
    report = compare(base, new)
    out.mkdir(parents=True, exist_ok=True)
    (out / "equivalence.json").write_text(json.dumps(report, indent=1), encoding="utf-8")
    text = markdown(report, f"Statistical equivalence: {args.base or base_dir} -> working tree")
    (out / "equivalence.md").write_text(text, encoding="utf-8")
    print(text)
    return 0 if report["passed"] else 1


if __name__ == "__main__":
    sys.exit(main())
