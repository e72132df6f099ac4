#!/usr/bin/env python3
"""Run an analysis command from two revisions on the same recordings and compare their JSON outputs.

A speed or memory change must leave every number unchanged (or within a rounding bound it states):

    .venv/bin/python tools/compare_json.py --base HEAD~1 -- residual SESSION.yaml RECORDING

runs ``euc-ros residual SESSION.yaml RECORDING --json ...`` with the code of ``--base`` (checked out into a
temporary git worktree) and with the working tree, then lists every value that differs (``--rtol``: relative
differences up to this are equal; default 0, bit for bit). Exit code 0 when equal, 1 when not, 2 on errors.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RUN = "import sys; from euc_ros.cli.main import main; sys.exit(main(sys.argv[1:]))"


def differences(a, b, path: str = "", rtol: float = 0.0) -> list[tuple[str, str]]:
    """Every leaf that differs between two JSON documents, as ``(path, what)``."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append((f"{path}/{k}", "only in " + ("the working tree" if k in b else "the base")))
            else:
                out += differences(a[k], b[k], f"{path}/{k}", rtol)
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [(path, f"length {len(a)} vs {len(b)}")]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{path}[{i}]", rtol)]
    numbers = isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool)
    if numbers:
        if a == b or (math.isnan(a) and math.isnan(b)):
            return []
        rel = abs(a - b) / max(abs(a), abs(b))
        return [] if rel <= rtol else [(path, f"{a!r} vs {b!r} (relative {rel:.1e})")]
    return [] if a == b else [(path, f"{str(a)[:60]!r} vs {str(b)[:60]!r}")]


def run(source: Path, argv: list[str], out: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(source))
    done = subprocess.run([sys.executable, "-c", RUN, *argv, "--json", str(out), "--no-progress"], env=env,
                          cwd=tempfile.gettempdir(), capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"error: {' '.join(argv)} failed with the code of {source}:\n{done.stderr[-2000:]}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", required=True, help="git revision to compare the working tree with")
    parser.add_argument("--rtol", type=float, default=0.0, help="relative differences up to this are equal")
    parser.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND ARGS (without --json)")
    args = parser.parse_args()
    argv = [a for a in args.command if a != "--"]
    if not argv:
        parser.error("give the command after --, e.g. -- residual SESSION.yaml RECORDING")
    argv = [str(Path(a).resolve()) if Path(a).exists() else a for a in argv]
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", "-q", str(base), args.base],
                       check=True)
        try:
            run(base, argv, Path(tmp) / "base.json")
            run(REPO, argv, Path(tmp) / "work.json")
            diffs = differences(json.loads((Path(tmp) / "base.json").read_text()),
                                json.loads((Path(tmp) / "work.json").read_text()), rtol=args.rtol)
        finally:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(base)], check=False)
    for where, what in diffs:
        print(f"{where}: {what}")
    print(f"{len(diffs)} values differ" if diffs else "the JSON outputs are equal")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
