"""The twin's topic layout in a bag: robot namespaces, message types per suffix, QoS strings.

A robot publishes on ``/kilobot_<id>/<suffix>``; the recorder stores each topic's offered QoS
as rosbag2's ``offered_qos_profiles`` YAML string.
"""

from __future__ import annotations

import re

import yaml

#: Message type of each robot topic suffix.
ROBOT_TYPES = {
    "pose": "geometry_msgs/msg/PoseStamped",
    "light": "sensor_msgs/msg/Illuminance",
    "led": "std_msgs/msg/ColorRGBA",
    "clock": "sensor_msgs/msg/TimeReference",
    "traits": "std_msgs/msg/String",
}
ROBOT_TOPIC = re.compile(r"^/kilobot_(\d+)/(" + "|".join(ROBOT_TYPES) + r")$")


def robot_namespace(robot_id: int) -> str:
    return f"/kilobot_{int(robot_id)}"


def parse_robot_topic(topic: str) -> tuple[int, str] | None:
    """``'/kilobot_7/pose'`` -> ``(7, 'pose')``; ``None`` for any other topic."""
    m = ROBOT_TOPIC.match(topic)
    return (int(m.group(1)), m.group(2)) if m else None


def qos_yaml(reliability: int, durability: int, depth: int, history: int = 1) -> str:
    """rosbag2's offered_qos_profiles string for one publisher (ints as in rmw: reliable=1,
    best_effort=2; transient_local=1, volatile=2; keep_last=1)."""
    inf = {"sec": 2147483647, "nsec": 4294967295}
    return yaml.safe_dump([{"history": history, "depth": depth, "reliability": reliability, "durability": durability,
                            "deadline": inf, "lifespan": inf, "liveliness": 1, "liveliness_lease_duration": inf,
                            "avoid_ros_namespace_conventions": False}], sort_keys=False)


DATA_QOS = qos_yaml(1, 2, 1000)     # reliable, volatile
LATCHED_QOS = qos_yaml(1, 1, 1)     # reliable, transient-local
