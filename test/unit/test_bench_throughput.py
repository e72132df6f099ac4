"""The throughput benchmark's load measurement on a short recording: the compiled CSV parser is loaded in the
untimed warm-up when the timed recording is a CSV (a process's one-time cost, not the read's), and only then.

Speed figures are the benchmark's (``euc-ros bench --only throughput``), not asserted here.
"""
from __future__ import annotations

import subprocess
import sys

_CHECK = """
import sys
from euc_ros.bench import throughput
r = throughput.measure_load(sys.argv[1], warmup_path=sys.argv[1])
print(r["frames"], r["wall_s"] > 0.0, "euc_ros.core.io.csv_compiled" in sys.modules)
"""


def test_the_compiled_csv_parser_is_loaded_before_a_timed_csv_read(short_ride):
    out, _ = short_ride
    path = str(next(out.glob("*.csv")))
    proc = subprocess.run([sys.executable, "-c", _CHECK, path], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    frames, timed, loaded = proc.stdout.split()
    assert int(frames) > 100 and timed == "True"
    assert loaded == "True"            # a short CSV is read by numpy: the parser was loaded by the warm-up


def test_no_compiled_csv_parser_for_bags():
    code = ("import sys\nfrom euc_ros.bench import throughput\nthroughput._prime_csv_parser(['a/bag', 'b.mcap'])\n"
            "print('euc_ros.core.io.csv_compiled' in sys.modules)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.strip() == "False"
