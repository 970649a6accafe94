"""`colcon build` (colcon-core + colcon-ros from PyPI) installs every node where `ros2 run` looks."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXECUTABLES = ("robot", "swarm", "world", "analysis", "recorder", "replay", "kilobot-twin")


def test_colcon_build_installs_executables_and_ament_index(tmp_path):
    ws = tmp_path / "ws"
    (ws / "src").mkdir(parents=True)
    ignore = shutil.ignore_patterns(".git", ".venv", "bags", "build", "install", "log", "__pycache__", "*.egg-info",
                                    "out", "results")
    shutil.copytree(ROOT, ws / "src" / "kilobot_twin", ignore=ignore)
    colcon = str(Path(sys.executable).with_name("colcon"))
    env = dict(os.environ, PYTHONPATH="")
    res = subprocess.run([colcon, "build", "--base-paths", "src"], cwd=ws, capture_output=True, text=True, env=env,
                         timeout=300)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    lib = ws / "install" / "kilobot_twin" / "lib" / "kilobot_twin"
    for exe in EXECUTABLES:
        assert (lib / exe).is_file() and os.access(lib / exe, os.X_OK), exe
    share = ws / "install" / "kilobot_twin" / "share"
    assert (share / "ament_index" / "resource_index" / "packages" / "kilobot_twin").is_file()
    assert (share / "kilobot_twin" / "package.xml").is_file()
    assert (share / "kilobot_twin" / "launch" / "twin.launch.py").is_file()
