"""kilobot_twin: a digital twin of a Kilobot swarm in which every robot is an individual.

The model lives in :mod:`kilobot_twin.core` (pure NumPy), the Monte Carlo engine in
:mod:`kilobot_twin.batch`, the ROS 2 adapters in :mod:`kilobot_twin.nodes`.
"""

__version__ = "0.1.0"
