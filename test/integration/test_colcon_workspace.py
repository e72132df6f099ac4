"""The README's colcon recipe, run as written on a temporary workspace.

A lab clones euc_ros into ``src/`` of a ROS 2 Jazzy workspace and builds with colcon. Here the ROS
underlay is this environment's PyPI wheels instead of /opt/ros/jazzy, so two things differ from a
real install, and only these: the underlay is the venv (CMAKE_PREFIX_PATH / AMENT_PREFIX_PATH, as
``source /opt/ros/jazzy/setup.bash`` would set them), and the wheels need our CMake fix-up
(``--cmake-args``, README "ROS 2 from PyPI"). The ``colcon build`` line itself is taken from the README.

``ros2`` (ros2cli) is not on PyPI either: ``ros2 run`` is emulated by the lookup it does (the package's
prefix from the ament index, then ``<prefix>/lib/<package>/<executable>``); ``ros2 launch euc_ros FILE``
by ``euc-ros launch euc_ros FILE``, which reads the same XML launch file from the installed
``share/euc_ros/launch/`` (test/unit/test_launch_files.py holds the files to what Jazzy's launch reads).

Limit: the venv underlay already holds euc_msgs (``./run setup`` builds it there), and the wheels'
start-up hook puts the venv's lib/ first on LD_LIBRARY_PATH, so the C type-support libraries load from
the venv; the Python package euc_msgs and everything of euc_ros are checked to come from install/.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from euc_ros.core.io.bags import check_bag, read_bag
from euc_ros.ros.registry import NODES

pytestmark = [pytest.mark.ros, pytest.mark.integration, pytest.mark.slow]
REPO = Path(__file__).resolve().parents[2]
VENV = Path(sys.executable).parent.parent
COLCON = Path(sys.executable).parent / "colcon"

# ros2 run's lookup, for a shell without ros2cli: the first AMENT_PREFIX_PATH entry that indexes the package;
# ros2 launch PACKAGE FILE: euc-ros launch, which takes the same form
ROS2_RUN = r'''
ros2() {
  [ "$1" = launch ] && { shift; euc-ros launch "$@"; return $?; }
  [ "$1" = run ] || { echo "ros2 $1: not available here (ros2cli is not on PyPI)" >&2; return 2; }
  local pkg="$2" exe="$3"; shift 3
  local IFS=:
  for prefix in $AMENT_PREFIX_PATH; do
    if [ -e "$prefix/share/ament_index/resource_index/packages/$pkg" ]; then
      unset IFS; "$prefix/lib/$pkg/$exe" "$@"; return $?
    fi
  done
  echo "Package '$pkg' not found" >&2; return 1
}
'''


def readme_recipe() -> list[str]:
    """The commands of the README's colcon recipe block."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- colcon-recipe -->\s*```bash\n(.*?)```", text, re.S)
    assert m, "README has no <!-- colcon-recipe --> block"
    return [ln.split("  #")[0].strip() for ln in m.group(1).splitlines() if ln.strip() and not ln.startswith("#")]


def copy_sources(dst: Path) -> None:
    """The repository as a clone would have it (tracked files only where git is available)."""
    try:
        files = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True).stdout
        names = [n for n in files.decode().split("\0") if n]
    except (OSError, subprocess.CalledProcessError):
        names = None
    if names:
        for name in names:
            if (REPO / name).is_file():
                (dst / name).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(REPO / name, dst / name)
    else:
        shutil.copytree(REPO, dst, ignore=shutil.ignore_patterns(".venv", "build", "install", "log", ".git",
                                                                  "__pycache__", "*.pyc"))


def clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("LD_LIBRARY_PATH", "_ROS_WHEELS_BOOTSTRAP_COMPLETE", "PYTHONPATH", "AMENT_PREFIX_PATH",
                        "CMAKE_PREFIX_PATH", "COLCON_PREFIX_PATH")}
    # the underlay: what `source /opt/ros/jazzy/setup.bash` sets on a real install
    env.update(PATH=f"{VENV / 'bin'}:{env.get('PATH', '/usr/bin:/bin')}", AMENT_PREFIX_PATH=str(VENV),
               CMAKE_PREFIX_PATH=str(VENV))
    return env


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    if not COLCON.exists():
        pytest.skip(f"colcon is not installed in {VENV} (requirements-build.txt; ./run setup)")
    if shutil.which("cmake") is None or shutil.which("ninja") is None:
        pytest.skip("cmake and ninja are needed to build euc_msgs")
    ws = tmp_path_factory.mktemp("euc_ws")
    copy_sources(ws / "src" / "euc_ros")
    recipe = readme_recipe()
    build = [c for c in recipe if c.startswith("colcon build")]
    assert len(build) == 1, recipe
    listing = subprocess.run([str(COLCON), "list", "--names-only", *shlex.split(build[0])[2:]], cwd=ws,
                             env=clean_env(), capture_output=True, text=True, timeout=120)
    wheel_args = ["--cmake-args", f"-DCMAKE_PROJECT_INCLUDE={REPO / 'cmake' / 'ros_wheels_fixup.cmake'}",
                  f"-DPython3_EXECUTABLE={sys.executable}", "-DBUILD_TESTING=OFF"]
    r = subprocess.run([str(COLCON), *shlex.split(build[0])[1:], *wheel_args], cwd=ws, env=clean_env(),
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]
    return ws, recipe, listing.stdout.split()


