"""When robots take their steps: the one rule of robot nodes and swarm processes (no rclpy).

- lockstep: step 0 is published on the first ``/clock`` tick (t = 0), and step k + 1 is taken
  on the tick stamped ``(k + 1) dt`` (the world sends each step's time once);
- realtime: at wall time t since the world's start, every step up to ``floor(t / dt)`` is due
  (a late timer catches the missed steps up at once), never beyond the scenario's last step
  (the world's ``done`` may arrive late).
"""

from __future__ import annotations

from .convert import step_stamp_ns


class StepRule:
    """Decides what a robot or a swarm does on a clock tick or a timer (see the module docstring)."""

    START, STEP = "start", "step"

    def __init__(self, dt_s: float, n_steps: int):
        self.dt_s = dt_s
        self.n_steps = n_steps
        self.step_ns = step_stamp_ns(1, dt_s)
        self.started = False

    def on_clock(self, clock_ns: int, step_index: int) -> str | None:
        """Lockstep: ``START`` (publish step 0), ``STEP`` (take one step and publish) or None."""
        if clock_ns == 0 and step_index == 0 and not self.started:
            self.started = True
            return self.START
        if self.started and step_index < self.n_steps and clock_ns == step_stamp_ns(step_index + 1, self.dt_s):
            return self.STEP
        return None

    def due(self, elapsed_ns: int, step_index: int) -> int:
        """Realtime: how many steps to take now, ``elapsed_ns`` after the start."""
        return max(0, min(elapsed_ns // self.step_ns, self.n_steps) - step_index)


class LockstepPacer:
    """The world's lockstep bookkeeping (no rclpy, no wall clock): which ``/clock`` steps may go out.

    Step k goes out once every robot has reported step ``k - window_steps`` and, when the
    recorder is awaited, the recorder has acknowledged every robot data message up to step
    ``k - lag_steps``. A robot reports a step by its pose, a batched swarm for all its robots by
    its cloud (:meth:`report`). ``messages_after`` (n_steps + 1,): one robot's data messages
    written after each step (pose, light, led every step, clock on clock steps).
    """

    def __init__(self, dt_s: float, n_steps: int, window_steps: int, lag_steps: int, messages_after):
        self.dt_s, self.n_steps = dt_s, n_steps
        self.window_steps, self.lag_steps = window_steps, lag_steps
        self.messages_after = messages_after
        self.robots = 0  # robots in the run
        self.step = -1  # last step sent
        self.complete = -1  # last step every robot has reported
        self.reported: dict[int, int] = {}  # step -> robots heard from
        self.recorded = 0  # robot messages the recorder acknowledged

    def robot_messages_through(self, step: int) -> int:
        """Data messages all robots have published after step ``step``."""
        return 0 if step < 0 else self.robots * int(self.messages_after[min(step, self.n_steps)])

    def next_steps(self, await_recorder: bool) -> list[int]:
        """The steps to send now (in order); a run without robots is never held."""
        out = []
        while self.step < self.n_steps and self.step < self.complete + self.window_steps and (
                not await_recorder or self.recorded >= self.robot_messages_through(self.step + 1 - self.lag_steps)):
            self.step += 1
            out.append(self.step)
            if not self.robots:
                self.complete = self.step
        return out

    def report(self, stamp_ns: int, robots: int) -> bool:
        """``robots`` robots published the step stamped ``stamp_ns``; True if a step completed."""
        k = int(round(stamp_ns / (self.dt_s * 1e9)))
        if k <= self.complete or k > self.step or stamp_ns != step_stamp_ns(k, self.dt_s):
            return False  # not a step in flight (a stale or foreign message)
        self.reported[k] = self.reported.get(k, 0) + robots
        advanced = False
        while self.reported.get(self.complete + 1, 0) >= self.robots:
            self.complete += 1
            del self.reported[self.complete]
            advanced = True
        return advanced

    @property
    def all_reported(self) -> bool:
        return self.complete >= self.n_steps

    def all_recorded(self) -> bool:
        return self.recorded >= self.robot_messages_through(self.n_steps)
