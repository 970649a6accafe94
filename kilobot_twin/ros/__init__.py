"""ROS 2 adapters shared by the nodes: message conversion, parameters, MCAP bags, launching.

Nothing in :mod:`kilobot_twin.core` or :mod:`kilobot_twin.batch` imports this package.
Bags are read, written and repaired without ROS in :mod:`kilobot_twin.recording`.
"""
