#!/usr/bin/env python3
"""Coverage study of the README: the 95 % interval of h against the truth over seeds and maneuvers.

Usage: python studies/coverage_study.py [--seeds 10]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
# run as a script, studies/ heads sys.path: the repository root goes first instead
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != HERE]
sys.path.insert(0, str(HERE.parent))

from studies.coverage_cases import CASES, study  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=10)
    a = ap.parse_args()
    print("| case (true h = 0.61 m) | rides | identifiable | 95 % interval contains h | median width | "
          "median h | when not identifiable |")
    print("|:---|---:|---:|---:|---:|---:|:---|")
    for r in study(CASES, range(a.seeds)):
        cov = f"{r['covered']} of {r['identifiable']}" if r["identifiable"] else "-"
        width = f"{r['median_width_mm']:.0f} mm" if r["identifiable"] else "-"
        print(f"| {r['case']} | {r['rides']} | {r['identifiable']} | {cov} | {width} | {r['median_h_m']:.3f} | "
              f"{'; '.join(r['reasons']) or '-'} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
