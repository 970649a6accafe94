"""The world's start gate says what it waits for: in words, and on the real process's log."""

import os
import subprocess
import sys
import time

import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from std_msgs.msg import Float64

from kilobot_twin.errors import ConfigError
from kilobot_twin.nodes.analysis import AnalysisNode
from kilobot_twin.nodes.swarm import SwarmNode
from kilobot_twin.nodes.world import WorldNode
from kilobot_twin.ros import latched, qos
from kilobot_twin.ros.launcher import Child, timeout_problem

from ..ros.test_latched import drop_first_reader
from .graph import Graph, overrides
from .test_lockstep import Collector

N = 3


def test_the_gate_names_what_is_missing_in_the_order_it_comes():
    with Graph() as g:
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario="phototaxis", duration_s=1.0, robots=N, wait_for_nodes="collector", wait_topics="pose,led",
            settle_s=0.2, linger_s=0.0)))
        g.spin_until(lambda: False, 0.5)
        assert world._gate_waits_for() == f"robots: 0 of {N} on the graph"
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=N, batched=False)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        swarm.create_robots(g.executor)
        assert g.spin_until(lambda: len(world.robots) == N, 10)
        # Robots there, nobody recording them: the first robot topic without its subscriber.
        assert g.spin_until(lambda: world._gate_waits_for().startswith("collector to subscribe to /kilobot_"), 10), \
            world._gate_waits_for()
        assert world.pacer.step < 0  # not started
        g.add(Collector(g.context, N))
        assert g.spin_until(lambda: world._gate_waits_for() == "", 10), world._gate_waits_for()
        assert g.spin_until(lambda: world.finished.done(), 30)
        assert not world._match_warned  # the writers' reports came, and said they had matched


class TimeListener(Node):
    """The analysis node's evaluation times as they go out."""

    def __init__(self, context):
        super().__init__("listener", context=context)
        self.times = []
        self.create_subscription(Float64, "/analysis/time_s", lambda m: self.times.append(m.data), qos.DATA)


def test_the_gate_waits_for_an_analysis_that_reads_the_swarms_cloud():
    """`kilobot-twin run` starts the analysis beside the world. Under load its process came up
    after a 4 s lockstep run had ended (0.15 s of wall time), and the bag held no /analysis topic
    (tests/nodes/test_analysis_wire.py, once in a full run). Awaited as ``analysis@cloud``, the
    world holds the start until the analysis subscribes to the batched swarm's cloud, from which it
    reads the robots (not to their own topics, which a plain awaited node must take), and the
    analysis's first values are those of the first step."""
    with Graph() as g:
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario="random_walk", duration_s=1.0, robots=N, wait_for_nodes="analysis@cloud", settle_s=0.2,
            linger_s=0.0, gate_report_s=0.0)))
        listener = g.add(TimeListener(g.context))
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=N, batched=True)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        swarm.create_robots(g.executor)
        assert g.spin_until(lambda: world._gate_waits_for().startswith("analysis to subscribe to /kilobot_0/"), 10), \
            world._gate_waits_for()
        g.spin_until(lambda: False, 1.0)
        assert world.pacer.step < 0  # not started without it
        g.add(AnalysisNode(context=g.context, parameter_overrides=overrides(period_s=0.5)))
        assert g.spin_until(lambda: world.finished.done(), 30), world._gate_waits_for()
        assert g.spin_until(lambda: len(listener.times) == 3, 5), listener.times
        assert listener.times == [0.0, 0.5, 1.0]


def test_an_awaited_node_read_in_an_unknown_way_is_one_clear_error():
    with Graph() as g, pytest.raises(ConfigError, match="wait_for_nodes"):
        g.add(WorldNode(context=g.context, parameter_overrides=overrides(robots=N, wait_for_nodes="analysis@bundle")))


class UnservedCollector(Node):
    """Subscribes to the robots' poses asking for their history (transient-local), which their
    volatile writers cannot give: on the graph, never matched."""

    def __init__(self, context, n):
        super().__init__("collector", context=context)
        for i in range(n):
            self.create_subscription(PoseStamped, f"/kilobot_{i}/pose", lambda m: None, qos.LATCHED)


