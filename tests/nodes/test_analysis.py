"""The analysis node's live metrics equal the metrics of the batch engine's trajectories, computed
here by hand, whether it reads a batched swarm's cloud or every robot's own topics (in one
process; tests/nodes/test_analysis_wire.py checks the same across processes, from a bag)."""

import numpy as np
import pytest

from kilobot_twin.core import sim
from kilobot_twin.core.constants import LED_BLUE, LED_RED
from kilobot_twin.nodes.analysis import METRICS, AnalysisNode
from kilobot_twin.nodes.swarm import SwarmNode
from kilobot_twin.nodes.world import WorldNode
from kilobot_twin.core.scenarios import load_swarm_traits, named_scenario

from .graph import Graph, overrides

N = 6


@pytest.mark.parametrize("scenario,batched", [("phototaxis", True), ("phototaxis", False), ("blink", True)])
def test_analysis_metrics_equal_the_batch_engine(scenario, batched):
    seed, duration = 11, 5.0
    sc = named_scenario(scenario, duration)
    ref = sim.simulate(sc, load_swarm_traits("", N, seed), seed, runs=[0], record_every=1)
    final = {k: ref.traj[k][0, :, -1] for k in ("x", "y", "led")}
    with Graph() as g:
        analysis = g.add(AnalysisNode(context=g.context, parameter_overrides=overrides(period_s=0.0)))
        world = g.add(WorldNode(context=g.context, parameter_overrides=overrides(
            scenario=scenario, duration_s=duration, seed=seed, robots=N, mode="lockstep",
            wait_for_nodes="analysis", wait_topics="robots" if batched else "pose,led,clock", settle_s=0.3,
            linger_s=0.0)))
        swarm = g.add(SwarmNode(context=g.context, parameter_overrides=overrides(robots=N, seed=seed, batched=batched)))
        assert g.spin_until(lambda: swarm.world_ready.done(), 10)
        swarm.create_robots(g.executor)
        assert g.spin_until(lambda: world.finished.done(), 60), f"world stopped at step {world.pacer.step}"

        def caught_up():
            return len(analysis.x) == N and np.allclose([analysis.x[i] for i in range(N)], final["x"], rtol=0,
                                                        atol=1e-12)
        assert g.spin_until(caught_up, 5)
        g.spin_until(lambda: False, 0.2)  # the last led / clock messages
        got = analysis.publish_metrics(int(round(duration * 1e9)))
    # Which path was taken: the cloud for a batched swarm, the robots' own topics otherwise.
    assert analysis.covered == (set(range(N)) if batched else set())
    # Expected values by hand: coverage cells of side c counted from the arena's corner.
    c, (w, h) = sc.arena.coverage_cell_m, (sc.arena.width_m, sc.arena.height_m)
    cells = set(zip(((ref.traj["x"][0].ravel() + w / 2) // c).tolist(), ((ref.traj["y"][0].ravel() + h / 2) // c).tolist()))
    cx, cy = sc.light.center
    want = {"led_red_fraction": np.mean(final["led"] == LED_RED), "led_blue_fraction": np.mean(final["led"] == LED_BLUE),
            "mean_distance_to_light_m": np.mean(np.hypot(final["x"] - cx, final["y"] - cy)),
            "covered_area_m2": len(cells) * c * c, "order_parameter": np.nan}
    if ref.order is not None:  # the batch engine's order parameter of the robots' clocks at the end
        want["order_parameter"] = ref.order[0, -1]
    for k in METRICS:
        np.testing.assert_allclose(got[k], want[k], rtol=1e-9, atol=1e-12, err_msg=k, equal_nan=True)
    assert np.isfinite(got["order_parameter"]) == (scenario == "blink")
    if scenario == "phototaxis":
        assert got["covered_area_m2"] > sc.arena.coverage_cell_m ** 2  # the robots moved over cells
