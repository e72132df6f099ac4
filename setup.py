"""Packaging of euc_ros (ament_python layout; installed with pip in the project venv)."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "euc_ros"

NODES = {
    "mocap_ingest": "euc_ros.nodes.mocap_ingest:main",
    "rider_state": "euc_ros.nodes.rider_state:main",
    "torque_estimator": "euc_ros.nodes.torque_estimator:main",
    "monitor": "euc_ros.nodes.monitor:main",
    "recorder": "euc_ros.nodes.recorder:main",
    "unicycle_sim": "euc_ros.nodes.unicycle_sim:main",
    "steering_controller": "euc_ros.nodes.steering_controller:main",
}

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=[PACKAGE, PACKAGE + ".*"]),
    package_data={PACKAGE: ["data/*", "config/*.yaml"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
        ("share/" + PACKAGE + "/config", glob("config/*.yaml")),
    ],
    python_requires=">=3.11",
    install_requires=[],  # pinned in requirements.txt; ROS 2 comes from the ros-jazzy-* wheels
    zip_safe=False,
    maintainer="euc_ros developers",
    description="ROS 2 Jazzy package for motion-capture processing and electric-unicycle monitoring",
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["euc-ros = euc_ros.cli.main:main"]
        + [f"{name} = {target}" for name, target in NODES.items()],
    },
)
