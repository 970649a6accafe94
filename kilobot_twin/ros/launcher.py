"""``kilobot-twin run``: start recorder, analysis, world and swarm as processes, watch, stop, sum up.

This is what ``launch/twin.launch.py`` does on a full ROS install, plus supervision: the
processes are started in the order that loses no message (recorder first; the world holds
the start until the recorder subscribes to every robot topic), watched, and stopped in the
order that finalises the bag (robots and world, then analysis, then the recorder with
SIGINT so that it writes the MCAP summary and ``metadata.yaml``). Ctrl-C or SIGTERM on
``run`` takes the same path. A process that dies early is reported and the others are still
stopped cleanly. No rclpy import here: the nodes run in their own interpreters.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ConfigError, is_number
from ..outputs import check_out_dir
from ..recording.topics import topic_group
from ..core.scenarios import NAMED, is_scenario_file, load_swarm_traits, named_scenario, scenario_file

#: Fast DDS profiles for the node processes (shared-memory queues sized for swarm bursts).
FASTDDS_PROFILES = Path(__file__).with_name("fastdds.xml")


@dataclass
class Child:
    name: str
    proc: subprocess.Popen
    log: Path
    returncode: int | None = None
    stopped_by_us: bool = False

    def _lines(self) -> list[str]:
        try:
            return [ln for ln in self.log.read_text(errors="replace").splitlines() if ln.strip()]
        except OSError:
            return []

    def last_error_line(self) -> str:
        lines = self._lines()
        err = [ln for ln in lines if "error" in ln.lower() or "Traceback" in ln or "ERROR" in ln]
        return (err or lines or [""])[-1]

    def last_line(self, containing: str) -> str:
        """The log's last line that contains ``containing`` ("" if none)."""
        return next((ln for ln in reversed(self._lines()) if containing in ln), "")


@dataclass
class RunReport:
    bag: Path
    mode: str
    robots: int
    sim_s: float | None  # simulated seconds that actually ran (None: unknown)
    wall_s: float | None = None
    real_time_factor: float | None = None
    counts: dict = field(default_factory=dict)
    published: dict = field(default_factory=dict)
    problems: list = field(default_factory=list)
    interrupted: bool = False
    swarm_stats: dict = field(default_factory=dict)
    planned_s: float | None = None  # --duration

    @property
    def ok(self) -> bool:
        return not self.problems and not self.interrupted

    def grouped_counts(self) -> dict[str, tuple[int, int]]:
        """``{"/kilobot_*/pose": (messages, topics), "/clock": (n, 1), ...}``."""
        out: dict[str, list] = {}
        for topic, n in sorted(self.counts.items()):
            key = topic_group(topic)
            acc = out.setdefault(key, [0, 0])
            acc[0] += n
            acc[1] += 1
        return {k: (v[0], v[1]) for k, v in out.items()}

    def text(self) -> str:
        if self.sim_s is None:
            ran = "simulated time unknown"
        elif self.planned_s is not None and abs(self.sim_s - self.planned_s) > 1e-9:
            ran = f"{self.sim_s:g} of {self.planned_s:g} s simulated"
        else:
            ran = f"{self.sim_s:g} s simulated"
        lines = [f"bag: {self.bag}  ({self.mode}, {self.robots} robots, {ran})"]
        if self.wall_s is not None:
            lines.append(f"wall time {self.wall_s:.2f} s, real-time factor {self.real_time_factor:.2f}")
        lines.append("messages per topic:")
        for key, (n, topics) in self.grouped_counts().items():
            kind = key.rsplit("/", 1)[-1]
            pub = self.published.get(kind) if key.startswith("/kilobot_*/") else None
            extra = f"  (published {pub}, recorded {100.0 * n / pub:.2f} %)" if pub else ""
            lines.append(f"  {key:<36} {n:>9}" + (f" over {topics} topics" if topics > 1 else "") + extra)
        if self.interrupted:
            lines.append("interrupted: the bag was finalised")
        for p in self.problems:
            lines.append(f"problem: {p}")
        return "\n".join(lines)


def _node_cmd(name: str, **params) -> list[str]:
    cmd = [sys.executable, "-m", f"kilobot_twin.nodes.{name}", "--ros-args"]
    for k, v in params.items():
        if isinstance(v, bool):
            v = "true" if v else "false"
        elif isinstance(v, str) and (v == "" or v.strip() != v):
            v = f"'{v}'"
        cmd += ["-p", f"{k}:={v}"]
    return cmd


