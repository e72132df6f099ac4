"""Shared fixtures: a unique ROS domain per test run, rclpy contexts, the shared data folder."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: ../shared next to the repository (papers, spec, real Motive exports); never needed at run time.
SHARED = Path(os.environ.get("EUC_ROS_SHARED", REPO.parent / "shared"))
MOTIVE_REAL = SHARED / "data" / "motive_real"


#: Test folders whose tests run ROS nodes against wall-clock timing (discovery, start-up, streams): on the
#: suite's worker processes (pytest-xdist) they all go to one worker, one at a time, as in a serial run;
#: the other files are spread over the workers file by file (:func:`pytest_xdist_make_scheduler`).
ROS_TIMED = ("test/integration/", "test/nodes/")
#: ... but for these: end-to-end command runs in process, without a ROS graph (CPU-bound, spread as the unit tests).
NOT_ROS_TIMED = ("test/integration/cli/",)


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "shared" in item.keywords and not MOTIVE_REAL.is_dir():
            item.add_marker(pytest.mark.skip(reason=f"{MOTIVE_REAL} is absent (shared data is not part of the repo)"))


@pytest.hookimpl(optionalhook=True)      # a hook of pytest-xdist: no error where it is not loaded
def pytest_xdist_make_scheduler(config, log):
    """Whole files to the workers, and every :data:`ROS_TIMED` test (not :data:`NOT_ROS_TIMED`) to one of them."""
    from xdist.scheduler import LoadScopeScheduling

    class Scheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return "ros_timed" if path.startswith(ROS_TIMED) and not path.startswith(NOT_ROS_TIMED) else path

    return Scheduling(config, log)


@pytest.fixture(scope="session")
def ros_domain():
    """Reserve a ROS_DOMAIN_ID for this test run (host-wide, via domain_coordinator) and export it."""
    from domain_coordinator import domain_id

    from euc_ros.bench.common import environ

    with domain_id() as did, environ({"ROS_DOMAIN_ID": did, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}):
        yield did


def _private_context(domain: int):
    """A private rclpy Context on ``domain`` (yields it; shut down after)."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


@pytest.fixture
def ros_context(ros_domain):
    """A private rclpy Context on the run's domain, shut down after the test."""
    yield from _private_context(ros_domain)


@pytest.fixture
def other_ros_context(ros_domain):
    """A second private Context (a participant of its own: DDS refuses two types on one topic in one)."""
    yield from _private_context(ros_domain)


@pytest.fixture(scope="session")
def layout_topics() -> set[str]:
    """Every topic the Foxglove layout (config/foxglove/euc_pipeline.json) names: 3D panel topics, plot paths,
    diagnostics panels."""
    import json

    layout = json.loads((REPO / "config" / "foxglove" / "euc_pipeline.json").read_text(encoding="utf-8"))
    topics = set()
    for cfg in layout["configById"].values():
        topics.update(cfg.get("topics", {}))
        topics.update(p["value"].split(".")[0] for p in cfg.get("paths", []))
        if "topicToRender" in cfg:
            topics.add(cfg["topicToRender"])
    return topics


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """The ../shared folder (tests using it are marked ``shared`` and skip where it is absent)."""
    return SHARED


@pytest.fixture(scope="session", autouse=True)
def no_processes_left_behind():
    """After the run, kill and report any child process a test left alive (node, launcher...)."""
    yield
    import psutil

    leftovers = psutil.Process().children(recursive=True)
    for proc in leftovers:
        try:
            proc.kill()
        except psutil.NoSuchProcess:
            pass
    if leftovers:
        names = ", ".join(f"{p.pid}" for p in leftovers)
        raise RuntimeError(f"processes left behind by the tests (killed): {names}")


@pytest.fixture(scope="session")
def short_ride(tmp_path_factory):
    """A 3 s deceleration run (Motive CSV, session.yaml, truth) written by the ride simulator."""
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    out = tmp_path_factory.mktemp("short_ride")
    result = simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=3, duration_s=3.0))
    write_ride(result, out)
    return out, result


NPM_NETWORK_ERRORS = ("ENOTFOUND", "EAI_AGAIN", "ETIMEDOUT", "ECONNREFUSED", "ECONNRESET", "network")


@pytest.fixture(scope="session")
def npm_tool():
    """``install(tool_dir, marker, script, purpose) -> Path``: a tools/ folder's pinned npm packages
    (``npm ci`` of its lock file, cached by the lock's hash) with its script beside them; skips with the
    reason where node, npm or the registry are absent."""
    import fcntl
    import hashlib
    import shutil
    import subprocess

    def install(tool_dir: Path, marker: str, script: str, purpose: str) -> Path:
        node, npm = shutil.which("node"), shutil.which("npm")
        if node is None or npm is None:
            pytest.skip(f"node and npm are needed for {purpose} (Node 20)")
        lock = (tool_dir / "package-lock.json").read_bytes()
        cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "euc_ros" / tool_dir.name / \
            hashlib.sha256(lock).hexdigest()[:16]
        cache.mkdir(parents=True, exist_ok=True)
        # one install at a time: the suite's worker processes may ask for the same tool at once
        with open(cache.parent / f"{cache.name}.lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            if not (cache / "node_modules" / marker).is_dir():
                for name in ("package.json", "package-lock.json"):
                    shutil.copy(tool_dir / name, cache / name)
                r = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--ignore-scripts"], cwd=cache,
                                   capture_output=True, text=True, timeout=600)
                if r.returncode != 0:
                    if any(e in r.stderr for e in NPM_NETWORK_ERRORS):
                        pytest.skip(f"the npm registry is unreachable: {r.stderr.strip().splitlines()[-1]}")
                    pytest.fail(f"npm ci failed (lock file or packages broken):\n{r.stderr[-3000:]}")
            shutil.copy(tool_dir / script, cache / script)
        return cache

    return install


@pytest.fixture
def looping_launch(short_ride, tmp_path):
    """``(launch file, bag)``: a recorder and a mocap_ingest looping the short ride's CSV (it waits for the
    recorder's subscription), as a ROS 2 XML launch file."""
    config = Path(__file__).resolve().parents[1] / "config"
    ride_dir, _ = short_ride
    bag = tmp_path / "bag"
    launch_file = tmp_path / "two.launch.xml"
    launch_file.write_text(f"""<launch>
  <node pkg="euc_ros" exec="recorder" output="screen" on_exit="shutdown">
    <param from="{config / 'recorder.yaml'}"/>
    <param name="output" value="{bag}" type="str"/>
  </node>
  <node pkg="euc_ros" exec="mocap_ingest" output="screen" on_exit="shutdown">
    <param from="{config / 'mocap_ingest.yaml'}"/>
    <param name="csv_path" value="{ride_dir / 'deceleration_01.csv'}" type="str"/>
    <param name="loop" value="true"/>
    <param name="start_delay" value="0.5"/>
    <param name="wait_subscribers" value="1"/>
  </node>
</launch>
""")
    return launch_file, bag
