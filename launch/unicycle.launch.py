"""The closed loop: the simulated autonomous unicycle and its steering controller, optionally recorded.

    ros2 launch euc_ros unicycle.launch.py maneuver:=lane_change speed:=1.0 bag:=bags/lane_change

Mirrors launch/unicycle.yaml (``euc-ros launch`` on wheel installs).
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, Shutdown
from launch.conditions import LaunchConfigurationEquals, LaunchConfigurationNotEquals
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def _params_file(node: str):
    return PathJoinSubstitution([FindPackageShare("euc_ros"), "config", f"{node}.yaml"])


def generate_launch_description() -> LaunchDescription:
    speed = LaunchConfiguration("speed")
    return LaunchDescription([
        DeclareLaunchArgument("maneuver", default_value="lane_change",
                              choices=["lane_change", "turn"],
                              description="what the steering controller makes the unicycle do"),
        DeclareLaunchArgument("speed", default_value="1.0", description="forward speed [m/s]"),
        DeclareLaunchArgument("duration", default_value="10.0", description="simulated time [s]"),
        DeclareLaunchArgument("bag", default_value="", description="record to this bag directory (empty: no recorder)"),
        Node(package="euc_ros", executable="recorder", name="recorder", output="screen",
             condition=LaunchConfigurationNotEquals("bag", ""),
             parameters=[_params_file("recorder"), {
                 "output": LaunchConfiguration("bag"),
                 "topics": ["unicycle/state", "unicycle/command", "unicycle/pose"],
             }]),
        Node(package="euc_ros", executable="steering_controller", name="steering_controller", output="screen",
             parameters=[_params_file("steering_controller"), {
                 "maneuver": LaunchConfiguration("maneuver"), "speed": speed}]),
        # with a recorder, step 0 also waits for the recorder's subscription (wait_observers)
        Node(package="euc_ros", executable="unicycle_sim", name="unicycle_sim", output="screen",
             condition=LaunchConfigurationEquals("bag", ""),
             parameters=[_params_file("unicycle_sim"), {
                 "mode": "lockstep", "speed": speed, "duration": LaunchConfiguration("duration"),
                 "wait_observers": 0}], on_exit=Shutdown(reason="simulation finished")),
        Node(package="euc_ros", executable="unicycle_sim", name="unicycle_sim", output="screen",
             condition=LaunchConfigurationNotEquals("bag", ""),
             parameters=[_params_file("unicycle_sim"), {
                 "mode": "lockstep", "speed": speed, "duration": LaunchConfiguration("duration"),
                 "wait_observers": 1}], on_exit=Shutdown(reason="simulation finished")),
    ])
