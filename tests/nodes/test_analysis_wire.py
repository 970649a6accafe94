"""`/analysis/*` of a multi-process run (`kilobot-twin run`: world, swarm, analysis and recorder
talk over DDS) recomputed from the robots' own topics in the bag, read with `rosbags`, by the
formulas written out here (no project metric code), with the light off the origin.

The analysis node publishes ``/analysis/time_s`` and then every metric once per simulated second,
so the k-th message of each metric topic belongs to the k-th time.
"""

import subprocess
import sys

import numpy as np
import pytest

from ..ros.test_bag import rosbags_messages
from .test_run import ENV, ROOT, cli

LIGHT = (0.25, -0.15)  # off the origin: a distance measured to the origin fails
CELL_M, ARENA_M = 0.02, 4.0
TICK_HZ = 31.0
HALF_PERIOD = 31

SCENARIOS = {
    # Moving robots: distance to the light and covered area change with time.
    "phototaxis": f"""behavior: {{kind: phototaxis, p_right: 0.5}}
light: {{kind: cone, center: [{LIGHT[0]}, {LIGHT[1]}], radius_m: 2.8284, peak: 1024.0}}
arena: {{width_m: {ARENA_M}, height_m: {ARENA_M}, coverage_cell_m: {CELL_M}}}
start: {{kind: uniform, half_width_m: 0.4, heading_rad: null, shared: false}}
""",
    # Blinkers: red / blue fractions and the Kuramoto order parameter change with time.
    "blink": f"""behavior: {{kind: blink, half_period_ticks: {HALF_PERIOD}}}
light: {{kind: cone, center: [{LIGHT[0]}, {LIGHT[1]}], radius_m: 2.8284, peak: 1024.0}}
arena: {{width_m: {ARENA_M}, height_m: {ARENA_M}, coverage_cell_m: {CELL_M}}}
start: {{kind: grid, spacing_m: 0.06}}
""",
}


def _ns(stamp) -> int:
    return stamp.sec * 10**9 + stamp.nanosec


def _led(c) -> str:
    """ColorRGBA -> 'red' / 'blue' / 'off' (the README's LED colours)."""
    if c.a == 0:
        return "off"
    return "red" if (c.r, c.g, c.b) == (1.0, 0.0, 0.0) else "blue" if (c.r, c.g, c.b) == (0.0, 0.0, 1.0) else "?"


