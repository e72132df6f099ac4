"""Every node of the package: console-script name -> node class path (lazy, no rclpy import here)."""
from __future__ import annotations

import importlib

NODES: dict[str, str] = {
    "mocap_ingest": "euc_ros.nodes.mocap_ingest:MocapIngest",
    "rider_state": "euc_ros.nodes.rider_state:RiderStateNode",
    "torque_estimator": "euc_ros.nodes.torque_estimator:TorqueEstimatorNode",
    "monitor": "euc_ros.nodes.monitor:Monitor",
    "recorder": "euc_ros.nodes.recorder:Recorder",
    "unicycle_sim": "euc_ros.nodes.unicycle_sim:UnicycleSim",
    "steering_controller": "euc_ros.nodes.steering_controller:SteeringControllerNode",
}


def node_class(name: str):
    """Import and return the node class registered as ``name``."""
    module, cls = NODES[name].split(":")
    return getattr(importlib.import_module(module), cls)


def write_default_configs(config_dir: str = "config", names=None) -> list[str]:
    """(Re)write ``config/<node>.yaml`` from the nodes' ParamSpec tables; returns the paths."""
    from pathlib import Path

    from euc_ros.ros.params import render_params_yaml

    out = []
    for name in names or NODES:
        try:
            cls = node_class(name)
        except ModuleNotFoundError:
            continue
        path = Path(config_dir) / f"{name}.yaml"
        path.write_text(render_params_yaml(cls.NAME, cls.SPECS), encoding="utf-8")
        out.append(str(path))
    return out


if __name__ == "__main__":
    print("\n".join(write_default_configs()))
