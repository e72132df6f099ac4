"""The fuzz job through ``euc-ros bench`` (quick): CLI, isolated worker, JSON and Markdown outputs."""
from __future__ import annotations

import json

import pytest

from euc_ros.cli.main import main


def test_bench_fuzz_job_writes_json_and_markdown(tmp_path, capsys):
    out = tmp_path / "res" / "bench.json"
    code = main(["bench", "--quick", "--only", "fuzz", "--json", str(out), "--cache-dir", str(tmp_path / "cache")])
    assert code == 0, capsys.readouterr().err
    result = json.loads(out.read_text())
    (bench,) = result["benchmarks"]
    assert bench["name"] == "fuzz" and "error" not in bench
    for kind in ("natnet", "csv"):
        d = bench["details"][kind]
        assert d["inputs"] > 0 and d["crash"] == d["hang"] == d["unclear"] == 0
        assert d["accepted"] + d["rejected"] + d["invalid"] == d["inputs"]
        assert 10 < bench["peak_rss_mb"][f"fuzz {kind}"] < 2000     # the worker's own high-water mark, in MB
    assert result["machine"]["logical_cpus"] >= 1 and len(result["load_average_start"]) == 3
    # the benchmark's wall time, measured around it (recordings included) and by it (measuring alone)
    assert result["wall_s"] >= bench["total_s"] >= bench["wall_s"] > 0
    assert result["quick"] is True and "indicative" in result["note"]
    md = out.with_suffix(".md").read_text()
    assert "| fuzz | natnet: inputs, failures |" in md and "Peak memory" in md
    assert result["note"] in md
    times = md[md.index("Wall time per benchmark"):].splitlines()
    (row,) = [line for line in times if line.startswith("| fuzz |")]   # rounded to 2 decimals or 3 digits
    assert [float(c.split()[0]) for c in row.strip("|").split("|")[1:]] == [
        pytest.approx(bench["total_s"], rel=5e-3, abs=5e-3), pytest.approx(bench["wall_s"], rel=5e-3, abs=5e-3)]
    assert md in capsys.readouterr().out
