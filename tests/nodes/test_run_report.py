"""`run`'s summary says what actually ran: after a stop, the simulated time is the bag's, not --duration."""

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

from ..ros.test_bag import rosbags_messages

ROOT = Path(__file__).resolve().parents[2]
ENV = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))


def test_stopped_run_reports_the_simulated_time_that_ran(tmp_path):
    out = tmp_path / "stopped"
    p = subprocess.Popen([sys.executable, "-m", "kilobot_twin", "run", "--scenario", "straight", "--robots", "2",
                          "--duration", "3000", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV, cwd=ROOT)
    world_log = out.parent / "stopped.logs" / "world.log"
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and "lockstep:" not in (world_log.read_text() if world_log.exists() else ""):
        time.sleep(0.2)
    time.sleep(2.0)
    p.send_signal(signal.SIGTERM)
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 130, stderr
    m = re.search(r"([0-9.e+]+) of 3000 s simulated", stdout)
    assert m, stdout
    reported = float(m.group(1))
    # The independent witness: the last pose stamp of the bag (rosbags), in simulated time.
    stamps = [msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
              for t, msg in rosbags_messages(out) if t == "/kilobot_0/pose"]
    assert 0 < reported < 3000
    assert abs(reported - stamps[-1]) <= 0.1 * 40, (reported, stamps[-1])  # within the lockstep window (32 steps)
