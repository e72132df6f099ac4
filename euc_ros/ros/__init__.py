"""The ROS layer: everything that knows rclpy or ROS messages, below the nodes and the CLI.

The nodes in :mod:`euc_ros.nodes` are wiring only; what they share (executor, runtime, parameters,
interfaces, message conversion, intra-process fan-out, the launcher) lives here. The core
(:mod:`euc_ros.core`) never imports this package.
"""
