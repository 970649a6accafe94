"""The executor the nodes spin in: rclpy's EventsExecutor where available.

Measured on 2 cores: the EventsExecutor costs about 1/7 of the SingleThreadedExecutor per
message; a SingleThreadedExecutor falls below real time between 200 and 300 robot nodes of
3 publishers at 10 Hz, the EventsExecutor held 1,000.
"""

from __future__ import annotations

import os

import rclpy.executors


def make_executor(context=None, events: bool | None = None):
    """An EventsExecutor (unless ``KILOBOT_TWIN_EXECUTOR=single`` or ``events=False``)."""
    if events is None:
        events = os.environ.get("KILOBOT_TWIN_EXECUTOR", "events") != "single"
    if events:
        try:
            from rclpy.experimental import EventsExecutor

            return EventsExecutor(context=context)
        except ImportError:  # pragma: no cover - older rclpy
            pass
    return rclpy.executors.SingleThreadedExecutor(context=context)
