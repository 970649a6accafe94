"""``robot``: one Kilobot as a ROS 2 node (topics, parameters and id: README, "nodes").

Parameters: ``robot_id, seed, run, trial, swarm_size``, the traits (``heading_bias`` ...
``clock_rate``), ``behavior`` (empty: the world's scenario's behaviour) and
``<behavior>.<field>`` (set ones override the world's values), ``world`` (the world node's
name, default ``/world``). ``ros2 param set`` on a trait or the behaviour takes effect from the
next step (the behaviour's program restarts); the identity parameters are read-only.

The environment (light field, arena, time step, start poses) comes from the world's
transient-local scenario document, so the robot evaluates the same analytic light field as the
batch engine without a round trip per reading. Lockstep: one step per ``/clock`` message for
its next step; realtime: once the world says ``running``, a wall timer of period ``dt_s``
(stamps are wall time since the world's start).
"""

from __future__ import annotations

import json
import re
import sys
import time

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Illuminance, TimeReference
from geometry_msgs.msg import PoseStamped
from std_msgs.msg import ColorRGBA, String

from ..core.traits import TRAIT_NAMES, SwarmTraits, traits_from_mapping
from ..errors import ConfigError
from ..recording.topics import robot_id_of_namespace
from ..ros import convert, params, qos
from ..ros.executors import run_node
from ..ros.latched import LatchedReader
from ..ros.model import RobotModel, SwarmModel
from ..ros.publishing import MatchReport, ReaderAwarePublisher
from ..core.scenarios import clock_period_from_document, parse_world_document, scenario_from_document
from ..ros.stepping import StepRule

PROG = "kilobot-twin robot"


class WrongNamespace(Exception):
    """The robot's id (from a params file) is known only once the node exists: build it again in
    namespace ``kilobot_<robot_id>``."""

    def __init__(self, robot_id: int):
        super().__init__(robot_id)
        self.robot_id = robot_id


