"""Publishers of robot data that skip the hand-over to DDS while no reader is matched.

A swarm of 200 robots publishes some 620 messages a step; with nobody subscribed to a robot's own
topics (the recorder takes the swarm's bundle, the world and the analysis its cloud) each publish
still costs several microseconds in rmw and Fast DDS, and delivers nothing: the topics are
volatile, so a reader that joins later would not receive the message either. The writer's
matched count (its ``matched`` event, and a fresh ``get_subscription_count`` every
:data:`RECHECK_EVERY` calls in case an rmw does not deliver that event) decides.
"""

from __future__ import annotations

from rclpy.event_handler import PublisherEventCallbacks
from std_msgs.msg import String

from ..recording import topics
from . import qos
from .convert import json_msg

#: A publisher asks rmw for its matched readers at least once every this many publish calls.
RECHECK_EVERY = 32


class ReaderAwarePublisher:
    """``node.create_publisher(msg_type, topic, qos_profile)`` whose :meth:`publish` is a no-op
    while no reader is matched. ``handed`` and ``skipped`` count the two outcomes."""

    def __init__(self, node, msg_type, topic: str, qos_profile):
        self.readers = 0
        self.handed = self.skipped = 0
        self._until_check = 0
        try:
            self.pub = node.create_publisher(msg_type, topic, qos_profile,
                                             event_callbacks=PublisherEventCallbacks(matched=self._on_matched))
        except Exception:  # noqa: BLE001 - an rmw without matched events (UnsupportedEventTypeError): poll only
            self.pub = node.create_publisher(msg_type, topic, qos_profile)

    def _on_matched(self, info) -> None:
        self.readers = info.current_count
        self._until_check = RECHECK_EVERY

    def publish(self, data) -> None:
        self._until_check -= 1
        if self._until_check <= 0:
            self.refresh()
        if self.readers > 0:
            self.pub.publish(data)
            self.handed += 1
        else:
            self.skipped += 1

    def get_subscription_count(self) -> int:
        return self.pub.get_subscription_count()

    def refresh(self) -> int:
        """Ask rmw for the matched readers now: every RECHECK_EVERY publications, and for a
        :class:`MatchReport` (so that what the world is told is what the first publication after
        it sees, not a count whose matched event is still queued)."""
        self.readers = self.pub.get_subscription_count()
        self._until_check = RECHECK_EVERY
        return self.readers

    @property
    def topic_name(self) -> str:
        return self.pub.topic_name


class MatchReport:
    """Until :meth:`stop`, every ``period_s`` tells the world how many readers each of a process's
    data writers has matched (on :data:`topics.MATCH_REPORT_TOPIC`). The world's graph shows a
    reader as soon as the world has discovered it; a writer in another process matches it when
    that process has, which on a loaded machine can be later: a run started in between loses its
    first messages to that reader. ``writers()``: the writers to report (ReaderAwarePublishers,
    whose cached count is refreshed too, or rclpy publishers)."""

    def __init__(self, node, writers, period_s: float = 0.2):
        self.node, self.writers = node, writers
        self.pub = node.create_publisher(String, topics.MATCH_REPORT_TOPIC, qos.DATA)
        self.timer = node.create_timer(period_s, self.report)

    def report(self) -> None:
        counts = {w.topic_name: (w.refresh() if isinstance(w, ReaderAwarePublisher) else w.get_subscription_count())
                  for w in self.writers()}
        self.pub.publish(json_msg({"node": self.node.get_fully_qualified_name(), "matched": counts}))

    def stop(self) -> None:
        if self.timer is not None:
            self.node.destroy_timer(self.timer)
            self.timer = None