def test_the_gate_waits_for_the_writers_to_match_an_awaited_reader_and_then_starts_with_a_warning():
    """The graph the world sees is not the robots' processes': a reader on the world's graph may
    not be matched by a robot's writer yet, and a run started then loses its first messages to
    it. Here the awaited reader is one no writer can serve (it asks for history that volatile
    writers do not keep): on the graph, never matched. The world does not start on the graph
    alone; it names the writer and the count, and after ``match_timeout_s`` starts with a warning."""
    with Graph() as g:
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario="random_walk", duration_s=1.0, robots=N, wait_for_nodes="collector", wait_topics="pose",
            settle_s=0.2, linger_s=0.0, match_timeout_s=3.0, gate_report_s=0.0)))
        g.add(UnservedCollector(g.context, N))
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=N, batched=False)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        swarm.create_robots(g.executor)
        # the world's own pose reader (lockstep) is matched, the collector's is not
        want = "the writer of /kilobot_0/pose to match its readers (1 of 2)"
        assert g.spin_until(lambda: world._gate_waits_for() == want, 10), world._gate_waits_for()
        assert world.pacer.step < 0 and not world._match_warned
        assert g.spin_until(lambda: world.finished.done(), 30), world._gate_waits_for()
        assert world._match_warned


def test_a_world_that_never_starts_says_why_on_its_log_and_in_the_runs_report(tmp_path):
    # The node as `ros2 run` starts it, alone: no robot ever comes.
    cmd = [sys.executable, "-m", "kilobot_twin.nodes.world", "--ros-args", "-p", f"robots:={N}",
           "-p", "gate_report_s:=0.3"]
    log = tmp_path / "world.log"
    with open(log, "w") as fh:
        p = subprocess.Popen(cmd, stdout=fh, stderr=subprocess.STDOUT, env=dict(os.environ, PYTHONUNBUFFERED="1"))
    time.sleep(3.0)
    p.terminate()
    p.wait(20)
    out = log.read_text()
    warned = [ln for ln in out.splitlines() if "not started after" in ln]
    assert len(warned) >= 2 and all(f"waiting for robots: 0 of {N} on the graph" in ln for ln in warned), out
    assert "WARN" in warned[0]
    # `kilobot-twin run`'s report of a timeout carries the world's last word on it.
    line = timeout_problem(64.0, Child("world", p, log), tmp_path)
    assert line.startswith("timed out after 64 s (world not done: not started after ") and \
        line.endswith(f"s: waiting for robots: 0 of {N} on the graph; see {tmp_path})"), line
    assert timeout_problem(64.0, Child("world", p, tmp_path / "none.log"), tmp_path) == \
        f"timed out after 64 s (world not done; see {tmp_path})"


def test_a_member_list_that_never_arrives_is_asked_for_again(monkeypatch):
    """A batched swarm's member list is latched; now and then the world's subscription, made once
    the topic is on the graph, never delivered it (the world waited 60 s, the recorder of the same
    run had it). Here the world's first reader of the list is never served: the world subscribes
    again after RETRY_S, hears the list from the new reader, and starts."""
    monkeypatch.setattr(latched, "RETRY_S", 1.0)
    drop_first_reader(monkeypatch, "/members")
    with Graph() as g:
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario="random_walk", duration_s=1.0, robots=N, settle_s=0.2, linger_s=0.0, gate_report_s=0.0)))
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=N, batched=True)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        swarm.create_robots(g.executor)
        assert g.spin_until(lambda: world.finished.done(), 30), world._gate_waits_for()
        reader = world._members_readers["/swarm"]
        assert reader.topic == "/swarm/members" and reader.retries == 1 and world.swarms["/swarm"] == set(range(N))


def test_a_swarm_whose_reader_of_the_worlds_scenario_is_never_served_asks_again_and_runs(monkeypatch):
    """CI of stop 57: a swarm never heard the world's latched scenario document, so it never made
    its robots and the run timed out after 60 s. Its first reader of the document is never served
    here: it subscribes again, makes its robots, and the run ends."""
    monkeypatch.setattr(latched, "RETRY_S", 1.0)
    drop_first_reader(monkeypatch, "/world/scenario")
    with Graph() as g:
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario="random_walk", duration_s=1.0, robots=N, settle_s=0.2, linger_s=0.0, gate_report_s=0.0)))
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=N, batched=True)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        assert swarm.world_reader.retries == 1
        swarm.create_robots(g.executor)
        assert g.spin_until(lambda: world.finished.done(), 30), world._gate_waits_for()
