"""A robot node's parameters as a ROS 2 user meets them: its id from a params file or a namespace,
its behaviour from the world unless told otherwise, and `ros2 param set` that either takes effect
from the next step or is refused with the start-up message."""

import json

import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter

from kilobot_twin.core.scenario import Scenario, scenario_from_dict
from kilobot_twin.nodes.robot import RobotNode, make_robot
from kilobot_twin.core.scenarios import parse_world_document, world_document

from .graph import overrides

V_M_S = 0.06 * 48 / 255  # straight: both wheels at 48/255 of 6 cm/s (README, "Kilobot constants")
L_M = 0.025  # wheel separation


@pytest.fixture
def ros_args(request):
    """A context initialised with a command line's --ros-args (as `ros2 run` / launch pass them)."""
    contexts = []

    def make(*args):
        ctx = Context()
        rclpy.init(args=["robot", "--ros-args", *args], context=ctx)
        contexts.append(ctx)
        return ctx
    yield make
    for ctx in contexts:
        rclpy.try_shutdown(context=ctx)


def _world(scenario: Scenario, robots=1) -> dict:
    return parse_world_document(world_document(scenario, seed=0, run=0, n_robots=robots, mode="lockstep"))


def _latched_traits(ctx) -> dict:
    from std_msgs.msg import String

    from kilobot_twin.ros import qos
    from kilobot_twin.ros.executors import make_executor

    got = []
    listener = rclpy.create_node("listener", context=ctx)
    listener.create_subscription(String, "/kilobot_0/traits", lambda m: got.append(json.loads(m.data)), qos.LATCHED)
    executor = make_executor(context=ctx, events=False)
    executor.add_node(listener)
    for _ in range(200):
        if got:
            break
        executor.spin_once(timeout_sec=0.05)
    listener.destroy_node()
    return got[-1]


def test_robot_id_from_a_params_file_sets_the_namespace(ros_args, tmp_path):
    f = tmp_path / "p.yaml"  # what launch_ros writes for Node(parameters=[{'robot_id': 3}])
    f.write_text("/**:\n  ros__parameters:\n    robot_id: 3\n")
    ctx = ros_args("--params-file", str(f))
    node = make_robot([], context=ctx)
    try:
        assert (node.get_namespace(), node.robot_id) == ("/kilobot_3", 3)
    finally:
        node.destroy_node()


def test_robot_id_from_the_namespace(ros_args):
    ctx = ros_args("-r", "__ns:=/kilobot_5")  # launch's Node(namespace='kilobot_5')
    node = make_robot([], context=ctx)
    try:
        assert (node.get_namespace(), node.robot_id) == ("/kilobot_5", 5)
    finally:
        node.destroy_node()


def test_robot_id_and_namespace_that_disagree_are_refused(ros_args):
    from kilobot_twin.errors import ConfigError

    ctx = ros_args("-r", "__ns:=/kilobot_5", "-p", "robot_id:=2")
    with pytest.raises(ConfigError, match="robot_id"):
        make_robot([], context=ctx)


def test_behaviour_follows_the_world_unless_set(ros_args):
    world = scenario_from_dict({"behavior": {"kind": "phototaxis", "p_right": 0.25, "reference": 900.0}})
    ctx = ros_args()
    plain = RobotNode(0, context=ctx)
    told = RobotNode(1, context=ctx, parameter_overrides=overrides(behavior="straight"))
    field = RobotNode(2, context=ctx, parameter_overrides=overrides(**{"phototaxis.p_right": 1.0}))
    try:
        for n in (plain, told, field):
            n.set_world(_world(world, 3))
        assert plain.behavior == world.behavior  # the world's kind and values
        assert told.behavior.name == "straight"
        assert (field.behavior.name, field.behavior.p_right, field.behavior.reference) == ("phototaxis", 1.0, 900.0)
    finally:
        for n in (plain, told, field):
            n.destroy_node()


def test_param_set_takes_effect_from_the_next_step_or_is_refused(ros_args):
    ctx = ros_args()
    node = RobotNode(0, context=ctx)
    try:
        node.set_world(_world(scenario_from_dict({"behavior": "straight", "start": {"kind": "origin", "heading_rad": 0.0}})))
        dt = node.scenario.dt_s
        theta = [node.model.state.theta[0, 0]]
        for _ in range(3):
            node.model.step()
            theta.append(node.model.state.theta[0, 0])
        # Refused, with the start-up message; nothing changes.
        for name, value, field in [("clock_rate", -1.0, "clock_rate"), ("heading_bias", "abc", "heading_bias"),
                                   ("behavior", "bogus", "behavior"), ("phototaxis.p_right", 2.0, "phototaxis.p_right"),
                                   ("phototaxis_argos.p_right", 2.0, "phototaxis_argos.p_right"),
                                   ("blink.half_period_ticks", 2.5, "blink.half_period_ticks")]:
            res = node.set_parameters([Parameter(name, value=value)])[0]
            assert not res.successful and res.reason.startswith(field + ":"), (name, res.reason)
        assert node.get_parameter("clock_rate").value == 1.0 and node.traits.clock_rate == 1.0
        for name in ("robot_id", "seed", "swarm_size", "world"):  # identity: read-only
            assert not node.set_parameters([Parameter(name, value=7 if name != "world" else "/w")])[0].successful
        # Taken: a wheel imbalance b turns the robot at -b v / L from the next step (b > 0: clockwise).
        assert node.set_parameters([Parameter("heading_bias", value=0.3)])[0].successful
        for _ in range(3):
            node.model.step()
            theta.append(node.model.state.theta[0, 0])
        turn = np.diff(theta) / dt
        np.testing.assert_allclose(turn[:3], 0.0, atol=1e-12)
        np.testing.assert_allclose(turn[3:], -0.3 * V_M_S / L_M, rtol=1e-9)
        assert _latched_traits(ctx)["traits"]["heading_bias"] == 0.3  # what `ros2 topic echo traits` shows
        # A behaviour change restarts the program with the new behaviour.
        assert node.set_parameters([Parameter("behavior", value="still")])[0].successful
        assert node.model.scenario.behavior.name == "still" and node.behavior.name == "still"
    finally:
        node.destroy_node()


def test_a_robot_node_reads_with_its_trials_sensor_offset(ros_args):
    """The trait ``sensor_offset_trial_sd`` reaches a robot node's sensor through its ROS
    parameter: set to 25 counts, the node's reading in a dark arena is its offset shifted by this
    trial's draw (what a (1, 1) core state of the same robot, seed and run reads), and before it
    is set, the offset itself."""
    from kilobot_twin.core import sim
    from kilobot_twin.core.traits import SwarmTraits

    ctx = ros_args()
    node = RobotNode(0, context=ctx)
    try:
        sc = scenario_from_dict({"behavior": "phototaxis", "light": {"kind": "cone", "radius_m": 0.01, "center": [5.0, 5.0]},
                                 "start": {"kind": "origin", "heading_rad": 0.0}})
        node.set_world(_world(sc))
        assert node.set_parameters([Parameter("sensor_offset", value=100.0)])[0].successful
        node.model.step()
        assert node.model.state.reading[0, 0] == 100.0
        assert node.set_parameters([Parameter("sensor_offset_trial_sd", value=25.0)])[0].successful
        node.model.step()
        got = node.model.state.reading[0, 0]
        ref = sim.init_state(node.model.scenario, SwarmTraits.from_robots([node.traits], ids=[0]), node.seed,
                             runs=[node.run], trials=[node.trial])
        assert got == np.floor(ref.offset[0, 0]) and got != 100.0
    finally:
        node.destroy_node()
