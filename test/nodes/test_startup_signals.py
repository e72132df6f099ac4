"""A node executable stopped by SIGINT or SIGTERM while it starts exits 0 with one line at most, no traceback.

``euc-ros launch`` stops its nodes with SIGINT; a node still importing numpy, scipy and rclpy must not
print a KeyboardInterrupt traceback (~15-35 lines each, ~110 for a launch), exit non-zero, or die
by SIGTERM with -15. The node console scripts (the ones of the shared environment, running this tree's
code through PYTHONPATH) are started and signalled 0-0.4 s after the handlers are in place (seen in
/proc: the process catches SIGTERM, which Python alone does not), inside their imports on this class
of machine, and once more after they run. The first ~60 ms of a process (the interpreter's own
start-up and its site packages, before any module of the package is imported; longer on a loaded
host) are not covered.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from euc_ros.ros import startup

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def catches(pid: int, sig: int) -> bool:
    """Whether process ``pid`` has a handler for ``sig`` (``SigCgt`` of /proc/<pid>/status)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    mask = int(next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), 16)
    return bool(mask >> (int(sig) - 1) & 1)


def run_and_signal(argv: list[str], sig: int, after_s: float) -> tuple[int, str]:
    """Start ``argv``, wait until it catches SIGTERM (our handlers are in), then ``after_s``, then send ``sig``."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               PYTHONUNBUFFERED="1", RCUTILS_LOGGING_BUFFERED_STREAM="0")
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env,
                            text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 20.0
        while not catches(proc.pid, signal.SIGTERM) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.002)
        assert catches(proc.pid, signal.SIGTERM), "the handlers were never installed"
        time.sleep(after_s)
        proc.send_signal(sig)
        out, _ = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return proc.returncode, out


def executable(name: str) -> str:
    path = BIN / name
    if not path.exists():
        pytest.skip(f"{path} is not installed (pip install -e . makes the node console scripts)")
    return str(path)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("after_s", [0.0, 0.1, 0.3])
def test_monitor_stopped_while_starting_exits_quietly(ros_domain, sig, after_s):
    code, out = run_and_signal([executable("monitor")], sig, after_s)
    lines = out.strip().splitlines()
    assert code == 0 and "Traceback" not in out and len(lines) <= 1, (code, out)
    assert not lines or lines == [f"monitor: {signal.Signals(sig).name} while starting: stopped"], out


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
@pytest.mark.parametrize("after_s", [0.05, 0.3, 3.0])
def test_mocap_ingest_stopped_while_starting_or_running_exits_0(ros_domain, sig, after_s):
    code, out = run_and_signal([executable("mocap_ingest"), "--ros-args", "-p", "source:=topics",
                                "-p", "bodies:=[E]"], sig, after_s)
    assert code == 0 and "Traceback" not in out, (code, out)
    if after_s < 1.0 and "assembling frames" not in out:         # still starting: one line
        assert len(out.strip().splitlines()) <= 1, out


def test_the_handlers_apply_to_the_node_executables_only():
    setup_py = (REPO / "setup.py").read_text(encoding="utf-8")
    scripts = set(re.findall(r'"(\w+)": "euc_ros\.nodes\.\w+:main"', setup_py))
    from euc_ros.ros.registry import NODES

    assert startup.NODE_EXECUTABLES == scripts == set(NODES) | {"pipeline_container"}
    assert not startup.install_for(["/usr/bin/pytest"]) and not startup.is_installed()
    assert not startup.install_for([]) and not startup.install_for(["-c"])


def test_a_node_executable_gets_them_before_its_node_module(tmp_path):
    """``euc_ros.nodes`` installs them for ``argv[0]`` a node executable; importing it does not load rclpy."""
    probe = ("import signal, sys; sys.argv[0] = '/opt/ros/lib/euc_ros/rider_state'; import euc_ros.nodes; "
             "from euc_ros.ros import startup; "
             "print(startup.is_installed(), signal.getsignal(signal.SIGTERM) is startup._handler, "
             "'rclpy' in sys.modules, 'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60,
                         env=dict(os.environ, PYTHONPATH=str(REPO)))
    assert out.stdout.split() == ["True", "True", "False", "False"], out.stderr
