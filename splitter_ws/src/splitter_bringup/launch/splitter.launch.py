"""ROS 2 launch file for full ROS installs: the same graph as ``splitter launch``.

    ros2 launch splitter_bringup splitter.launch.py scenario:=spin_stabilization
    ros2 launch splitter_bringup splitter.launch.py scenario:=lunar_jumping record:=true

The parameters of every node come from the scenario through the same
``splitter_bringup.scenario.graph_config`` the ``splitter`` launcher uses, so both
start identical graphs. (Not runnable where launch/launch_ros are not installed,
as on the project's CI machines: there ``splitter launch`` does the same job.)
"""

from __future__ import annotations

from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, SetEnvironmentVariable
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from splitter_bringup.scenario.definition import load_scenario
from splitter_bringup.scenario.graph_config import graph_nodes
from splitter_msgs_py.environment import loopback_profile_path

# node name -> (package, executable) of the console scripts in setup.cfg
EXECUTABLES = {
    "recorder": ("splitter_bag", "recorder"),
    "inertial_morphing_mpc": ("splitter_mpc", "inertial_morphing_mpc"),
    "ik_tether_allocator": ("splitter_ik", "ik_tether_allocator"),
    "gait_phase_manager": ("splitter_mpc", "gait_phase_manager"),
    "simulator": ("splitter_sim", "simulator"),
}


def _nodes(context, *args, **kwargs) -> list:
    scenario = load_scenario(
        LaunchConfiguration("scenario").perform(context),
        LaunchConfiguration("variant").perform(context) or None,
    )
    record = LaunchConfiguration("record").perform(context).lower() == "true"
    bag_dir = Path(LaunchConfiguration("bag").perform(context)) if record else None
    real_time = LaunchConfiguration("real_time").perform(context).lower() == "true"
    actions = []
    for node in graph_nodes(scenario, real_time=real_time, bag_dir=bag_dir):
        package, executable = EXECUTABLES[node.name]
        actions.append(
            Node(
                package=package,
                executable=executable,
                name=node.name,
                parameters=[dict(node.parameters)],
                output="screen",
            )
        )
    return actions


def generate_launch_description() -> LaunchDescription:
    """Scenario, variant, recording and pacing as launch arguments."""
    return LaunchDescription(
        [
            DeclareLaunchArgument("scenario", default_value="lunar_jumping"),
            DeclareLaunchArgument("variant", default_value=""),
            DeclareLaunchArgument("record", default_value="false"),
            DeclareLaunchArgument("bag", default_value="splitter_bag"),
            DeclareLaunchArgument("real_time", default_value="false"),
            # loopback-only DDS unless the caller opts in by overriding these
            SetEnvironmentVariable("FASTRTPS_DEFAULT_PROFILES_FILE", str(loopback_profile_path())),
            SetEnvironmentVariable("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET"),
            OpaqueFunction(function=_nodes),
        ]
    )
