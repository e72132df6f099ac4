"""The campaign benchmark (euc_ros.bench.campaign): its figures from measured runs, and its measurements on a
tiny campaign (2 tasks of 2 s rides) serially and on a real local cluster of 2 workers, each in a fresh
interpreter as the benchmark runs them."""
from __future__ import annotations

import importlib.util

import pytest

from euc_ros.bench import BENCHMARKS
from euc_ros.bench import campaign as bench
from euc_ros.bench.common import BenchContext

RUNNER = "euc_ros.cli.campaign_tasks"


def _rows(h: float = 0.6) -> list[dict]:
    return [{"task": f"seed_{s:06d}", "status": "ok", "h_m": h + 0.01 * s, "rmse_nm": float("nan"), "seconds": 0.4}
            for s in range(4)]


def _runs(serial_wall: float, cluster_wall: float, rows=None) -> tuple[list[dict], list[dict]]:
    s = {"wall_s": serial_wall, "cpu_s": serial_wall, "warmup_s": 1.0, "tasks": 4, "duration_s": 10.0,
         "task_s": serial_wall, "rows": _rows()}
    c = {"wall_s": cluster_wall, "cpu_s": 0.1, "startup_s": 1.0, "warmup_s": 1.0, "worker_cpu_s": [1.0, 1.0],
         "tasks": 4, "duration_s": 10.0, "task_s": serial_wall,
         "rows": rows if rows is not None else [dict(r, seconds=9.0) for r in _rows()]}
    return [s], [c]


def test_speedup_figure_follows_the_walls_the_rows_and_the_cores():
    assert BENCHMARKS.index("campaign") == BENCHMARKS.index("ridesim") + 1
    figs, det = bench.summarize(*_runs(4.0, 2.5), cores=2, cpu_count=2)
    rate, speed, rows = figs
    assert rate["value"] == pytest.approx(4 * 60 / 2.5) and rate["floor"] == pytest.approx(4 * 60 / 4.0)
    assert speed["value"] == pytest.approx(1.6) and speed["met"] is True
    assert det["speedup_with_startup"] == pytest.approx(4.0 / 3.5)
    assert rows["met"] is True and rows["value"] == 4 and det["rows_identical"]   # seconds and NaN do not count

    assert bench.summarize(*_runs(4.0, 3.0), cores=2, cpu_count=2)[0][1]["met"] is False     # 1.33x
    assert bench.summarize(*_runs(4.0, 2.5), cores=1, cpu_count=1)[0][1]["met"] is None      # not applicable

    changed = _rows()
    changed[2]["h_m"] += 1e-12
    figs, det = bench.summarize(*_runs(4.0, 2.0, rows=changed), cores=2, cpu_count=2)
    assert figs[2]["met"] is False and figs[2]["value"] == 3 and "seed_000002" in figs[2]["note"]
    assert figs[1]["met"] is False                           # 2x, but the rows differ
    assert bench.differing_rows(_rows()[:3], _rows()) == ["seed_000003"]


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                    reason="dask.distributed (requirements.txt) runs the cluster side")
def test_measurements_on_a_tiny_campaign_serially_and_on_two_workers(tmp_path):
    ctx = BenchContext(quick=True, cache_dir=tmp_path, tmp_dir=tmp_path)
    serial = ctx.isolated("euc_ros.bench.campaign:measure_serial", n_tasks=2, runner=RUNNER, duration_s=2.0,
                          timeout_s=300.0)
    cluster = ctx.isolated("euc_ros.bench.campaign:measure_cluster", n_tasks=2, runner=RUNNER, workers=2,
                           duration_s=2.0, timeout_s=300.0)
    assert serial["warmup_status"] == "ok" and cluster["warmup_status"] == ["ok", "ok"]
    assert [r["task"] for r in serial["rows"]] == ["seed_000000", "seed_000001"]
    assert all(r["status"] == "ok" and abs(r["h_m"] - 0.61) < 0.2 for r in serial["rows"])
    assert bench.differing_rows(cluster["rows"], serial["rows"]) == []
    for r in (serial, cluster):
        assert 0 < r["wall_s"] < 60 and r["tasks"] == 2 and r["peak_rss_mb"] > 0
    assert cluster["workers"] == 2 and len(set(cluster["worker_pids"])) == 2
    assert cluster["measuring_pid"] not in cluster["worker_pids"]            # workers are processes of their own
    assert 0 < cluster["startup_s"] < 60 and len(cluster["worker_peak_rss_mb"]) == 2
    assert sum(cluster["worker_cpu_s"]) > 0
    assert serial["task_s"] == pytest.approx(sum(r["seconds"] for r in serial["rows"]))
    figs, det = bench.summarize([serial], [cluster], cores=2, cpu_count=2)
    assert figs[2]["met"] is True and det["speedup"] > 0
