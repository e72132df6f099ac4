"""Shared fixtures: a unique ROS domain per test run, rclpy contexts, the shared data folder."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
#: ../shared next to the repository (papers, spec, real Motive exports); never needed at run time.
SHARED = Path(os.environ.get("EUC_ROS_SHARED", REPO.parent / "shared"))
MOTIVE_REAL = SHARED / "data" / "motive_real"


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "shared" in item.keywords and not MOTIVE_REAL.is_dir():
            item.add_marker(pytest.mark.skip(reason=f"{MOTIVE_REAL} is absent (shared data is not part of the repo)"))


@pytest.fixture(scope="session")
def ros_domain():
    """Reserve a ROS_DOMAIN_ID for this test run (host-wide, via domain_coordinator) and export it."""
    from domain_coordinator import domain_id

    from euc_ros.bench.common import environ

    with domain_id() as did, environ({"ROS_DOMAIN_ID": did, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}):
        yield did


@pytest.fixture
def ros_context(ros_domain):
    """A private rclpy Context on the run's domain, shut down after the test."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=ros_domain, signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


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
