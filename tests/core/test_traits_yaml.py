"""Traits: YAML round trip, population draws, validation with one-line errors."""

import numpy as np
import pytest

from kilobot_twin.core.traits import (
    RobotTraits, SwarmTraits, draw_population, load_swarm, save_swarm, swarm_from_dict,
)
from kilobot_twin.errors import ConfigError


def test_yaml_round_trip(tmp_path):
    sw = draw_population({"n": 5, "heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04},
                          "clock_rate": {"dist": "normal", "mean": 1.0, "sd": 0.015}}, seed=2)
    p = tmp_path / "t.yaml"
    save_swarm(sw, p)
    back = load_swarm(p)
    assert np.array_equal(back.ids, sw.ids)
    for k, v in sw.values.items():
        np.testing.assert_array_equal(back.values[k], v)


def test_population_is_seeded_and_traits_are_independent_streams():
    spec = {"n": 50, "heading_bias": {"dist": "uniform", "low": -0.04, "high": 0.04}}
    a = draw_population(spec, seed=1)
    b = draw_population(spec, seed=1)
    c = draw_population({**spec, "sensor_gain": {"dist": "normal", "mean": 1, "sd": 0.1}}, seed=1)
    assert np.array_equal(a.heading_bias, b.heading_bias)
    # Adding another trait does not change the heading biases drawn.
    assert np.array_equal(a.heading_bias, c.heading_bias)
    assert a.heading_bias.min() >= -0.04 and a.heading_bias.max() <= 0.04


def test_defaults_and_robot_ids():
    sw = swarm_from_dict({"defaults": {"sigma_omega": 0.05}, "robots": {3: {"heading_bias": 0.01}, 7: {}}})
    assert list(sw.ids) == [3, 7]
    assert list(sw.sigma_omega) == [0.05, 0.05]
    assert sw.robot(0) == RobotTraits(heading_bias=0.01, sigma_omega=0.05)


@pytest.mark.parametrize("doc, field", [
    ({"robots": {0: {"heading_bais": 0.1}}}, "robots.0.heading_bais"),
    ({"robots": {0: {"clock_rate": -1}}}, "robots.0.clock_rate"),
    ({"robots": {0: {"heading_bias": "left"}}}, "robots.0.heading_bias"),
    ({"robots": {0: {"wheel_noise": 1.5}}}, "robots.0.wheel_noise"),
    ({"robots": {"a": {}}}, "robots.a"),
    ({"population": {"n": 0}}, "population.n"),
    ({"population": {"n": 3, "heading_bias": {"dist": "beta"}}}, "population.heading_bias.dist"),
    ({"population": {"n": 3, "heading_bias": {"dist": "uniform", "low": 1}}}, "population.heading_bias.high"),
    ({"population": {"n": 3, "clock_rate": {"dist": "normal", "mean": 1, "sd": -1}}}, "population.clock_rate.sd"),
    ({"population": {"n": 3, "heading_bias": {"dist": "uniform", "low": 0, "high": float("inf")}}},
     "population.heading_bias.high"),
    ({"population": {"n": 3, "heading_bias": {"dist": "normal", "mean": float("nan"), "sd": 0.01}}},
     "population.heading_bias.mean"),
    ({"robots": {}, "population": {"n": 1}}, "robots"),
    ({"robot": {}}, "robot"),
    ({"population": {"n": 3, "seed": 5}}, "population.seed"),  # it was passed over silently
    ({"seed": -1, "population": {"n": 3}}, "seed"),  # it was a traceback
    ({"seed": 1.5, "population": {"n": 3}}, "seed"),  # it was cut to 1
])
def test_bad_traits_give_one_line_error_naming_the_field(doc, field):
    with pytest.raises(ConfigError) as e:
        swarm_from_dict(doc)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(field + ":"), msg


def test_out_of_range_trait_in_dataclass():
    with pytest.raises(ConfigError, match="clock_rate"):
        RobotTraits(clock_rate=0.0)


def test_yaml_syntax_error_names_file_and_line(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("robots:\n  0: {heading_bias: 0.1\n")
    with pytest.raises(ConfigError) as e:
        load_swarm(p)
    assert str(p) in str(e.value) and "line" in str(e.value)


def test_swarm_subset_and_with_values():
    sw = SwarmTraits.uniform(4).with_values(heading_bias=[0.1, 0.2, 0.3, 0.4])
    sub = sw.subset([1, 3])
    assert list(sub.heading_bias) == [0.2, 0.4]
    assert list(sub.ids) == [1, 3]
