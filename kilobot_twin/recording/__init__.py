"""Recordings on disk, free of rclpy: MCAP bags in the rosbag2 layout (:mod:`.bag`), the twin's
topic layout and QoS strings (:mod:`.topics`), ``ros2msg`` schema text (:mod:`.schemas`) and the
few CDR layouts read without ROS (:mod:`.cdr`).

Layer order: ``core -> batch -> recording -> ros -> nodes -> ...``; only :mod:`.bag` opens MCAP
files.
"""
