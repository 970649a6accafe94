"""ROS 2 nodes (one file per node, each with a ``main`` registered as a console script)."""