def validate(scenario: str, robots: int, duration: float, seed: int, mode: str, traits: str | None, out: str,
             swarms: int = 1, timeout_s: float | None = None):
    """Reject bad input before any process starts (one line naming the option; exit 2)."""
    sc = None
    if is_scenario_file(scenario):
        sc = scenario_file(scenario, duration, field="--scenario")
        if sc.start.kind == "poses":  # every robot of the run has its start pose (run 0)
            sc.start.pose_table([0], load_swarm_traits(traits, robots, seed, field="--traits").ids, scenario)
    elif scenario not in NAMED:
        raise ConfigError("--scenario", f"unknown scenario {scenario!r}",
                          f"use one of {', '.join(NAMED)} or a scenario YAML file")
    if mode not in ("lockstep", "realtime"):
        raise ConfigError("--mode", f"unknown mode {mode!r}", "use lockstep or realtime")
    if robots < 1:
        raise ConfigError("--robots", f"must be >= 1, got {robots}", "give the number of robots")
    if not 1 <= swarms <= robots:
        raise ConfigError("--swarms", f"must be between 1 and --robots ({robots}), got {swarms}",
                          "give the number of swarm processes, e.g. --swarms 3")
    if swarms > 1 and (sc or named_scenario(scenario)).coupling_per_s > 0:
        raise ConfigError("--swarms", "Kuramoto coupling acts within one swarm process only",
                          "run a coupled scenario (sync) with --swarms 1")
    if not (is_number(duration) and duration > 0):
        raise ConfigError("--duration", f"must be a positive finite number, got {duration}", "give simulated seconds")
    if timeout_s is not None and not (is_number(timeout_s) and timeout_s > 0):
        raise ConfigError("--timeout", f"must be a positive finite number, got {timeout_s}",
                          "give wall seconds, or leave it out for the default")
    if seed < 0:
        raise ConfigError("--seed", f"must be >= 0, got {seed}", "give a non-negative integer")
    if traits:
        load_swarm_traits(traits, robots, seed, field="--traits")
    check_out_dir(out, field="--out", new=True)  # not a file, not under a file, never over a bag


def run_twin(scenario: str = "phototaxis", robots: int = 10, duration: float = 20.0, seed: int = 0,
             mode: str = "lockstep", traits: str | None = None, out: str = "bags/run", timeout_s: float | None = None,
             echo=None, install_signal_handlers: bool = True, swarms: int = 1) -> RunReport:
    """Run the twin as separate processes; returns a :class:`RunReport` (bag finalised in every case).

    ``echo(str)`` receives progress lines.
    """
    validate(scenario, robots, duration, seed, mode, traits, out, swarms, timeout_s)
    echo = echo or (lambda s: None)
    bag = Path(out)
    logs = bag.parent / f"{bag.name}.logs"
    logs.mkdir(parents=True, exist_ok=True)
    if timeout_s is None:
        timeout_s = 60.0 + (duration * 1.5 if mode == "realtime" else duration * 2.0)
    world_scenario = ({"scenario_file": str(Path(scenario).resolve())} if is_scenario_file(scenario)
                      else {"scenario": scenario})
    swarm_names = ["swarm"] if swarms == 1 else [f"swarm_{k}" for k in range(swarms)]
    swarm_stats = [logs / f"{name}_stats.json" for name in swarm_names]
    world_stats = logs / "world_stats.json"
    for f in (*swarm_stats, world_stats):
        f.unlink(missing_ok=True)
    cmds = {
        "recorder": _node_cmd("recorder", out=str(bag)),
        "analysis": _node_cmd("analysis"),
        "world": _node_cmd("world", **world_scenario, duration_s=float(duration), seed=seed, robots=robots, mode=mode,
                           wait_for_nodes="recorder,analysis@cloud", stats_file=str(world_stats)),
    }
    for k, (name, stats) in enumerate(zip(swarm_names, swarm_stats)):
        # Swarm k of K owns the k-th block of robot ids; its own node name keeps its topics apart.
        cmds[name] = _node_cmd("swarm", robots=robots, seed=seed, traits_file=traits or "", stats_file=str(stats),
                               slices=swarms, slice_index=k) + ["-r", f"__node:={name}"]
    report = RunReport(bag=bag, mode=mode, robots=robots, sim_s=None, planned_s=float(duration))
    dt_s = (scenario_file(scenario) if is_scenario_file(scenario) else named_scenario(scenario)).dt_s
    children: dict[str, Child] = {}
    stop_request = {"signal": None}

    def on_signal(signum, frame):
        stop_request["signal"] = signum

    old = {}
    if install_signal_handlers:
        for s in (signal.SIGINT, signal.SIGTERM):
            old[s] = signal.signal(s, on_signal)
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env.setdefault("FASTRTPS_DEFAULT_PROFILES_FILE", str(FASTDDS_PROFILES))
    try:
        for name in cmds:  # recorder first: the world holds the start until it subscribes
            log = logs / f"{name}.log"
            fh = open(log, "w")
            # Own process group: a Ctrl-C in the terminal reaches `run` only, which then stops
            # the children in order.
            proc = subprocess.Popen(cmds[name], stdout=fh, stderr=subprocess.STDOUT, env=env, start_new_session=True)
            fh.close()
            children[name] = Child(name, proc, log)
            echo(f"started {name} (pid {proc.pid}), log {log}")
        t0 = time.monotonic()
        while True:
            if stop_request["signal"] is not None:
                report.interrupted = True
                echo(f"received {signal.Signals(stop_request['signal']).name}: stopping")
                break
            for c in children.values():
                if c.returncode is None:
                    c.returncode = c.proc.poll()
            w = children["world"]
            if w.returncode == 0:
                break
            dead = [c for c in children.values() if c.returncode is not None and c.name != "world"]
            if w.returncode not in (None, 0):
                dead.append(w)
            if dead:
                for c in dead:
                    msg = f"{c.name} exited early with code {c.returncode}"
                    line = c.last_error_line()
                    report.problems.append(msg + (f": {line}" if line else "") + f" (log {c.log})")
                    echo(report.problems[-1])
                break
            if time.monotonic() - t0 > timeout_s:
                report.problems.append(timeout_problem(timeout_s, w, logs))
                break
            time.sleep(0.05)
        time.sleep(0.3)  # let the last messages reach the recorder
    finally:
        for name in ("world", *swarm_names, "analysis", "recorder"):
            if name in children:
                _stop(children[name], 20.0 if name == "recorder" else 10.0)
        for s, h in old.items():
            signal.signal(s, h)
    rec = children.get("recorder")
    if rec is not None and rec.returncode not in (0, None) and rec.stopped_by_us and rec.returncode < 0:
        report.problems.append(f"recorder did not stop cleanly (code {rec.returncode}); try `kilobot-twin bag repair {bag}`")
    _fill_report(report, swarm_stats, world_stats, dt_s)
    return report


