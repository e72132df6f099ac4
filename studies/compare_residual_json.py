"""Run ``euc-ros residual`` from two source trees on one recording and compare the JSON outputs.

Used for changes that must leave every number unchanged (restructuring, memory work that reorders,
blocks and frees arrays). ``--base REV`` exports that git revision
of this repository (``git archive``) into a temporary directory and runs the command with it first on
``PYTHONPATH``; the working tree is the other side. Both runs use the same interpreter.

    python studies/compare_residual_json.py SESSION.yaml RECORDING.csv --base HEAD~4

Exit 0 when the two JSON documents are identical (every key, every float bit for bit), else 1 with
the differing paths and the largest absolute and relative float differences. ``--ignore KEY`` drops a
top-level key from both (none is ignored by default: the outputs carry no timing or path that differs).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run_residual(tree: Path, session: str, recording: str, out: Path, extra: list[str]) -> None:
    env = dict(os.environ, PYTHONPATH=f"{tree}{os.pathsep}{os.environ.get('PYTHONPATH', '')}")
    cmd = [sys.executable, "-m", "euc_ros.cli.main", "residual", session, recording, "--no-progress",
           "--json", str(out), *extra]
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)


def export_revision(rev: str, dest: Path) -> Path:
    """The files of ``rev`` (git archive) under ``dest``."""
    tar = dest / "tree.tar"
    with open(tar, "wb") as f:
        subprocess.run(["git", "-C", str(ROOT), "archive", rev], stdout=f, check=True)
    tree = dest / "tree"
    with tarfile.open(tar) as t:
        t.extractall(tree)
    return tree


def differences(a, b, path: str = "") -> list[tuple[str, object, object]]:
    """Every place where ``a`` and ``b`` differ (floats compared bit for bit; NaN equals NaN)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += differences(a.get(k, "<missing>"), b.get(k, "<missing>"), f"{path}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [(path + " (length)", len(a), len(b))]
        out = []
        for i, (x, y) in enumerate(zip(a, b)):
            out += differences(x, y, f"{path}[{i}]")
        return out
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return []
    return [] if (a == b and type(a) is type(b)) else [(path, a, b)]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("session")
    ap.add_argument("recording")
    ap.add_argument("--base", required=True, help="git revision of the reference tree (e.g. HEAD~4)")
    ap.add_argument("--ignore", action="append", default=[], help="top-level JSON key left out of the comparison")
    args, residual_args = ap.parse_known_args(argv)     # the rest: further arguments of euc-ros residual
    with tempfile.TemporaryDirectory(prefix="cmp_residual_") as tmp:
        tmp = Path(tmp)
        base_tree = export_revision(args.base, tmp)
        outs = {}
        for label, tree in (("base", base_tree), ("tree", ROOT)):
            outs[label] = tmp / f"{label}.json"
            run_residual(tree, args.session, args.recording, outs[label], residual_args)
        a, b = (json.loads(outs[k].read_text()) for k in ("base", "tree"))
        same_bytes = outs["base"].read_bytes() == outs["tree"].read_bytes()
    for k in args.ignore:
        a.pop(k, None)
        b.pop(k, None)
    diffs = differences(a, b)
    if not diffs:
        print(f"identical ({'byte for byte' if same_bytes else 'every value'}): {args.base} and the working tree")
        return 0
    worst_abs = worst_rel = 0.0
    for path, x, y in diffs[:50]:
        print(f"{path}: {x!r} != {y!r}")
    for _, x, y in diffs:
        if isinstance(x, (int, float)) and isinstance(y, (int, float)):
            worst_abs = max(worst_abs, abs(x - y))
            worst_rel = max(worst_rel, abs(x - y) / max(abs(x), abs(y), 1e-300))
    print(f"{len(diffs)} differences; largest absolute {worst_abs:.3g}, relative {worst_rel:.3g}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
