"""Foundation: nodes as separate processes through the launcher, over DDS, into a bag.

CSV source -> mocap_ingest -> recorder -> MCAP bag -> read back equals the CSV.

Tolerances: poses are float64 all the way (1e-12); stamps are integer nanoseconds of start + frame /
rate (within 0.5e-9 s, plus the ulp of the start: 2e-9 s).
"""
from __future__ import annotations

import io
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import psutil
import pytest

from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.core.io.motive_csv import read_motive_csv
from euc_ros.ros.launcher import Launcher, NodeSpec

pytestmark = [pytest.mark.ros, pytest.mark.integration]
REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config"


def test_custom_message_crosses_between_two_node_processes(ros_domain, short_ride, tmp_path):
    ride_dir, _ = short_ride
    csv = ride_dir / "deceleration_01.csv"
    bag = tmp_path / "bag"
    log = io.StringIO()
    specs = [
        NodeSpec("recorder", params_file=str(CONFIG / "recorder.yaml"), parameters={"output": str(bag)},
                 required=False),
        NodeSpec("mocap_ingest", params_file=str(CONFIG / "mocap_ingest.yaml"),
                 parameters={"csv_path": str(csv), "exit_when_done": True, "rate_factor": 4.0,
                             "start_delay": 2.0, "linger": 1.0, "wait_subscribers": 1}),
    ]
    with Launcher(specs, stream=log) as launcher:
        assert launcher.wait(timeout=60), "ingest did not finish in 60 s:\n" + log.getvalue()
    assert launcher.exit_codes["mocap_ingest"] == 0, log.getvalue()
    assert launcher.exit_codes["recorder"] == 0, log.getvalue()
    assert launcher.return_code() == 0
    assert "[mocap_ingest]" in log.getvalue() and "[recorder]" in log.getvalue()  # prefixed, streamed logs

    assert check_bag(bag) == []
    frames = [m for topic, _, _, m in read_bag(bag, topics=["/mocap/frame"])]
    series = read_motive_csv(csv, world_up="y")
    assert len(frames) == series.n_frames, "frames were lost between the processes"
    numbers = np.array([f.frame_number for f in frames])
    np.testing.assert_array_equal(numbers, series.frame)
    pos = np.array([[[p.position.x, p.position.y, p.position.z] for p in f.poses] for f in frames])
    quat = np.array([[[p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w] for p in f.poses]
                     for f in frames])
    np.testing.assert_allclose(pos, series.position.transpose(1, 0, 2), atol=1e-12, equal_nan=True)
    np.testing.assert_allclose(quat, series.quat.transpose(1, 0, 2), atol=1e-12, equal_nan=True)
    assert list(frames[0].body_names) == series.bodies
    stamps = np.array([f.header.stamp.sec * 10**9 + f.header.stamp.nanosec for f in frames], dtype=np.int64)
    np.testing.assert_allclose((stamps - stamps[0]) * 1e-9, series.t - series.t[0], atol=2e-9)  # start + frame/rate


