"""Summaries against theory and the closed-form blink path against stepping."""

import numpy as np

from kilobot_twin.core import sim
from kilobot_twin.core.traits import SwarmTraits, draw_population
from kilobot_twin.gap import summaries, synth
from kilobot_twin.gap.model import blink_leds


def test_turn_rate_and_speed_of_noisy_gappy_tracks_match_kinematics():
    b = np.linspace(-0.04, 0.04, 9)
    sc = synth.motion_scenario(60.0, 0.1)
    res = sim.simulate(sc, SwarmTraits.uniform(9).with_values(heading_bias=b), 0, record_every=1)
    rng = np.random.default_rng(0)
    x = res.traj["x"] + 0.002 * rng.standard_normal(res.traj["x"].shape)
    y = res.traj["y"] + 0.002 * rng.standard_normal(res.traj["y"].shape)
    drop = rng.random(x.shape) < 0.05
    drop[..., 100:130] = True  # a 3 s tracking loss
    s = summaries.motion(np.where(drop, np.nan, x), np.where(drop, np.nan, y), 0.1)
    v = synth.FORWARD_SPEED_M_S
    np.testing.assert_allclose(s["turn_rate"][0], -b * v / 0.025, atol=3e-4)  # omega = -b v / L
    np.testing.assert_allclose(summaries.bias_from_turn_rate(s["turn_rate"], v)[0], b, atol=0.001)
    assert np.all(np.abs(s["speed"][0] / v - 1) < 0.05)


def test_light_sweep_gain_is_linear_slope():
    stim = np.linspace(0, 1, 200)[None, None, :]
    reading = np.minimum(5 + 2000 * stim, 1023)
    s = summaries.light_sweep(stim, reading)
    assert abs(s["gain"][0, 0] - 2000) < 1e-6 and abs(s["offset"][0, 0] - 5) < 1e-6


def test_blink_toggle_rate_and_closed_form_leds():
    sc = synth.blink_scenario(30.0, 1 / 30)
    sw = draw_population({"n": 5, "clock_rate": {"dist": "normal", "mean": 1, "sd": 0.02}, "clock_trial_sd": 0.002}, seed=1)
    res = sim.simulate(sc, sw, 3, runs=[0, 5], trials=[0, 2], record_every=1)
    T = res.traj["led"].shape[-1]
    leds = blink_leds(sc, sw, 3, [0, 5], [0, 2], T)
    assert np.array_equal(res.traj["led"], leds)
    rate = summaries.blink(leds.astype(float), 1 / 30)["toggle_rate"]
    st = sim.init_state(sc, sw, 3, runs=[0, 5], trials=[0, 2])
    expected = 31.0 * st.clock / 30  # toggles per second
    assert np.all(np.abs(rate / expected - 1) < 0.01)
