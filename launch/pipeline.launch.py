"""The EUC pipeline: mocap_ingest -> rider_state -> torque_estimator, monitor, and a recorder.

    ros2 launch euc_ros pipeline.launch.py session:=/path/session.yaml source:=natnet server_ip:=192.168.1.10
    ros2 launch euc_ros pipeline.launch.py session:=session.yaml source:=csv csv_path:=ride.csv bag:=bags/ride
    ros2 launch euc_ros pipeline.launch.py session:=session.yaml source:=topics bodies:="['E','PV','CHL']"
    ros2 launch euc_ros pipeline.launch.py session:=session.yaml compose:=true   # 240 Hz and up: one process

Mirrors launch/pipeline.yaml (``euc-ros launch`` on wheel installs, where launch_ros is absent).
Parameters not set here come from config/<node>.yaml in the package's share directory.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, Shutdown
from launch.conditions import IfCondition, LaunchConfigurationNotEquals, UnlessCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare


def _params_file(node: str):
    return PathJoinSubstitution([FindPackageShare("euc_ros"), "config", f"{node}.yaml"])


def generate_launch_description() -> LaunchDescription:
    session = LaunchConfiguration("session")
    compose = LaunchConfiguration("compose")
    return LaunchDescription([
        DeclareLaunchArgument("session", description="session YAML (rider, EUC and marker set; docs/session.md)"),
        DeclareLaunchArgument("source", default_value="natnet", choices=["natnet", "topics", "csv"],
                              description="where poses come from: Motive over NatNet, ROS topics, or a CSV export"),
        DeclareLaunchArgument("server_ip", default_value="127.0.0.1", description="Motive host (source natnet)"),
        DeclareLaunchArgument("local_ip", default_value="0.0.0.0", description="local interface (source natnet)"),
        DeclareLaunchArgument("csv_path", default_value="", description="Motive CSV export to replay (source csv)"),
        DeclareLaunchArgument("rate_factor", default_value="1.0", description="CSV replay speed (source csv)"),
        DeclareLaunchArgument("start_delay", default_value="3.0",
                              description="wait before the first CSV frame, so that all five processes have "
                                          "discovered each other (source csv) [s]"),
        DeclareLaunchArgument("exit_when_done", default_value="false", choices=["true", "false"],
                              description="end the launch when the CSV has been replayed (source csv)"),
        DeclareLaunchArgument("topic_prefix", default_value="/vrpn_mocap",
                              description="prefix of per-body PoseStamped inputs (source topics)"),
        DeclareLaunchArgument("bodies", default_value="['']",
                              description="rigid bodies to publish, in order (required for source topics)"),
        DeclareLaunchArgument("h", default_value="0.61", description="rider CoG height above the hinge h [m]"),
        DeclareLaunchArgument("bag", default_value="", description="record to this bag directory (empty: no recorder)"),
        DeclareLaunchArgument("compose", default_value="false", choices=["true", "false"],
                              description="run mocap_ingest, rider_state and torque_estimator in one "
                                          "pipeline_container process, linked in-process (for 240 Hz and up)"),
        Node(package="euc_ros", executable="mocap_ingest", name="mocap_ingest", output="screen",
             on_exit=Shutdown(reason="mocap_ingest ended"), condition=UnlessCondition(compose),
             parameters=[_params_file("mocap_ingest"), {
                 "session_file": session,
                 "source": LaunchConfiguration("source"),
                 "server_ip": LaunchConfiguration("server_ip"),
                 "local_ip": LaunchConfiguration("local_ip"),
                 "csv_path": LaunchConfiguration("csv_path"),
                 "rate_factor": LaunchConfiguration("rate_factor"),
                 "start_delay": LaunchConfiguration("start_delay"),
                 "exit_when_done": LaunchConfiguration("exit_when_done"),
                 "topic_prefix": LaunchConfiguration("topic_prefix"),
                 "bodies": LaunchConfiguration("bodies"),
             }]),
        Node(package="euc_ros", executable="rider_state", name="rider_state", output="screen",
             condition=UnlessCondition(compose),
             parameters=[_params_file("rider_state"), {"session_file": session}]),
        Node(package="euc_ros", executable="torque_estimator", name="torque_estimator", output="screen",
             condition=UnlessCondition(compose),
             parameters=[_params_file("torque_estimator"), {"session_file": session,
                                                             "h": LaunchConfiguration("h")}]),
        # no name=: it would rename every node of the process; each keeps its own (and its params file section).
        # The ingest parameters are written out again, not shared through a variable: the launch files are
        # checked statically against the YAML mirror and the nodes' declarations (test_launch_files.py).
        Node(package="euc_ros", executable="pipeline_container", output="screen",
             on_exit=Shutdown(reason="pipeline_container ended"), condition=IfCondition(compose),
             arguments=["--nodes", "mocap_ingest,rider_state,torque_estimator"],
             parameters=[_params_file("mocap_ingest"), _params_file("rider_state"), _params_file("torque_estimator"), {
                 "session_file": session,
                 "h": LaunchConfiguration("h"),
                 "source": LaunchConfiguration("source"),
                 "server_ip": LaunchConfiguration("server_ip"),
                 "local_ip": LaunchConfiguration("local_ip"),
                 "csv_path": LaunchConfiguration("csv_path"),
                 "rate_factor": LaunchConfiguration("rate_factor"),
                 "start_delay": LaunchConfiguration("start_delay"),
                 "exit_when_done": LaunchConfiguration("exit_when_done"),
                 "topic_prefix": LaunchConfiguration("topic_prefix"),
                 "bodies": LaunchConfiguration("bodies"),
             }]),
        Node(package="euc_ros", executable="monitor", name="monitor", output="screen",
             parameters=[_params_file("monitor")]),
        Node(package="euc_ros", executable="recorder", name="recorder", output="screen",
             condition=LaunchConfigurationNotEquals("bag", ""),
             parameters=[_params_file("recorder"), {"output": LaunchConfiguration("bag")}]),
    ])