@pytest.mark.parametrize("kind", sorted(SCENARIOS))
def test_live_metrics_equal_a_recomputation_from_the_robot_topics(kind, tmp_path):
    n, duration = 6, 4.0
    sc_file = tmp_path / f"{kind}.yaml"
    sc_file.write_text(SCENARIOS[kind])
    out = tmp_path / "bags" / kind
    res = cli("run", "--scenario", str(sc_file), "--robots", str(n), "--duration", str(duration), "--seed", "3",
              "--out", str(out))
    assert res.returncode == 0, res.stdout + res.stderr
    msgs = rosbags_messages(out)

    def topic(name):
        return [m for t, m in msgs if t == name]

    # Each robot's state per step, from its own topics (lockstep: every message is in the bag; led
    # has no stamp, its k-th message belongs to the k-th pose).
    pose = {i: {_ns(m.header.stamp): (m.pose.position.x, m.pose.position.y) for m in topic(f"/kilobot_{i}/pose")}
            for i in range(n)}
    led = {i: dict(zip(sorted(pose[i]), [_led(c) for c in topic(f"/kilobot_{i}/led")])) for i in range(n)}
    ticks = {i: {_ns(m.header.stamp): _ns(m.time_ref) / 1e9 * TICK_HZ for m in topic(f"/kilobot_{i}/clock")}
             for i in range(n)}
    steps = sorted(pose[0])
    assert len(steps) == int(duration * 10) + 1 and all(sorted(pose[i]) == steps for i in range(n))

    stamps = [round(m.data * 1e9) for m in topic("/analysis/time_s")]
    assert stamps == [k * 10**9 for k in range(int(duration) + 1)]  # once per simulated second, from t = 0
    got = {name: [m.data for m in topic(f"/analysis/{name}")] for name in
           ("led_red_fraction", "led_blue_fraction", "order_parameter", "mean_distance_to_light_m", "covered_area_m2")}
    assert all(len(v) == len(stamps) for v in got.values()), {k: len(v) for k, v in got.items()}
    assert [m.data for m in topic("/analysis/robots")] == [n] * len(stamps)

    visited: set[tuple[int, int]] = set()
    for k, t in enumerate(stamps):
        xy = np.array([pose[i][t] for i in range(n)])
        for s in steps:  # cells of every pose up to t (a cell of side CELL_M, from the arena's corner)
            if s <= t:
                for i in range(n):
                    x, y = pose[i][s]
                    visited.add((int((x + ARENA_M / 2) // CELL_M), int((y + ARENA_M / 2) // CELL_M)))
        colours = [led[i][t] for i in range(n)]
        want = {
            "led_red_fraction": colours.count("red") / n,
            "led_blue_fraction": colours.count("blue") / n,
            "mean_distance_to_light_m": float(np.mean(np.hypot(xy[:, 0] - LIGHT[0], xy[:, 1] - LIGHT[1]))),
            "covered_area_m2": len(visited) * CELL_M ** 2,
        }
        if kind == "blink":
            phase = np.array([ticks[i][t] for i in range(n)]) * 2 * np.pi / (2 * HALF_PERIOD)
            want["order_parameter"] = abs(np.mean(np.exp(1j * phase)))
        else:
            assert np.isnan(got["order_parameter"][k])  # no blink program: undefined
        for name, value in want.items():
            assert got[name][k] == pytest.approx(value, abs=1e-6), (name, t)
    # The run exercised what is compared: moving robots / blinking LEDs.
    if kind == "phototaxis":
        assert got["covered_area_m2"][-1] > got["covered_area_m2"][0]
    else:
        assert 0 < max(got["led_red_fraction"]) and 0 < max(got["led_blue_fraction"])
    # The viewer puts each recorded value at its simulated time, without the undefined ones.
    from kilobot_twin.recording.swarm_data import from_bag

    rec = from_bag(out)
    t, v = rec.recorded_metrics["mean_distance_to_light_m"]
    np.testing.assert_allclose(t, [s / 1e9 for s in stamps], atol=1e-9)
    np.testing.assert_array_equal(v, got["mean_distance_to_light_m"])
    assert ("order_parameter" in rec.recorded_metrics) == (kind == "blink") and "time_s" not in rec.recorded_metrics


SLOW_START = """import time
try:
    if b"kilobot_twin.nodes.analysis" in open("/proc/self/cmdline", "rb").read():
        time.sleep(4.0)
except OSError:
    pass
"""


def test_an_analysis_process_slow_to_start_still_has_every_value_in_the_bag(tmp_path):
    """Under load the analysis process of a `run` came up after a 4 s lockstep run had ended
    (0.15 s of wall time): the bag held no /analysis topic. Here its interpreter sleeps 4 s
    before it starts (a sitecustomize on its path); the world waits for it (``analysis@cloud``)
    and the bag holds its values from t = 0. On e3cfdc8's launcher the same run's bag held 36
    topics and none of the analysis."""
    slow = tmp_path / "slow"
    slow.mkdir()
    (slow / "sitecustomize.py").write_text(SLOW_START)
    out = tmp_path / "bags" / "slow"
    env = dict(ENV, PYTHONPATH=str(slow) + ":" + ENV["PYTHONPATH"])
    res = subprocess.run([sys.executable, "-m", "kilobot_twin", "run", "--scenario", "blink", "--robots", "6",
                          "--duration", "4", "--seed", "3", "--out", str(out)],
                         capture_output=True, text=True, env=env, cwd=ROOT, timeout=120)
    assert res.returncode == 0, res.stdout + res.stderr
    stamps = [round(m.data * 1e9) for t, m in rosbags_messages(out) if t == "/analysis/time_s"]
    assert stamps == [k * 10**9 for k in range(5)]
