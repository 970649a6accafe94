"""The twin on a full ROS 2 Jazzy install: ros2 launch kilobot_twin twin.launch.py robots:=20

Starts recorder, analysis, world and swarm (what `kilobot-twin run` does without a ROS
install, which additionally supervises the processes and prints a summary).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    args = {
        "scenario": "phototaxis",
        "robots": "10",
        "duration": "20.0",
        "seed": "0",
        "mode": "lockstep",
        "traits": "",
        "out": "bags/run",
    }
    cfg = {k: LaunchConfiguration(k) for k in args}
    return LaunchDescription(
        [DeclareLaunchArgument(k, default_value=v) for k, v in args.items()]
        + [
            Node(package="kilobot_twin", executable="recorder", name="recorder", output="screen",
                 parameters=[{"out": ParameterValue(cfg["out"], value_type=str)}]),
            Node(package="kilobot_twin", executable="analysis", name="analysis", output="screen"),
            Node(package="kilobot_twin", executable="world", name="world", output="screen",
                 parameters=[{"scenario": cfg["scenario"], "duration_s": cfg["duration"], "seed": cfg["seed"],
                              "robots": cfg["robots"], "mode": cfg["mode"], "wait_for_nodes": "recorder"}]),
            Node(package="kilobot_twin", executable="swarm", name="swarm", output="screen",
                 parameters=[{"robots": cfg["robots"], "seed": cfg["seed"], "traits_file": ParameterValue(cfg["traits"], value_type=str)}]),
        ]
    )
