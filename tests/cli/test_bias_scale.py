"""Two scales of heading bias, two names: `heading_bias` is the wheel imbalance b everywhere;
`heading_bias_paper_axis` (run configs only) is converted with the preset's documented scale."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from kilobot_twin.config import config_from_dict, load_config
from kilobot_twin.core.traits import load_swarm
from kilobot_twin.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
# The scales docs/presets.md gives: paper b = 10 x axis, argos-code b = axis.
SCALE = {"paper": 10.0, "argos-code": 1.0}


@pytest.mark.parametrize("preset", list(SCALE))
def test_paper_axis_key_is_converted_with_the_preset_scale(preset):
    doc = {"scenario": {"preset": preset},
           "swarm": {"population": {"n": 5, "heading_bias_paper_axis": {"dist": "linspace", "low": -0.04, "high": 0.04}}}}
    cfg = config_from_dict(doc)
    np.testing.assert_allclose(cfg.swarm.heading_bias, SCALE[preset] * np.linspace(-0.04, 0.04, 5), rtol=0, atol=1e-15)
    doc = {"scenario": {"preset": preset}, "swarm": {"robots": {0: {"heading_bias_paper_axis": 0.02}, 1: {"heading_bias": 0.02}}}}
    cfg = config_from_dict(doc)
    assert list(cfg.swarm.heading_bias) == [SCALE[preset] * 0.02, 0.02]  # heading_bias is never rescaled


def test_demo_config_is_on_the_paper_axis_and_applies_b_ten_times_it():
    cfg = load_config(ROOT / "config" / "demo_phototaxis.yaml")
    assert cfg.swarm.heading_bias.min() == pytest.approx(-0.4) and cfg.swarm.heading_bias.max() == pytest.approx(0.4)


@pytest.mark.parametrize("doc, field", [
    ({"scenario": {}, "swarm": {"population": {"n": 2, "heading_bias_paper_axis": 0.01}}},
     "swarm.population.heading_bias_paper_axis"),
    ({"scenario": {"preset": "paper"}, "swarm": {"robots": {0: {"heading_bias_paper_axis": 0.01, "heading_bias": 0.1}}}},
     "swarm.robots.0.heading_bias_paper_axis"),
])
def test_paper_axis_without_a_scale_or_with_both_keys_is_refused(doc, field):
    with pytest.raises(ConfigError) as e:
        config_from_dict(doc)
    assert str(e.value).startswith(field + ":"), str(e.value)


def test_a_traits_file_cannot_carry_the_paper_axis(tmp_path):
    """Traits files (kilobot-twin/traits-v1) have no preset: only the wheel imbalance is valid there."""
    f = tmp_path / "t.yaml"
    f.write_text(yaml.safe_dump({"format": "kilobot-twin/traits-v1", "robots": {0: {"heading_bias_paper_axis": 0.01}}}))
    with pytest.raises(ConfigError, match="heading_bias_paper_axis"):
        load_swarm(f)
    f.write_text(yaml.safe_dump({"format": "kilobot-twin/traits-v1", "robots": {0: {"heading_bias": 0.01}}}))
    assert load_swarm(f).heading_bias[0] == 0.01
