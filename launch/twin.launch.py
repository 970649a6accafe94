"""The twin on a full ROS 2 Jazzy install: ros2 launch kilobot_twin twin.launch.py robots:=20

Starts recorder, analysis, world and swarm (what `kilobot-twin run` does without a ROS
install, which additionally supervises the processes and prints a summary), with the same
Fast DDS profile as `run` (unless FASTRTPS_DEFAULT_PROFILES_FILE is set). The launch ends by
itself when the world ends (the run is done, or a bad argument: the world's one-line error):
the other processes get SIGINT a second later (the recorder finalises the bag), and
`ros2 launch` exits with the world's exit status. The default bag is a new `bags/twin_<UTC
time>`; the recorder refuses a bag that exists.
"""

import atexit
import os
import sys
from datetime import datetime, timezone

from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, EmitEvent, LogInfo, OpaqueFunction, RegisterEventHandler,
                            SetEnvironmentVariable, TimerAction)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import EnvironmentVariable, LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

from kilobot_twin.ros.launcher import FASTDDS_PROFILES
from kilobot_twin.core.scenarios import NAMED

ARGUMENTS = {  # name: (default, description)
    "scenario": ("phototaxis", f"named scenario ({', '.join(NAMED)})"),
    "robots": ("10", "number of robots (one swarm process)"),
    "duration": ("20.0", "simulated seconds"),
    "seed": ("0", "root seed of every random number (traits, noise, start poses)"),
    "mode": ("lockstep", "lockstep (simulated time, every message recorded) or realtime (wall clock)"),
    "traits": ("", "traits or population YAML file for the swarm; empty: the default population"),
    "swarms": ("1", "swarm processes (swarm_0 .. swarm_K-1), each a block of the robot ids; uncoupled scenarios"),
    "out": (None, "bag directory to create (refused if it exists); default: bags/twin_<UTC time>"),
}


def _exit_with(status: int) -> None:
    """`ros2 launch` returns 0 or 1; end the process with the world's status once launch is done."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(status)


def _world_exited(event, _context):
    status = event.returncode
    if status:
        atexit.register(_exit_with, status)
    return [LogInfo(msg=f"world exited with status {status}: stopping the twin"),
            TimerAction(period=1.0, actions=[EmitEvent(event=Shutdown(reason=f"world exited ({status})"))])]


def _swarms(context):
    """One swarm node per process: ``swarm`` alone, else ``swarm_0`` .. ``swarm_<K-1>``."""
    k = int(LaunchConfiguration("swarms").perform(context))
    names = ["swarm"] if k == 1 else [f"swarm_{i}" for i in range(k)]
    return [Node(package="kilobot_twin", executable="swarm", name=name, output="screen",
                 parameters=[{"robots": LaunchConfiguration("robots"), "seed": LaunchConfiguration("seed"),
                              "traits_file": ParameterValue(LaunchConfiguration("traits"), value_type=str),
                              "slices": k, "slice_index": i}])
            for i, name in enumerate(names)]


def generate_launch_description():
    default_out = "bags/twin_" + datetime.now(timezone.utc).strftime("%Y%m%d_%H%M%S")
    args = [DeclareLaunchArgument(k, default_value=default_out if v is None else v, description=d)
            for k, (v, d) in ARGUMENTS.items()]
    cfg = {k: LaunchConfiguration(k) for k in ARGUMENTS}
    world = Node(package="kilobot_twin", executable="world", name="world", output="screen",
                 parameters=[{"scenario": cfg["scenario"], "duration_s": cfg["duration"], "seed": cfg["seed"],
                              "robots": cfg["robots"], "mode": cfg["mode"],
                              "wait_for_nodes": "recorder,analysis@cloud"}])
    return LaunchDescription(args + [
        SetEnvironmentVariable("FASTRTPS_DEFAULT_PROFILES_FILE",
                               EnvironmentVariable("FASTRTPS_DEFAULT_PROFILES_FILE", default_value=str(FASTDDS_PROFILES))),
        Node(package="kilobot_twin", executable="recorder", name="recorder", output="screen",
             parameters=[{"out": ParameterValue(cfg["out"], value_type=str)}]),
        Node(package="kilobot_twin", executable="analysis", name="analysis", output="screen"),
        world,
        OpaqueFunction(function=_swarms),
        RegisterEventHandler(OnProcessExit(target_action=world, on_exit=_world_exited)),
    ])
