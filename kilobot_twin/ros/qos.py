"""QoS profiles used across the graph (one place, so publishers and the recorder agree)."""

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: Robot data topics: reliable so that lockstep and recordings lose nothing; a deep queue
#: absorbs bursts (a 200-robot swarm publishes in bursts when its timers fire together).
DATA = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=200, reliability=ReliabilityPolicy.RELIABLE,
                  durability=DurabilityPolicy.VOLATILE)

#: Documents published once (traits, the world's scenario, the light-field image, run state):
#: late joiners get the last one.
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)

#: /clock: reliable (lockstep steps on every message).
CLOCK = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.VOLATILE)
