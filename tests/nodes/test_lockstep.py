"""Lockstep: world + swarm nodes reproduce the batch engine to 1e-9 (same seed, traits, scenario)."""

import math

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.node import Node
from std_msgs.msg import ColorRGBA

from kilobot_twin.core import sim
from kilobot_twin.nodes.swarm import SwarmNode
from kilobot_twin.nodes.world import WorldNode
from kilobot_twin.recording.cdr import led_from_rgba
from kilobot_twin.ros import convert, qos
from kilobot_twin.core.scenarios import load_swarm_traits, named_scenario

from .graph import Graph, overrides

N = 10


class Collector(Node):
    def __init__(self, context, n):
        super().__init__("collector", context=context)
        self.poses = {i: [] for i in range(n)}
        self.leds = {i: [] for i in range(n)}
        for i in range(n):
            self.create_subscription(PoseStamped, f"/kilobot_{i}/pose", lambda m, i=i: self.poses[i].append(
                (m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, m.pose.position.x, m.pose.position.y,
                 2 * math.atan2(m.pose.orientation.z, m.pose.orientation.w))), qos.DATA)
            self.create_subscription(ColorRGBA, f"/kilobot_{i}/led",
                                     lambda m, i=i: self.leds[i].append(led_from_rgba(m.r, m.g, m.b, m.a)), qos.DATA)


@pytest.mark.parametrize("scenario,batched", [("phototaxis", False), ("random_walk", True), ("sync", True)])
def test_lockstep_equals_batch(scenario, batched):
    seed, duration = 7, 8.0
    with Graph() as g:
        col = g.add(Collector(g.context, N))
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario=scenario, duration_s=duration, seed=seed, robots=N, mode="lockstep",
            wait_for_nodes="collector", wait_topics="pose,led", settle_s=0.2, linger_s=0.0)))
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=N, seed=seed, batched=batched)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        swarm.create_robots(g.executor)
        assert g.spin_until(lambda: world.finished.done(), 60), f"world stopped at step {world.pacer.step}"
        g.spin_until(lambda: all(len(v) == world.n_steps + 1 for v in col.poses.values()), 5)
    # The handshake took the swarm's cloud for a batched swarm, every robot's pose otherwise.
    assert world.covered == (set(range(N)) if batched else set())

    sc = named_scenario(scenario, duration)
    traits = load_swarm_traits("", N, seed)
    ref = sim.simulate(sc, traits, seed, runs=[0], record_every=1)
    n = sc.n_steps
    for i in range(N):
        got = np.array(col.poses[i])
        assert got.shape == (n + 1, 4), (i, got.shape)
        np.testing.assert_array_equal(got[:, 0], [convert.step_stamp_ns(k, sc.dt_s) for k in range(n + 1)])
        np.testing.assert_allclose(got[:, 1], ref.traj["x"][0, i], rtol=0, atol=1e-9)
        np.testing.assert_allclose(got[:, 2], ref.traj["y"][0, i], rtol=0, atol=1e-9)
        dtheta = np.angle(np.exp(1j * (got[:, 3] - ref.traj["theta"][0, i])))
        assert np.abs(dtheta).max() < 1e-9
        assert col.leds[i] == ref.traj["led"][0, i].tolist()
    # The robots really moved (or, for sync, really blinked): the test is not vacuous.
    if scenario == "sync":
        assert len(set(col.leds[0])) == 2
    else:
        xy = np.array(col.poses[0])[:, 1:3]
        assert np.hypot(*np.diff(xy, axis=0).T).sum() > 0.02


def test_realtime_batched_swarm_follows_the_batch_engine_step_by_step():
    """Realtime: one wall timer steps the whole swarm; each publication is the next batch step
    (so Kuramoto coupling of ``sync`` applies as in lockstep), stamped with wall time."""
    seed, duration, n = 3, 1.5, 4
    with Graph() as g:
        col = g.add(Collector(g.context, n))
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario="sync", duration_s=duration, seed=seed, robots=n, mode="realtime",
            wait_for_nodes="collector", wait_topics="pose,led", settle_s=0.2, linger_s=0.0)))
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=n, seed=seed)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        swarm.create_robots(g.executor)
        assert g.spin_until(lambda: world.finished.done(), 30)
        g.spin_until(lambda: False, 0.3)
    assert swarm.model is not None and swarm.rt_timer is not None
    sc = named_scenario("sync", duration)
    ref = sim.simulate(sc, load_swarm_traits("", n, seed), seed, runs=[0], record_every=1)
    for i in range(n):
        got = np.array(col.poses[i])
        k = len(got)
        # every step, the last one too: it is due when the world says done, and taken then if its
        # timer has not fired yet (its loss made 1000 robots publish 600 of 601 samples each)
        assert k == sc.n_steps + 1, k
        assert np.all(np.diff(got[:, 0]) > 0)  # wall stamps, increasing
        np.testing.assert_allclose(got[:, 1], ref.traj["x"][0, i, :k], rtol=0, atol=1e-9)
        assert col.leds[i] == ref.traj["led"][0, i, :k].tolist()


def test_realtime_robots_of_their_own_publish_the_last_step_too():
    """Realtime with a robot node per robot (each on its own timer): every robot publishes every
    step up to the end, the last one (due when the world says done) included."""
    duration, n = 1.0, 3
    with Graph() as g:
        col = g.add(Collector(g.context, n))
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario="random_walk", duration_s=duration, seed=2, robots=n, mode="realtime",
            wait_for_nodes="collector", wait_topics="pose,led", settle_s=0.2, linger_s=0.0)))
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=n, seed=2, batched=False)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        swarm.create_robots(g.executor)
        assert g.spin_until(lambda: world.finished.done(), 30)
        g.spin_until(lambda: False, 0.3)
    steps = named_scenario("random_walk", duration).n_steps
    assert [len(col.poses[i]) for i in range(n)] == [steps + 1] * n
