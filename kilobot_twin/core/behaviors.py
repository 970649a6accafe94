"""Behaviours as vectorised state machines that run on each robot's own clock.

Every behaviour keeps its state in a dict of arrays of the batch shape (runs, robots) (or ()
for one robot) and, each step, turns the robot's integer tick count and light reading into a
motion command (:data:`~kilobot_twin.core.constants.STOP`, ``FORWARD``, ``TURN_LEFT``,
``TURN_RIGHT``). Timers are deadlines in the robot's own ticks, so a fast clock runs its
program fast, as on the real robot. Durations convert to ticks with
``floor(ms * tick_hz / 1000)``, like integer ``kilo_ticks`` arithmetic: at the authors'
simulator's 10 ticks/s a delay under 100 ms therefore does nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from . import rng
from .constants import FORWARD, STOP, TURN_LEFT, TURN_RIGHT


def ms_to_ticks(ms: float, tick_hz: float) -> int:
    return int(math.floor(ms * tick_hz / 1000.0 + 1e-9))


class _Fixed:
    """A behaviour without state that always commands the same motion (``MOTION``)."""

    MOTION: ClassVar[int] = STOP

    def init_state(self, shape, reading0, tick_hz):
        return {}

    def decide(self, st, now, reading, keys, step, tick_hz):
        return np.full(np.shape(now), self.MOTION, dtype=np.int8)


@dataclass(frozen=True)
class Straight(_Fixed):
    """Drive forward with both wheels at the straight calibration values, forever."""

    MOTION: ClassVar[int] = FORWARD
    name: str = field(default="straight", init=False)
    needs_light: bool = field(default=False, init=False)


@dataclass(frozen=True)
class Blink(_Fixed):
    """Stand still; the LED program is driven by the clock (see :mod:`.clocks`)."""

    half_period_ticks: int = 30
    name: str = field(default="blink", init=False)
    needs_light: bool = field(default=False, init=False)


@dataclass(frozen=True)
class Still(_Fixed):
    """Stand still and measure light every step (a robot under the projector, paper Fig. 8)."""

    name: str = field(default="still", init=False)
    needs_light: bool = field(default=True, init=False)


@dataclass(frozen=True)
class RandomWalk:
    """The Kilobot library's random walk, as the authors ran it.

    At every decision the robot draws: forward with probability ``p_forward`` for a duration
    uniform on [forward_min_s, forward_max_s], otherwise a turn (left or right, 50/50) for a
    duration uniform on [turn_min_s, turn_max_s]. The defaults are the authors' random_walk.c:
    forward 2 s (p = 0.5), turn 1 s (about 41 degrees), each decision independent.
    """

    p_forward: float = 0.5
    forward_min_s: float = 2.0
    forward_max_s: float = 2.0
    turn_min_s: float = 1.0
    turn_max_s: float = 1.0
    name: str = field(default="random_walk", init=False)
    needs_light: bool = field(default=False, init=False)

    def init_state(self, shape, reading0, tick_hz):
        return {
            "deadline": np.zeros(shape, dtype=np.int64),
            "motion": np.full(shape, FORWARD, dtype=np.int8),
        }

    def decide(self, st, now, reading, keys, step, tick_hz):
        due = now >= st["deadline"]
        if np.any(due):
            u_kind = rng.uniform(keys, 3 * step)
            u_dur = rng.uniform(keys, 3 * step + 1)
            u_dir = rng.uniform(keys, 3 * step + 2)
            forward = u_kind < self.p_forward
            fwd_s = self.forward_min_s + (self.forward_max_s - self.forward_min_s) * u_dur
            turn_s = self.turn_min_s + (self.turn_max_s - self.turn_min_s) * u_dur
            dur_ticks = np.floor(np.where(forward, fwd_s, turn_s) * tick_hz + 1e-9).astype(np.int64)
            new_motion = np.where(forward, FORWARD, np.where(u_dir < 0.5, TURN_LEFT, TURN_RIGHT))
            st["motion"] = np.where(due, new_motion, st["motion"]).astype(np.int8)
            st["deadline"] = np.where(due, now + np.maximum(dur_ticks, 1), st["deadline"])
        return st["motion"]


# Phototaxis controller modes.
P_STEP, P_HOLD, P_GOOD, P_STOP, P_TURN, P_AFTER_TURN, P_ARRIVED = range(7)


@dataclass(frozen=True)
class Phototaxis:
    """The authors' Kilobot phototaxis controller, as a vectorised state machine.

    Each step the robot measures light (mean of 10 samples, see :func:`.light.sense`) and:

    1. If the reading is within ``arrive_tolerance`` (2) of ``reference`` it stops there
       (and moves on again if the reading later leaves that band).
    2. Otherwise, whenever its current timer has run out:

       - after a ``hold`` (200 ms of keeping its current motion, started when the reading had
         changed by more than ``change_threshold`` (20) since the last decision) it decides:
         with ``d = |reading - reference|`` against ``d_last`` of the last decision,
         ``d < d_last`` -> forward for 300 ms; ``d > d_last + worse_margin`` (1) -> stop
         100 ms, turn right with probability ``p_right`` else left for 2.1 s, then forward
         1.4 s; otherwise forward 200 ms. The decision's reading becomes ``last``.
       - in any forward or stopped-at-target mode: if ``|reading - last| > change_threshold``
         start a hold, else drive forward for another 200 ms step.

    The first reading of a run is taken as ``last``. Constants are the ones named in the
    authors' controller; where the paper is silent (what exactly happens at a hold) we keep
    the current motion and take a fresh reading at its end.
    """

    p_right: float = 0.5
    reference: float = 1024.0
    change_threshold: float = 20.0
    arrive_tolerance: float = 2.0
    worse_margin: float = 1.0
    hold_ms: float = 200.0
    forward_good_ms: float = 300.0
    stop_ms: float = 100.0
    turn_ms: float = 2100.0
    forward_after_turn_ms: float = 1400.0
    step_ms: float = 200.0
    name: str = field(default="phototaxis", init=False)
    needs_light: bool = field(default=True, init=False)

    def init_state(self, shape, reading0, tick_hz):
        return {
            "mode": np.full(shape, P_STEP, dtype=np.int8),
            "deadline": np.zeros(shape, dtype=np.int64),
            "motion": np.full(shape, FORWARD, dtype=np.int8),
            "last": np.broadcast_to(np.asarray(reading0, dtype=np.float64), shape).copy(),
        }

    def decide(self, st, now, reading, keys, step, tick_hz):
        t = {k: ms_to_ticks(getattr(self, k), tick_hz) for k in
             ("hold_ms", "forward_good_ms", "stop_ms", "turn_ms", "forward_after_turn_ms", "step_ms")}
        mode, deadline, motion, last = st["mode"], st["deadline"], st["motion"], st["last"]

        arrived = np.abs(reading - self.reference) <= self.arrive_tolerance
        due = (now >= deadline) & ~arrived

        # Decide at the end of a hold.
        decide = due & (mode == P_HOLD)
        d_new = np.abs(reading - self.reference)
        d_old = np.abs(last - self.reference)
        better = decide & (d_new < d_old)
        worse = decide & (d_new > d_old + self.worse_margin)
        same = decide & ~better & ~worse
        # After the stop: turn; after the turn: forward.
        start_turn = due & (mode == P_STOP)
        end_turn = due & (mode == P_TURN)
        # Forward-type modes (and leaving the target band): check for a change, else step on.
        plain = due & ((mode == P_STEP) | (mode == P_GOOD) | (mode == P_AFTER_TURN) | (mode == P_ARRIVED))
        changed = np.abs(reading - last) > self.change_threshold
        hold = plain & changed
        step_on = (plain & ~changed) | same

        new_mode = mode.copy()
        new_motion = motion.copy()
        new_deadline = deadline.copy()

        def set_(mask, m, mo, dur):
            if not mask.any():
                return
            np.copyto(new_mode, m, where=mask)
            if mo is not None:
                np.copyto(new_motion, mo, where=mask)
            np.copyto(new_deadline, now + dur, where=mask)

        set_(better, P_GOOD, FORWARD, t["forward_good_ms"])
        set_(worse, P_STOP, STOP, t["stop_ms"])
        set_(step_on, P_STEP, FORWARD, t["step_ms"])
        set_(hold, P_HOLD, None, t["hold_ms"])
        set_(end_turn, P_AFTER_TURN, FORWARD, t["forward_after_turn_ms"])
        if np.any(start_turn):
            right = rng.uniform(keys, step) < self.p_right
            set_(start_turn, P_TURN, np.where(right, TURN_RIGHT, TURN_LEFT).astype(np.int8), t["turn_ms"])
        np.copyto(last, reading, where=decide)
        if arrived.any():
            np.copyto(new_mode, P_ARRIVED, where=arrived)
            np.copyto(new_motion, STOP, where=arrived)

        st["mode"], st["motion"], st["deadline"] = new_mode, new_motion, new_deadline
        return new_motion


BEHAVIORS = {"straight": Straight, "blink": Blink, "still": Still, "random_walk": RandomWalk, "phototaxis": Phototaxis}


# Modes of the tick-exact ARGoS phototaxis controller.
A_SETUP, A_LOOP, A_HOLD, A_STOP, A_TURN = range(5)


def delay_ticks(ms: float, tick_hz: float) -> int:
    """Control steps one ``delay(ms)`` of ARGoS's kilolib takes: none if shorter than a tick,
    else ceil(ms / tick length) (the countdown runs until it is <= one tick)."""
    tick_ms = 1000.0 / tick_hz
    if ms < tick_ms - 1e-9:
        return 0
    return int(math.ceil(ms / tick_ms - 1e-9))


@dataclass(frozen=True)
class PhototaxisArgos:
    """The authors' ``chemotaxis_adaptive_Cond_ver3_correct(_LoR).c`` as ARGoS runs it, tick by tick.

    ARGoS resumes the program once per control step; every ``delay()`` yields one step per
    tick length (delays under one tick do nothing) and each return from ``loop()`` yields one
    more step. So, in control steps (1 step = 1 tick):

    - ``setup()``: ``delay(1000)`` standing still (motors start at 0).
    - ``loop()`` reads ``a`` (this step). If ``|a - last_light| > 20``: keep the current motion
      for 2 steps (``delay(200)``), then with ``d = |a - 2000|`` (the reading from *before* the
      delay) and ``diff = d - last_d`` (``last_d`` starts at 0): ``last_light = a``,
      ``last_d = d``; ``diff < 0`` -> forward 4 steps (delay 100 + 200 + return);
      ``diff > 1`` -> stop 1 step, turn right w.p. ``p_right`` (else left) for 21 steps
      (delay 100 + 2000), forward 15 steps (delay 1400 + return); else 1 more step of the
      current motion. Otherwise forward 3 steps (delay 200 + return).
    - ``|a - reference| < 2`` -> stop (never happens with reference 2000).
    """

    p_right: float = 0.5
    reference: float = 2000.0
    change_threshold: float = 20.0
    worse_margin: float = 1.0
    setup_ms: float = 1000.0
    hold_ms: float = 200.0
    stop_ms: float = 100.0
    turn_ms: float = 2100.0
    forward_after_turn_ms: float = 1400.0
    step_ms: float = 200.0
    good_ms: float = 300.0
    loop_overhead_ticks: int = 1
    initial_last_light: float = 0.0
    initial_last_dist: float = 0.0
    name: str = field(default="phototaxis_argos", init=False)
    needs_light: bool = field(default=True, init=False)

    def init_state(self, shape, reading0, tick_hz):
        return {
            "mode": np.full(shape, A_SETUP, dtype=np.int8),
            "deadline": np.full(shape, delay_ticks(self.setup_ms, tick_hz), dtype=np.int64),
            "motion": np.full(shape, STOP, dtype=np.int8),
            "last": np.full(shape, float(self.initial_last_light)),
            "last_d": np.full(shape, float(self.initial_last_dist)),
            "a": np.zeros(shape),
        }

    def decide(self, st, now, reading, keys, step, tick_hz):
        def dt(ms):
            return delay_ticks(ms, tick_hz)

        o = self.loop_overhead_ticks
        mode, deadline, motion = st["mode"], st["deadline"], st["motion"]
        due = now >= deadline
        new_mode, new_deadline, new_motion = mode.copy(), deadline.copy(), motion.copy()

        def set_(mask, m, mo, dur):
            if not mask.any():
                return
            np.copyto(new_mode, m, where=mask)
            if mo is not None:
                np.copyto(new_motion, mo, where=mask)
            np.copyto(new_deadline, now + dur, where=mask)

        # Loop start (also the end of setup).
        start = due & ((mode == A_LOOP) | (mode == A_SETUP))
        changed = np.abs(reading - st["last"]) > self.change_threshold
        hold = start & changed
        plain = start & ~changed
        np.copyto(st["a"], reading, where=hold)
        set_(hold, A_HOLD, None, dt(self.hold_ms))
        set_(plain, A_LOOP, FORWARD, dt(self.step_ms) + o)
        # End of the hold: decide on the reading taken at the loop start.
        dec = due & (mode == A_HOLD)
        d = np.abs(st["a"] - self.reference)
        diff = d - st["last_d"]
        better = dec & (diff < 0)
        worse = dec & (diff > self.worse_margin)
        same = dec & ~better & ~worse
        np.copyto(st["last"], st["a"], where=dec)
        np.copyto(st["last_d"], d, where=dec)
        set_(better, A_LOOP, FORWARD, dt(100) + dt(self.good_ms - 100) + o)
        set_(worse, A_STOP, STOP, dt(self.stop_ms))
        set_(same, A_LOOP, None, o)
        # After the stop: turn; after the turn: forward.
        start_turn = due & (mode == A_STOP)
        if np.any(start_turn):
            right = rng.uniform(keys, step) < self.p_right
            set_(start_turn, A_TURN, np.where(right, TURN_RIGHT, TURN_LEFT).astype(np.int8),
                 dt(100) + dt(self.turn_ms - 100))
        end_turn = due & (mode == A_TURN)
        set_(end_turn, A_LOOP, FORWARD, dt(self.forward_after_turn_ms) + o)
        st["mode"], st["motion"], st["deadline"] = new_mode, new_motion, new_deadline
        return new_motion


BEHAVIORS["phototaxis_argos"] = PhototaxisArgos
