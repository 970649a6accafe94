"""`run --scenario FILE` with `start: {kind: poses}`: the ROS twin's robots start exactly there.

The world sends the scenario as a JSON document and the swarm's robots rebuild it; the bag is
read back with rosbags (an independent reader).
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import yaml

from kilobot_twin.recording.bag import BagReader

from ..ros.test_bag import rosbags_messages

ROOT = Path(__file__).resolve().parents[2]
ENV = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
POSES = {0: [0.123456789012345, -0.987654321098765, 2.5], 1: [-1.1, 0.3333333333333333, -0.5], 2: [0.25, 0.5, 1.0]}


def cli(*args):
    return subprocess.run([sys.executable, "-m", "kilobot_twin", *args], capture_output=True, text=True, env=ENV,
                          cwd=ROOT, timeout=180)


def test_run_starts_robots_at_the_file_poses(tmp_path):
    sc_file = tmp_path / "arena.yaml"
    sc_file.write_text(yaml.safe_dump({"preset": "argos-code", "behavior": {"kind": "phototaxis_argos", "p_right": 1.0},
                                       "start": {"kind": "poses", "poses": POSES}}))
    out = tmp_path / "bags" / "poses"
    res = cli("run", "--scenario", str(sc_file), "--robots", "3", "--duration", "1", "--seed", "3", "--out", str(out))
    assert res.returncode == 0, res.stdout + res.stderr
    msgs = rosbags_messages(out)
    for i, (x, y, th) in POSES.items():
        first = next(m for t, m in msgs if t == f"/kilobot_{i}/pose")
        assert (first.pose.position.x, first.pose.position.y) == (x, y)
        q = first.pose.orientation
        assert math.isclose(2 * math.atan2(q.z, q.w), th, abs_tol=1e-12)
    doc = json.loads(BagReader(out).metadata()["kilobot_twin"]["scenario"])
    assert doc["start"]["kind"] == "poses"
    assert {int(k): v for k, v in doc["start"]["poses"].items()} == POSES


def test_run_refuses_a_robot_without_a_pose_before_starting(tmp_path):
    sc_file = tmp_path / "arena.yaml"
    sc_file.write_text(yaml.safe_dump({"behavior": "straight", "start": {"kind": "poses", "poses": {0: [0, 0, 0]}}}))
    out = tmp_path / "bags" / "x"
    res = cli("run", "--scenario", str(sc_file), "--robots", "2", "--duration", "1", "--out", str(out))
    assert res.returncode == 2, res.stdout + res.stderr
    assert len(res.stderr.strip().splitlines()) == 1 and "no start pose for robot 1" in res.stderr
    assert not (tmp_path / "bags").exists()
