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
ROBOT_NAMESPACE = re.compile(r"^/kilobot_(\d+)$")
#: Robot topics published every step (and clock on clock steps): what the recorder acknowledges.
ROBOT_DATA = ("pose", "light", "led", "clock")
#: A batched swarm process's member list (group 1: the swarm's topic base, ``/swarm`` or
#: ``/swarm_<k>``); its cloud is :func:`swarm_cloud_topic`.
SWARM_MEMBERS_TOPIC = re.compile(r"^((?:.*/)?swarm[^/]*)/members$")
SWARM_CLOUD = "robots"
#: A batched swarm's bundle: its robots' messages of a step in one message (:func:`kilobot_twin.recording.cdr.bundle_cdr`),
#: written into the bag as the robots' own topics, never as a topic of its own.
SWARM_BUNDLE = "bundle"
BUNDLE_TYPE = "std_msgs/msg/UInt8MultiArray"
#: Until a run starts, every process that publishes robot data (and the analysis node) says here
#: how many readers each of its writers has matched (std_msgs/String, JSON ``{"node": ..., "matched": {topic: count}}``):
#: the world's start gate waits for them (:mod:`kilobot_twin.nodes.world`). Hidden (the leading
#: underscore): ``ros2 topic list`` leaves it out, and the recorder's prefixes do not take it.
MATCH_REPORT_TOPIC = "/_kilobot_twin/matched"


def robot_namespace(robot_id: int) -> str:
    return f"/kilobot_{int(robot_id)}"


def robot_id_of_namespace(namespace: str) -> int | None:
    """``'/kilobot_7'`` -> 7; ``None`` for any other namespace."""
    m = ROBOT_NAMESPACE.match(namespace)
    return int(m.group(1)) if m else None


def swarm_cloud_topic(base: str) -> str:
    return f"{base}/{SWARM_CLOUD}"


def swarm_bundle_topic(base: str) -> str:
    return f"{base}/{SWARM_BUNDLE}"


def topic_group(topic: str) -> str:
    """``/kilobot_7/pose`` -> ``/kilobot_*/pose`` (robot topics grouped over robots); others as they are."""
    parsed = parse_robot_topic(topic)
    return f"/kilobot_*/{parsed[1]}" if parsed else topic


def parse_robot_topic(topic: str) -> tuple[int, str] | None:
    """``'/kilobot_7/pose'`` -> ``(7, 'pose')``; ``None`` for any other topic."""
    m = ROBOT_TOPIC.match(topic)
    return (int(m.group(1)), m.group(2)) if m else None


#: rmw's QoS policy values as rosbag2 stores them.
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST = 1


def qos_yaml(reliability: int, durability: int, depth: int, history: int = KEEP_LAST) -> str:
    """rosbag2's offered_qos_profiles string for one publisher (ints as in rmw: reliable=1,
    best_effort=2; transient_local=1, volatile=2; keep_last=1)."""
    inf = {"sec": 2147483647, "nsec": 4294967295}
    return yaml.safe_dump([{"history": history, "depth": depth, "reliability": reliability, "durability": durability,
                            "deadline": inf, "lifespan": inf, "liveliness": 1, "liveliness_lease_duration": inf,
                            "avoid_ros_namespace_conventions": False}], sort_keys=False)


DATA_QOS = qos_yaml(RELIABLE, VOLATILE, 1000)
LATCHED_QOS = qos_yaml(RELIABLE, TRANSIENT_LOCAL, 1)