def timeout_problem(timeout_s: float, world: Child, logs: Path) -> str:
    """The line a run that timed out reports; with what a world that never started waited for."""
    said = world.last_line("waiting for")
    return (f"timed out after {timeout_s:.0f} s (world not done" + (f": {said.split(']: ', 1)[-1]}" if said else "")
            + f"; see {logs})")


def _stop(c: Child, timeout_s: float) -> None:
    if c.proc.poll() is not None:
        c.returncode = c.proc.returncode
        return
    c.stopped_by_us = True
    for sig, wait in ((signal.SIGINT, timeout_s), (signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
        try:
            c.proc.send_signal(sig)
        except ProcessLookupError:
            break
        try:
            c.proc.wait(wait)
            break
        except subprocess.TimeoutExpired:
            continue
    c.returncode = c.proc.poll()


def _fill_report(report: RunReport, swarm_stats: list[Path], world_stats: Path, dt_s: float) -> None:
    from ..recording.bag import BagReader

    try:
        report.counts = BagReader(report.bag).counts()
    except Exception as exc:  # noqa: BLE001 - reported, not raised: the run is over
        report.problems.append(f"could not read the bag summary: {exc}")
    if world_stats.is_file():
        ws = json.loads(world_stats.read_text())
        report.wall_s = ws["wall_s"]
        report.real_time_factor = ws["real_time_factor"]
        report.sim_s = float(ws["sim_s"])
    parts = [json.loads(f.read_text()) for f in swarm_stats if f.is_file()]
    if parts:
        ss = merge_swarm_stats(parts)
        report.swarm_stats = ss
        report.published = ss["published_per_topic"]
        samples = max(ss["per_robot_samples"].values(), default=0)
        if report.sim_s is None and samples:  # stopped early: what the robots stepped (sample 0 is t = 0)
            report.sim_s = (samples - 1) * dt_s


def merge_swarm_stats(parts: list[dict]) -> dict:
    """The stats of K swarm processes as one swarm's: counts, CPU and the memory the robots took
    added, robots joined, wall time and a process's memory the largest."""
    out = dict(parts[0])
    for key in ("robots", "samples_published", "messages_published", "cpu_s", "late_steps", "rss_before_robots_bytes",
                "rss_after_robots_bytes"):
        out[key] = sum(p.get(key, 0) for p in parts)
    for key in ("wall_s", "rss_bytes"):
        out[key] = max(p.get(key, 0) for p in parts)
    out["per_robot_samples"] = {k: v for p in parts for k, v in (p.get("per_robot_samples") or {}).items()}
    out["published_per_topic"] = {t: sum((p.get("published_per_topic") or {}).get(t, 0) for p in parts)
                                  for t in parts[0].get("published_per_topic") or {}}
    out["processes"] = len(parts)
    return out
