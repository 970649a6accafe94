"""Readers of latched (transient-local) topics that ask again when the history never arrives.

A transient-local writer keeps its last message and sends it to every reader that joins later:
that is how the world's scenario document, its run state and a swarm's member list reach nodes
started after them. Fast DDS now and then does not deliver that history to a late-joining reader
(eProsima/Fast-DDS#3822: 5-10 % of runs in its reproducer). Here it left the world waiting 60 s
for a swarm's member list (two full test runs), and a swarm waiting for the world's scenario
until the run timed out (CI of stop 57). Such a reader hears nothing, ever, while the topic has
a writer.

:class:`LatchedReader` is a subscription with :data:`qos.LATCHED` that, while it has heard nothing
and the topic has a writer, is made again every :data:`RETRY_S` seconds: a new reader is sent the
writer's history anew. Once it has heard one message it is an ordinary subscription.
"""

from __future__ import annotations

import time

from . import qos

#: A latched topic with a writer but nothing heard after this long: subscribe again.
RETRY_S = 3.0


class LatchedReader:
    """``node.create_subscription(msg_type, topic, callback, qos.LATCHED)`` that is made again
    while nothing has been heard although ``topic`` has a publisher. ``retries`` counts the
    subscriptions made again (a subscription's deliveries carry the count it was made at);
    ``heard`` says whether a message arrived."""

    def __init__(self, node, msg_type, topic: str, callback, retry_s: float | None = None):
        self.node, self.msg_type, self.topic, self.callback = node, msg_type, topic, callback
        self.retry_s = RETRY_S if retry_s is None else float(retry_s)
        self.heard = False
        self.retries = 0
        self._sub = self._subscribe()
        self._timer = node.create_timer(min(1.0, self.retry_s / 3.0), self._check)

    def _subscribe(self):
        self._since = time.monotonic()
        made_at = self.retries
        return self.node.create_subscription(self.msg_type, self.topic, lambda msg: self._deliver(made_at, msg), qos.LATCHED)

    def _deliver(self, made_at: int, msg) -> None:
        if not self.heard:
            self.heard = True
            self._stop_timer()
        self.callback(msg)

    def _check(self) -> None:
        if self.heard:
            self._stop_timer()
            return
        now = time.monotonic()
        if now - self._since < self.retry_s or self.node.count_publishers(self.topic) == 0:
            return
        self.node.get_logger().warning(f"nothing heard on latched {self.topic} after {now - self._since:.0f} s "
                                       "although it has a publisher: subscribing again")
        self.node.destroy_subscription(self._sub)
        self.retries += 1
        self._sub = self._subscribe()

    def _stop_timer(self) -> None:
        if self._timer is not None:
            self.node.destroy_timer(self._timer)
            self._timer = None