class RobotNode(Node):
    """One robot. ``shared=(model, column)`` makes it publish a column of a swarm's batch state.

    Parameters
    ----------
    robot_id : int, optional
        Sets the default namespace ``kilobot_<id>``; read from the ``robot_id`` parameter
        override when not given.
    lean : bool
        No parameter services and no rosout (for hundreds of robots in one process).
    """

    def __init__(self, robot_id: int | None = None, *, context=None, parameter_overrides=None, namespace=None,
                 lean: bool = False, use_global_arguments: bool = True, standalone: bool = True):
        if robot_id is None:
            robot_id = next((int(p.value) for p in parameter_overrides or [] if p.name == "robot_id"), None)
        asked_ns = namespace or f"kilobot_{robot_id or 0}"
        super().__init__("robot", namespace=asked_ns, context=context,
                         parameter_overrides=parameter_overrides, start_parameter_services=not lean,
                         enable_rosout=not lean, use_global_arguments=use_global_arguments)
        ns = self.get_namespace()
        remapped = ns != "/" + asked_ns.lstrip("/")  # a namespace given by launch / -r __ns:=
        from_ns = robot_id_of_namespace(ns)
        default_id = robot_id if robot_id is not None else from_ns if from_ns is not None else 0
        self.robot_id = params.integer(self, "robot_id", default_id, minimum=0)
        if from_ns is not None and from_ns != self.robot_id:
            if not remapped:
                self.destroy_node()
                raise WrongNamespace(self.robot_id)
            raise ConfigError("robot_id", f"{self.robot_id} disagrees with the namespace {ns}",
                              "give only one of them, or the same id in both")
        self.seed = params.integer(self, "seed", 0, minimum=0)
        self.run = params.integer(self, "run", 0, minimum=0)
        self.trial = params.integer(self, "trial", 0, minimum=0)
        self.swarm_size = params.integer(self, "swarm_size", 1, minimum=1)
        self.world = params.text(self, "world", "/world")
        self.traits = params.declare_traits(self)
        self.choice = params.declare_behavior(self)
        self.behavior = None  # resolved against the world's scenario in set_world

        # Data topics go to DDS only while someone listens (see ReaderAwarePublisher).
        self.pub_pose = ReaderAwarePublisher(self, PoseStamped, "pose", qos.DATA)
        self.pub_light = ReaderAwarePublisher(self, Illuminance, "light", qos.DATA)
        self.pub_led = ReaderAwarePublisher(self, ColorRGBA, "led", qos.DATA)
        self.pub_clock = ReaderAwarePublisher(self, TimeReference, "clock", qos.DATA)
        self.pub_traits = self.create_publisher(String, "traits", qos.LATCHED)
        if not lean:
            self.add_on_set_parameters_callback(self._on_set_parameters)
        self.model: SwarmModel | None = None
        self.col = 0
        self.scenario = None
        self.mode = None
        self.start_wall_ns = 0
        self.timer = None
        self.published = 0
        self.clocks_published = 0
        self.clock_period_s = 0.0
        self.done = False
        self.match_report = None
        if standalone:
            self.match_report = MatchReport(self, lambda: (self.pub_pose, self.pub_light, self.pub_led, self.pub_clock))
            self.world_reader = LatchedReader(self, String, f"{self.world}/scenario", self._on_world_msg)
            self.state_reader = LatchedReader(self, String, f"{self.world}/state", self._on_state_msg)
            self.create_subscription(Clock, "/clock", self._on_clock_msg, qos.CLOCK)

    # --- inputs (called by subscriptions, or by the swarm node for its robots) ----------------

    def set_world(self, doc: dict, shared: tuple[SwarmModel, int] | None = None) -> None:
        """Adopt the world's scenario, with this robot's own behaviour."""
        if self.model is not None:
            return
        world = scenario_from_document(doc)
        self.world_behavior = world.behavior
        self.behavior = self.choice.resolve(world.behavior)
        self.scenario = world.replace(behavior=self.behavior)
        self.rule = StepRule(self.scenario.dt_s, self.scenario.n_steps)
        self.mode = doc.get("mode", "lockstep")
        self.clock_period_s = clock_period_from_document(doc)
        if shared is not None:
            self.model, self.col = shared
        else:
            n = max(self.swarm_size, int(doc.get("robots", 1)))
            self.model = RobotModel(self.scenario, self.traits, self.robot_id, self.seed, self.run, self.trial, n)
        self.publish_traits()

    def publish_traits(self) -> None:
        """The transient-local ``traits`` record: id, traits, behaviour, seed, run."""
        self.pub_traits.publish(convert.traits_to_msg(self.robot_id, self.traits,
                                                      params.behavior_to_values(self.behavior), self.seed, self.run))

    def _on_set_parameters(self, changes) -> SetParametersResult:
        """``ros2 param set``: validate like at start-up; apply from the next step or refuse."""
        values = {}
        choice = self.choice
        try:
            for p in changes:
                if p.name in TRAIT_NAMES:
                    values[p.name] = p.value
                elif params.is_behavior_parameter(p.name):
                    choice = choice.with_parameter(p.name, p.value)
            traits = traits_from_mapping(values, base=self.traits) if values else self.traits
            behavior = choice.resolve(self.world_behavior) if self.model is not None else None
        except ConfigError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.traits, self.choice = traits, choice
        if self.model is not None:
            if values:
                self.model.set_traits(SwarmTraits.from_robots([traits], ids=[self.robot_id]))
            if behavior != self.behavior:
                self.behavior = behavior
                self.scenario = self.scenario.replace(behavior=behavior)
                self.model.set_behavior(behavior)
            self.publish_traits()
        return SetParametersResult(successful=True)

    def set_state(self, doc: dict) -> None:
        state = doc.get("state")
        if state != "waiting" and self.match_report is not None:
            self.match_report.stop()  # the world's gate has opened
        if state == "running" and self.mode == "realtime" and self.timer is None and not self.done:
            self.start_wall_ns = int(doc["start_wall_ns"])
            self.publish_sample(self._wall_stamp())
            self.timer = self.create_timer(self.scenario.dt_s, self._on_timer)
        elif state == "done":
            if self.timer is not None and not self.done:  # the steps due by the end: the last races the world's done
                self._on_timer()
            self.done = True
            if self.timer is not None:
                self.timer.cancel()

    def on_clock(self, ns: int) -> None:
        """Lockstep: publish step 0 on the first tick, then one step per new tick (:class:`StepRule`)."""
        if self.model is None or self.mode != "lockstep" or self.done:
            return
        action = self.rule.on_clock(ns, self.model.step_index)
        if action == StepRule.STEP:
            self.model.step()
        if action is not None:
            self.publish_sample(ns)

    # --- outputs --------------------------------------------------------------------------------

    def publish_sample(self, stamp_ns: int) -> None:
        """Publish this robot's state (serialized CDR, see :func:`kilobot_twin.recording.cdr.robot_cdr`)."""
        pose, light, led, clock = self.model.serialized(stamp_ns, slice(self.col, self.col + 1))
        with_clock = bool(convert.clock_steps(self.model.step_index, self.scenario.dt_s, self.clock_period_s))
        self.publish_serialized(pose[0], light[0], led[0], clock[0] if with_clock else None)

    def publish_serialized(self, pose: bytes, light: bytes, led: bytes, clock: bytes | None) -> None:
        """One step's messages (``clock`` None: not a clock step). Pose last: the world takes a
        pose as "this robot has published this step"."""
        self.pub_light.publish(light)
        self.pub_led.publish(led)
        if clock is not None:
            self.pub_clock.publish(clock)
            self.clocks_published += 1
        self.pub_pose.publish(pose)
        self.published += 1

    def _wall_stamp(self) -> int:
        return max(0, time.time_ns() - self.start_wall_ns)

    def _on_timer(self) -> None:
        """Realtime: take the steps due since the start (:meth:`StepRule.due`)."""
        if self.done:
            return
        for _ in range(self.rule.due(self._wall_stamp(), self.model.step_index)):
            self.model.step()
            self.publish_sample(self._wall_stamp())

    def _on_world_msg(self, msg: String) -> None:
        self.set_world(parse_world_document(msg.data))

    def _on_state_msg(self, msg: String) -> None:
        self.set_state(json.loads(msg.data))

    def _on_clock_msg(self, msg: Clock) -> None:
        self.on_clock(convert.time_to_ns(msg.clock))


def robot_id_from_args(argv) -> int | None:
    """The ``-p robot_id:=N`` of a command line (saves building the node twice, see :class:`WrongNamespace`)."""
    for a in argv or []:
        m = re.fullmatch(r"(?:robot:)?robot_id:=(\d+)", a)
        if m:
            return int(m.group(1))
    return None


def make_robot(argv, **kwargs) -> RobotNode:
    """A robot node in namespace ``kilobot_<id>``, its id from the command line or the parameters."""
    try:
        return RobotNode(robot_id_from_args(argv), **kwargs)
    except WrongNamespace as wrong:
        return RobotNode(wrong.robot_id, **kwargs)


def main(args=None):
    argv = sys.argv if args is None else args
    run_node(PROG, lambda: make_robot(argv), args=args)


if __name__ == "__main__":
    main()
