"""Campaigns on a real dask.distributed LocalCluster of 2 worker processes: the rows equal the serial run's,
a failing task is a row with its session, and a worker killed mid-run loses no result."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from euc_ros.cli import campaign_tasks as cmp

distributed = pytest.importorskip("distributed", reason="dask.distributed (requirements.txt) runs campaigns")
pytestmark = [pytest.mark.slow]

SIM = {"maneuver": "deceleration", "runs": 1, "duration_s": 4.0, "h": 0.61, "effects": [], "params": {},
       "noise": True}
# The cluster runs in a process of its own (as `euc-ros campaign` does): multiprocessing's resource tracker,
# which a LocalCluster starts, lives as long as the process that made it.
CLUSTER_RUN = textwrap.dedent("""
    import json, os, signal, sys
    from distributed import Client, LocalCluster
    from euc_ros.cli import campaign_tasks as cmp
    tasks = [cmp.Task(**t) for t in json.loads(sys.stdin.read())]
    killed = []
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \\
            Client(cluster) as client:
        pids = list(client.run(os.getpid).values())
        assert len(pids) == 2 and os.getpid() not in pids            # workers are processes of their own

        def kill_one(done, total, row):
            if not killed:                                           # mid-run: the other tasks are running
                killed.append(pids[0])
                os.kill(pids[0], signal.SIGKILL)

        rows = cmp.run_campaign(tasks, client=client, progress=kill_one)
    print(json.dumps({"killed": killed, "rows": rows}))
""")


#: The headline h goes through SIMEX's replicate fits and a bootstrap, whose matrix products BLAS sums in an
#: order that depends on its thread count (one per worker, more in this process): round-off of sums over
#: ~1e4 samples, ~1e-12 relative, far below this.
ROUNDOFF_REL = 1e-9


def _same(a: list[dict], b: list[dict]) -> None:
    strip = [{k: v for k, v in r.items() if k != "seconds"} for r in a]
    want = [{k: (pytest.approx(v, rel=ROUNDOFF_REL) if isinstance(v, float) else v) for k, v in r.items()
             if k != "seconds"} for r in b]
    assert strip == want


@pytest.fixture(scope="module")
def tasks(tmp_path_factory):
    bad = tmp_path_factory.mktemp("campaign") / "broken_day"
    bad.mkdir()
    (bad / "session.yaml").write_text("world_up: y\nrate_hz: 120\n")          # rider and euc missing
    (bad / "take.csv").write_text("not a Motive export\n")
    return cmp.seed_tasks(range(4), SIM) + cmp.session_tasks([bad])


@pytest.fixture(scope="module")
def serial_rows(tasks):
    return cmp.run_campaign(tasks, serial=True)


def test_serial_rows_report_the_failure_and_go_on(serial_rows):
    assert [r["task"] for r in serial_rows] == ["broken_day", *(f"seed_{s:06d}" for s in range(4))]
    failed = serial_rows[0]
    assert failed["status"] == "failed" and "session.yaml" in failed["error"] and failed["session"].endswith(
        "broken_day/session.yaml")
    assert all(r["status"] == "ok" and abs(r["h_m"] - 0.61) < 0.15 for r in serial_rows[1:])


def test_local_cluster_gives_the_serial_rows_and_survives_a_killed_worker(tasks, serial_rows):
    run = subprocess.run([sys.executable, "-c", CLUSTER_RUN], input=json.dumps([cmp.task_dict(t) for t in tasks]),
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["killed"]                                         # a worker died mid-run ...
    _same(out["rows"], serial_rows)                              # ... and every row is there, as serially
