"""The ament_python layout colcon installs: `ros2 run euc_ros <node>` finds the
node executables in lib/euc_ros, the package is indexed, and its config is in share/euc_ros.

colcon-python-setup-py installs with `setup.py install --single-version-externally-managed`; this
runs that step on a copy of the package into a temporary prefix.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def test_setup_py_install_puts_the_nodes_where_ros2_run_looks(tmp_path):
    pytest.importorskip("setuptools")
    src = tmp_path / "src"
    src.mkdir()
    for name in ("setup.py", "setup.cfg", "package.xml"):
        shutil.copy(REPO / name, src / name)
    for name in ("resource", "config", "launch", "euc_ros"):
        shutil.copytree(REPO / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    prefix = tmp_path / "install"
    r = subprocess.run([sys.executable, "setup.py", "-q", "install", "--prefix", str(prefix),
                        "--single-version-externally-managed", "--record", str(tmp_path / "record.txt")],
                       cwd=src, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    from euc_ros.ros.registry import NODES

    lib = prefix / "lib" / "euc_ros"
    assert sorted(p.name for p in lib.iterdir() if p.name in NODES) == sorted(NODES)
    assert (lib / "euc-ros").exists()
    assert (prefix / "bin" / "euc-ros").exists()             # the CLI stays on the sourced PATH
    assert str(prefix / "bin" / "euc-ros") in (tmp_path / "record.txt").read_text()   # uninstallable
    launch = prefix / "share" / "euc_ros" / "launch"
    assert {p.name for p in launch.iterdir()} == {p.name for p in (REPO / "launch").iterdir()
                                                  if p.name.endswith(".launch.xml")}
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / "euc_ros").exists()
    assert (prefix / "share" / "euc_ros" / "package.xml").exists()
    assert {p.name for p in (prefix / "share" / "euc_ros" / "config").glob("*.yaml")} >= {f"{n}.yaml" for n in NODES}
    # $(find-pkg-share euc_ros) of the installed package is its share directory, not a source tree
    site = next(prefix.glob("lib/python3*/site-packages"))
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "AMENT_PREFIX_PATH")}
    env["PYTHONPATH"] = str(site)
    r = subprocess.run([sys.executable, "-c", "from euc_ros.ros.launch_file import find_launch_file, package_share; "
                        "print(package_share()); print(find_launch_file('pipeline.launch.xml'))"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == [str(prefix / "share" / "euc_ros"), str(launch / "pipeline.launch.xml")]
