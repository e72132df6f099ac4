"""Record the pipeline's topics (or any list, or all) into a rosbag2 bag with MCAP storage.

    ros2 launch euc_ros record.launch.py bag:=bags/session_03
    ros2 launch euc_ros record.launch.py bag:=bags/all all_topics:=true

Closed cleanly on Ctrl-C. Mirrors launch/record.yaml (``euc-ros launch`` on wheel installs).
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription([
        DeclareLaunchArgument("bag", description="bag directory to create (must not exist)"),
        DeclareLaunchArgument("topics", default_value="['mocap/frame', 'rider/state', 'euc/torque', '/diagnostics', '/tf']",
                              description="topics to record"),
        DeclareLaunchArgument("all_topics", default_value="false", choices=["true", "false"],
                              description="record every topic that appears"),
        Node(package="euc_ros", executable="recorder", name="recorder", output="screen",
             parameters=[PathJoinSubstitution([FindPackageShare("euc_ros"), "config", "recorder.yaml"]), {
                 "output": LaunchConfiguration("bag"),
                 "topics": LaunchConfiguration("topics"),
                 "all_topics": LaunchConfiguration("all_topics"),
             }]),
    ])
