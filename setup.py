"""Packaging of euc_ros (ament_python layout; installed with pip in the project venv)."""
from glob import glob

import os
import shutil

from setuptools import find_packages, setup
from setuptools.command.install_scripts import install_scripts


PACKAGE = "euc_ros"

NODES = {
    "mocap_ingest": "euc_ros.nodes.mocap_ingest:main",
    "rider_state": "euc_ros.nodes.rider_state:main",
    "torque_estimator": "euc_ros.nodes.torque_estimator:main",
    "monitor": "euc_ros.nodes.monitor:main",
    "recorder": "euc_ros.nodes.recorder:main",
    "unicycle_sim": "euc_ros.nodes.unicycle_sim:main",
    "steering_controller": "euc_ros.nodes.steering_controller:main",
    "pipeline_container": "euc_ros.nodes.container:main",
}

CLI = "euc-ros"


class InstallScripts(install_scripts):
    """ament_python layout (setup.cfg): node executables in ``<prefix>/lib/euc_ros`` for ``ros2 run``;
    the ``euc-ros`` command also in ``<prefix>/bin``, which the sourced install space puts on PATH."""

    def run(self):
        super().run()
        here = os.path.normpath(self.install_dir)
        if os.path.basename(here) != PACKAGE or os.path.basename(os.path.dirname(here)) != "lib":
            return   # pip (wheel, editable): scripts already in the environment's bin/
        src = os.path.join(here, CLI)
        if os.path.exists(src):
            bindir = os.path.join(os.path.dirname(os.path.dirname(here)), "bin")
            os.makedirs(bindir, exist_ok=True)
            shutil.copy2(src, os.path.join(bindir, CLI))
            self.outfiles.append(os.path.join(bindir, CLI))


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=[PACKAGE, PACKAGE + ".*"]),
    package_data={PACKAGE: ["data/*", "config/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
        ("share/" + PACKAGE + "/config", glob("config/*.yaml")),
        ("share/" + PACKAGE + "/launch", glob("launch/*.launch.xml")),
    ],
    python_requires=">=3.11",
    install_requires=[],  # pinned in requirements.txt; ROS 2 comes from the ros-jazzy-* wheels
    zip_safe=False,
    maintainer="euc_ros developers",
    description="ROS 2 Jazzy package for motion-capture processing and electric-unicycle monitoring",
    license="Apache-2.0",
    cmdclass={"install_scripts": InstallScripts},
    entry_points={
        "console_scripts": [f"{CLI} = euc_ros.cli.main:main"]
        + [f"{name} = {target}" for name, target in NODES.items()],
    },
)
