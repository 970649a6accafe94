"""ROS 2 adapters shared by the nodes: message conversion, parameters, MCAP bags, launching.

Nothing in :mod:`kilobot_twin.core` or :mod:`kilobot_twin.batch` imports this package.
:mod:`.bag` and :mod:`.schemas` do not import rclpy either (bags can be read and repaired
without ROS).
"""
