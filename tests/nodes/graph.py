"""Helpers for node tests: an in-process graph in its own rclpy context."""

from __future__ import annotations

import time

import rclpy
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter

from kilobot_twin.ros.executors import make_executor


def overrides(**kw) -> list[Parameter]:
    return [Parameter(k, value=v) for k, v in kw.items()]


class Graph:
    """A context + executor that tests add nodes to; shut down on exit."""

    def __init__(self):
        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = make_executor(context=self.context)
        self.nodes: list[Node] = []

    def add(self, node: Node) -> Node:
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def spin_until(self, predicate, timeout_s: float = 30.0) -> bool:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if predicate():
                return True
            self.executor.spin_once(timeout_sec=0.01)
        return predicate()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        for n in self.nodes:
            n.destroy_node()
        rclpy.try_shutdown(context=self.context)
        return False
