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
    # The plain build's nodes start (what `ros2 run kilobot_twin <node>` executes), from the install
    # space alone: the checkout is not on the path.
    site = ws / "install" / "kilobot_twin" / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    run_env = dict(env, PYTHONPATH=str(site))
    for exe in ("robot", "swarm", "world", "analysis", "recorder", "replay"):
        mod = subprocess.run([sys.executable, "-c", f"import kilobot_twin.nodes.{exe} as m; print(m.__file__)"],
                             capture_output=True, text=True, cwd=ws, env=run_env, timeout=60)
        assert mod.stdout.strip().startswith(str(site)), (exe, mod.stdout + mod.stderr)
    world = subprocess.run([str(lib / "world"), "--ros-args", "-p", "robots:=0", "-p", "duration_s:=1.0"],
                           capture_output=True, text=True, cwd=ws, env=run_env, timeout=60)
    assert world.returncode == 0, world.stdout + world.stderr
