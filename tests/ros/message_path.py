"""The message-object path of a robot's messages (rclpy message types filled field by field): the
second implementation that the serialized CDR of :mod:`kilobot_twin.recording.cdr` is checked against."""

import math
from dataclasses import dataclass

from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import Illuminance, TimeReference
from std_msgs.msg import ColorRGBA

from kilobot_twin.ros.convert import ns_to_time

NS_PER_S = 10**9
COLOURS = {0: (1.0, 0.0, 0.0, 1.0), 1: (0.0, 0.0, 1.0, 1.0), 2: (0.0, 0.0, 0.0, 0.0)}  # red, blue, off


@dataclass
class RobotSample:
    """What one robot reports after a step (plain values, no ROS types)."""

    robot_id: int
    step: int
    stamp_ns: int
    x_m: float
    y_m: float
    theta_rad: float
    reading: float
    led: int
    ticks: float
    tick_hz: float
    reading_variance: float = 0.0


class RobotMessages:
    """Reusable messages of one robot, filled from a :class:`RobotSample` (no per-step allocation)."""

    def __init__(self):
        self.pose = PoseStamped()
        self.pose.header.frame_id = "arena"
        self.light = Illuminance()
        self.light.header.frame_id = "arena"
        self.led = ColorRGBA()
        self.clock = TimeReference()
        self.clock.header.frame_id = "arena"
        self.clock.source = "kilo_ticks"

    def fill(self, s: RobotSample) -> "RobotMessages":
        for h in (self.pose.header, self.light.header, self.clock.header):
            ns_to_time(s.stamp_ns, h.stamp)
        p = self.pose.pose
        p.position.x = float(s.x_m)
        p.position.y = float(s.y_m)
        half = 0.5 * float(s.theta_rad)
        p.orientation.z = math.sin(half)
        p.orientation.w = math.cos(half)
        self.light.illuminance = float(s.reading)
        self.light.variance = float(s.reading_variance)
        self.led.r, self.led.g, self.led.b, self.led.a = COLOURS[int(s.led)]
        ns_to_time(int(round(s.ticks / s.tick_hz * NS_PER_S)), self.clock.time_ref)
        return self