def in_sourced_shell(ws: Path, script: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-c", f"set -e\nsource install/setup.bash\n{ROS2_RUN}\n{script}"], cwd=ws,
                          env=clean_env(), capture_output=True, text=True, timeout=timeout)


def test_colcon_finds_both_packages_and_not_the_tf2_msgs_copy(workspace):
    ws, recipe, names = workspace
    assert sorted(names) == ["euc_msgs", "euc_ros"]            # extra_interfaces/tf2_msgs is not built
    assert "source install/setup.bash" in recipe
    assert not (ws / "install" / "tf2_msgs").exists()


def test_install_space_has_nodes_launch_files_and_config(workspace):
    ws, _, _ = workspace
    prefix = ws / "install" / "euc_ros"
    assert sorted(p.name for p in (prefix / "lib" / "euc_ros").iterdir() if p.name in NODES) == sorted(NODES)
    assert (prefix / "bin" / "euc-ros").exists()
    launch = {p.name for p in (prefix / "share" / "euc_ros" / "launch").iterdir()}
    assert launch == {"pipeline.launch.xml", "unicycle.launch.xml", "record.launch.xml", "replay.launch.xml"}
    assert {f"{n}.yaml" for n in NODES} <= {p.name for p in (prefix / "share" / "euc_ros" / "config").iterdir()}


def test_sourced_install_space_imports_from_install(workspace):
    ws, _, _ = workspace
    r = in_sourced_shell(ws, "python -c 'import euc_msgs.msg, euc_ros, euc_ros.ros.launcher as l, "
                             "euc_ros.ros.launch_file as f; "
                             "print(euc_msgs.msg.__file__); print(euc_ros.__file__); "
                             "print(l.resolve_executable(\"mocap_ingest\")); print(f.package_share())'\n"
                             "command -v euc-ros")
    assert r.returncode == 0, r.stderr
    install = str(ws / "install")
    lines = r.stdout.split()
    assert all(line.startswith(install) for line in lines), lines
    assert lines[2] == f"{install}/euc_ros/lib/euc_ros/mocap_ingest"      # what ros2 run would start
    assert lines[3] == f"{install}/euc_ros/share/euc_ros"                  # $(find-pkg-share euc_ros)
    assert lines[4] == f"{install}/euc_ros/bin/euc-ros"                    # euc-ros on the PATH


def test_ros2_run_starts_a_node_from_the_install_space(workspace):
    ws, recipe, _ = workspace
    assert any(c.startswith("ros2 run euc_ros ") for c in recipe)
    # the closed-loop unicycle in two processes, both started the way `ros2 run` does
    r = in_sourced_shell(ws, "ros2 run euc_ros steering_controller --ros-args -p maneuver:=turn & job=$!\n"
                             "ros2 run euc_ros unicycle_sim --ros-args -p duration:=1.0\n"
                             "pkill -TERM -P $job; wait $job", timeout=120)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert re.search(r"\[unicycle_sim\]: simulation ended at t = 1\.000 s after 100 steps: ok", r.stderr), r.stderr
    assert "[steering_controller]: turn at 1 m/s" in r.stderr


def test_readme_launch_line_names_an_installed_launch_file(workspace):
    ws, recipe, _ = workspace
    launches = [shlex.split(c) for c in recipe if c.startswith("ros2 launch euc_ros ")]
    assert launches, recipe
    installed = {p.name for p in (ws / "install" / "euc_ros" / "share" / "euc_ros" / "launch").iterdir()}
    assert {c[3] for c in launches} <= installed, (launches, installed)


def test_installed_pipeline_launch_records_a_ride(workspace, short_ride, ros_domain):
    ws, _, _ = workspace
    ride_dir, _ = short_ride
    bag = ws / "bag"
    # as ros2 launch is written; the file comes from install/euc_ros/share/euc_ros/launch
    r = in_sourced_shell(ws, f"ros2 launch euc_ros pipeline.launch.xml session:={ride_dir / 'session.yaml'} h:=0.61 "
                             f"source:=csv csv_path:={ride_dir / 'deceleration_01.csv'} rate_factor:=2 "
                             f"exit_when_done:=true bag:={bag}", timeout=180)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert check_bag(bag) == []
    topics = {t for t, *_ in read_bag(bag)}
    assert {"/mocap/frame", "/rider/state", "/euc/torque", "/diagnostics"} <= topics
