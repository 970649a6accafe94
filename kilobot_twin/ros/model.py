"""The physics a robot node runs: the core's step function on a (1, 1) or (1, N) state.

No node code here (messages only as CDR bytes, :mod:`kilobot_twin.recording.cdr`). A standalone robot node owns a :class:`RobotModel` (one robot, exactly
``sim.init_state(..., robot_index=[i])`` + ``sim.step``). A ``swarm`` process in lockstep mode
steps all its robots in one vectorised call (:class:`SwarmModel`); since every random number
is keyed by (seed, run, robot), each robot's trajectory is the same either way, and Kuramoto
coupling between the robots of one process is then computed exactly as in the batch engine.
"""

from __future__ import annotations

import numpy as np

from ..core import sim
from ..core.scenario import Scenario
from ..core.traits import RobotTraits, SwarmTraits
from ..recording.cdr import robot_records, rows
from .convert import robot_cloud_cdr
from ..core.scenarios import start_pose


class SwarmModel:
    """A (1, N) batch state for robots ``ids`` of a swarm of ``n_robots`` (ids 0..n-1 for grids)."""

    def __init__(self, scenario: Scenario, traits: SwarmTraits, seed: int, run: int = 0, trial: int = 0,
                 n_robots: int | None = None):
        self.scenario = scenario
        n_robots = len(traits) if n_robots is None else n_robots
        poses = None
        if scenario.start.kind == "grid":
            xs, ys, ts = zip(*(start_pose(scenario, seed, run, int(i)) for i in traits.ids))
            poses = (np.concatenate(xs, axis=1), np.concatenate(ys, axis=1), np.concatenate(ts, axis=1))
        self.state = sim.init_state(scenario, traits, seed, runs=[run], trials=[trial], poses=poses)
        self.table = scenario.motors.wheel_table_m_s()
        self.ids = traits.ids
        self.variance = traits.values["sensor_noise"] ** 2 / scenario.sensor.samples

    @property
    def step_index(self) -> int:
        return self.state.step

    def step(self) -> None:
        sim.step(self.state, self.scenario, self.table)

    def set_traits(self, traits: SwarmTraits) -> None:
        """New traits for the same robots, from the next step on (see :func:`sim.set_traits`)."""
        sim.set_traits(self.state, traits)
        self.variance = traits.values["sensor_noise"] ** 2 / self.scenario.sensor.samples

    def set_behavior(self, behavior) -> None:
        """Run ``behavior`` from the next step on, its program started afresh."""
        self.scenario = self.scenario.replace(behavior=behavior)
        sim.restart_behavior(self.state, self.scenario)

    def records(self, stamp_ns, cols=slice(None)):
        """``(pose, light, led, clock)`` CDR record arrays for columns ``cols`` (all by default),
        stamped ``stamp_ns`` (one value or one per column): see :func:`kilobot_twin.recording.cdr.robot_records`."""
        st = self.state
        return robot_records(stamp_ns, st.x[0, cols], st.y[0, cols], st.theta[0, cols], st.reading[0, cols],
                             np.broadcast_to(self.variance, st.x.shape[1:])[cols], st.led[0, cols], st.ticks[0, cols],
                             self.scenario.tick_hz)

    def serialized(self, stamp_ns, cols=slice(None)):
        """Serialized ``(pose, light, led, clock)`` lists (one ``bytes`` per robot) of :meth:`records`."""
        return tuple(rows(r) for r in self.records(stamp_ns, cols))

    def cloud(self, stamp_ns: int) -> bytes:
        """Every robot's state as one serialized PointCloud2 (see :func:`convert.robot_cloud_cdr`)."""
        st = self.state
        return robot_cloud_cdr(stamp_ns, self.ids, st.x[0], st.y[0], st.theta[0], st.reading[0], st.led[0],
                               st.ticks[0])


class RobotModel(SwarmModel):
    """One robot: a (1, 1) state."""

    def __init__(self, scenario: Scenario, traits: RobotTraits, robot_id: int, seed: int, run: int = 0,
                 trial: int = 0, n_robots: int = 1):
        super().__init__(scenario, SwarmTraits.from_robots([traits], ids=[robot_id]), seed, run, trial,
                         max(n_robots, robot_id + 1))
