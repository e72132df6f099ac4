"""``python -m euc_ros.bench.worker REQUEST.json OUT.json``: one measurement in a fresh interpreter.

``REQUEST.json`` holds ``{"target": "module:function", "kwargs": {...}}``. The function's dict
result is written to ``OUT.json`` with ``peak_rss_mb``, this process's peak resident set size
(``resource.getrusage``, which includes the interpreter and the imports the measurement needed).
"""
from __future__ import annotations

import json
import sys

from euc_ros.bench.common import resolve_target, self_peak_rss_mb


def main(argv: list[str] | None = None) -> int:
    """Run the request; exit code 0 when the result was written."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python -m euc_ros.bench.worker REQUEST.json OUT.json", file=sys.stderr)
        return 2
    with open(argv[0], encoding="utf-8") as f:
        req = json.load(f)
    result = resolve_target(req["target"])(**req.get("kwargs", {}))
    result = dict(result)
    result["peak_rss_mb"] = round(self_peak_rss_mb(), 1)
    with open(argv[1], "w", encoding="utf-8") as f:
        json.dump(result, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
