"""The core must not import middleware: a fresh interpreter imports it and we look."""

import subprocess
import sys

FORBIDDEN = ("rclpy", "mcap", "rerun", "rosbags", "std_msgs", "geometry_msgs")


def test_core_and_batch_import_no_middleware():
    code = (
        "import sys, kilobot_twin.core.sim, kilobot_twin.core.light, kilobot_twin.batch;"
        f"bad=[m for m in sys.modules if m.split('.')[0] in {FORBIDDEN!r}];"
        "print(','.join(bad))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"core imported middleware: {out.stdout}"
