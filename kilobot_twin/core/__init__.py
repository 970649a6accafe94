"""The individual-Kilobot model: pure NumPy, no middleware imports.

Everything here is plain data and array functions; the batch engine, the ROS nodes, the
recorder and the viewer call into it.
"""
