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