def _children(pid: int) -> list[psutil.Process]:
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def test_sigint_to_launcher_ends_every_child(ros_domain, looping_launch, tmp_path):
    launch_file, _ = looping_launch
    exe = Path(sys.executable).parent / "euc-ros"
    proc = subprocess.Popen([str(exe), "launch", str(launch_file)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(proc.stdout), daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 60
        kids = []
        # the recorder has matched the ingest's publisher (frames from now on are recorded), and both run
        while time.monotonic() < deadline:
            kids = [k for k in _children(proc.pid) if k.name() in ("recorder", "mocap_ingest")
                    or any(n in " ".join(k.cmdline()) for n in ("/recorder", "/mocap_ingest"))]
            if len(kids) >= 2 and any("matched /mocap/frame: 1 publisher" in ln for ln in list(lines)):
                break
            time.sleep(0.1)
        assert len(kids) >= 2, "children did not start"
        time.sleep(1.0)  # let frames flow
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=30)
        reader.join(timeout=5)
    finally:
        if proc.poll() is None:
            proc.kill()
    out = "".join(lines)
    assert proc.returncode == 0, out
    gone, alive = psutil.wait_procs(kids, timeout=5)
    assert not alive, f"children still alive after SIGINT: {[p.pid for p in alive]}"
    assert check_bag(tmp_path / "bag") == []   # the recorder closed its bag cleanly
    assert sum(1 for _ in read_bag(tmp_path / "bag", topics=["/mocap/frame"])) > 0


def _run_node(args, cwd):
    exe = Path(sys.executable).parent / args[0]
    return subprocess.run([str(exe), *args[1:]], capture_output=True, text=True, timeout=60, cwd=cwd)


@pytest.mark.parametrize("content, expect", [
    ("mocap_ingest:\n  ros__parameters:\n    rate_factr: 2.0\n", r"key 'mocap_ingest.ros__parameters.rate_factr'"),
    ("mocap_ingest:\n  ros__parameters:\n    rate_factor: fast\n", r"key 'mocap_ingest.ros__parameters.rate_factor'"),
    ("mocap_ingest:\n  ros__parameters:\n    source: kinect\n", r"key 'mocap_ingest.ros__parameters.source'"),
    ("mocap_ingest:\n  ros__parameters: [1, 2\n", r"line 3, column 1: not valid YAML"),
])
def test_bad_params_file_is_one_clear_line(ros_domain, tmp_path, content, expect):
    bad = tmp_path / "bad.yaml"
    bad.write_text(content)
    r = _run_node(["mocap_ingest", "--ros-args", "--params-file", str(bad)], tmp_path)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert str(bad) in lines[0]
    import re
    assert re.search(expect, lines[0]), lines[0]


def test_missing_params_file(ros_domain, tmp_path):
    r = _run_node(["recorder", "--ros-args", "--params-file", str(tmp_path / "nope.yaml")], tmp_path)
    assert r.returncode == 2 and "nope.yaml" in r.stderr and "cannot read" in r.stderr


def test_launch_file_errors_name_the_line(tmp_path, capsys):
    from euc_ros.cli.main import main

    f = tmp_path / "l.launch.xml"
    f.write_text('<launch>\n  <node pkg="euc_ros" exec="recorder" paramz="1"/>\n</launch>\n')
    assert main(["launch", str(f)]) == 2
    assert f"{f}, line 2: <node exec=\"recorder\">: unsupported attribute 'paramz'" in capsys.readouterr().err


def test_required_node_death_gives_nonzero(ros_domain, tmp_path):
    # mocap_ingest with source csv and no csv_path fails at start-up: the launch returns 1
    code_specs = [NodeSpec("mocap_ingest", parameters={"source": "csv"})]
    from euc_ros.ros.launcher import run
    assert run(code_specs, duration=30, stream=io.StringIO()) == 1


def test_a_clean_end_waits_for_the_others_to_finish_their_work(tmp_path):
    """settle(): a node still busy (a backlog: a whole core) is waited for, an idle one is not; measured on real
    processes by their CPU time (the busy one works 1.5 s of CPU, then sleeps)."""
    launcher = Launcher([])
    busy = "import time\nt = time.process_time()\nwhile time.process_time() - t < 1.5: pass\ntime.sleep(60)"
    for label, code in (("busy", busy), ("idle", "import time; time.sleep(60)")):
        launcher.procs[label] = subprocess.Popen([sys.executable, "-c", code], start_new_session=True)
    try:
        waited = launcher.settle(max_s=15.0)
        # the busy one's 1.5 s of CPU (longer in wall time on a loaded machine) plus two windows at most
        assert 1.2 <= waited < 14.0, waited
        busy_cpu = psutil.Process(launcher.procs["busy"].pid).cpu_times()
        assert busy_cpu.user + busy_cpu.system >= 1.4
        t0 = time.monotonic()
        assert launcher.settle(max_s=15.0) < 1.0          # both idle now: two windows
        assert time.monotonic() - t0 < 1.5
    finally:
        launcher.shutdown(sigint_grace_s=1.0, sigterm_grace_s=1.0)
    assert all(p.poll() is not None for p in launcher.procs.values())
