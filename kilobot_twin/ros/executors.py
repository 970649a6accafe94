"""The executor the nodes spin in: rclpy's EventsExecutor where available.

Measured on 2 cores: the EventsExecutor costs about 1/7 of the SingleThreadedExecutor per
message; a SingleThreadedExecutor falls below real time between 200 and 300 robot nodes of
3 publishers at 10 Hz, the EventsExecutor held 1,000.
"""

from __future__ import annotations

import os

import rclpy.executors
import rclpy.utilities


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


def spin(executor, context=None, until=None) -> None:
    """Spin until ``until`` (a Future) is done or the context shuts down.

    The EventsExecutor's own ``spin()`` is not woken by SIGINT/SIGTERM in this rclpy (7.1.6), so we
    spin in short slices: Ctrl-C then raises KeyboardInterrupt and SIGTERM
    ExternalShutdownException, as with the other executors.
    """
    context = context if context is not None else rclpy.utilities.get_default_context()
    while context.ok() and (until is None or not until.done()):
        executor.spin_once(timeout_sec=0.1)
    if not context.ok():
        raise rclpy.executors.ExternalShutdownException()
