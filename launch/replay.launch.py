"""Replay a recorded bag through the estimation half of the pipeline, optionally recording the result.

    ros2 launch euc_ros replay.launch.py in_bag:=bags/ride session:=session.yaml bag:=bags/ride_reprocessed

``euc-ros play`` publishes the bag's mocap/frame with its recorded timing (x ``rate``) once rider_state and
monitor have subscribed and ``start_delay`` has passed;
rider_state, torque_estimator and monitor recompute states, torques and diagnostics from it. Only the
mocap frames are replayed, so nothing recorded earlier is published twice.
Mirrors launch/replay.yaml (``euc-ros launch`` on wheel installs).
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, Shutdown
from launch.conditions import LaunchConfigurationNotEquals
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def _params_file(node: str):
    return PathJoinSubstitution([FindPackageShare("euc_ros"), "config", f"{node}.yaml"])


def generate_launch_description() -> LaunchDescription:
    session = LaunchConfiguration("session")
    return LaunchDescription([
        DeclareLaunchArgument("in_bag", description="bag to replay (directory or .mcap)"),
        DeclareLaunchArgument("session", description="session YAML of the recording"),
        DeclareLaunchArgument("rate", default_value="1.0", description="replay speed (2 = twice as fast)"),
        DeclareLaunchArgument("start_delay", default_value="3.0",
                              description="wait after the first subscriptions before playing, so that all "
                                          "processes have discovered each other [s]"),
        DeclareLaunchArgument("h", default_value="0.61", description="rider CoG height above the hinge h [m]"),
        DeclareLaunchArgument("bag", default_value="", description="record the recomputed topics here (empty: none)"),
        Node(package="euc_ros", executable="recorder", name="recorder", output="screen",
             condition=LaunchConfigurationNotEquals("bag", ""),
             parameters=[_params_file("recorder"), {"output": LaunchConfiguration("bag")}]),
        Node(package="euc_ros", executable="monitor", name="monitor", output="screen",
             parameters=[_params_file("monitor")]),
        Node(package="euc_ros", executable="torque_estimator", name="torque_estimator", output="screen",
             parameters=[_params_file("torque_estimator"), {"session_file": session,
                                                             "h": LaunchConfiguration("h")}]),
        Node(package="euc_ros", executable="rider_state", name="rider_state", output="screen",
             parameters=[_params_file("rider_state"), {"session_file": session}]),
        ExecuteProcess(cmd=["euc-ros", "play", LaunchConfiguration("in_bag"), "--rate", LaunchConfiguration("rate"),
                            "--topics", "mocap/frame", "--wait-subscribers", "2",
                            "--delay", LaunchConfiguration("start_delay"), "--linger", "2.0"],
                       name="play", output="screen", on_exit=Shutdown(reason="replay finished")),
    ])
