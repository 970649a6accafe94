"""The step rule of robots and swarms, without rclpy: against hand-written tick sequences."""

from kilobot_twin.ros.stepping import StepRule


def test_lockstep_publishes_step_0_then_one_step_per_new_tick():
    rule = StepRule(dt_s=0.1, n_steps=3)
    k, actions = 0, []
    # /clock as the world sends it (t = 0, 0.1, 0.2, 0.3 s), with a repeated and a stale tick.
    for ns in (0, 0, 100_000_000, 100_000_000, 200_000_000, 100_000_000, 300_000_000, 400_000_000):
        a = rule.on_clock(ns, k)
        actions.append(a)
        k += a == StepRule.STEP
    assert actions == ["start", None, "step", None, "step", None, "step", None]  # never past step 3
    assert k == 3


def test_lockstep_waits_for_the_first_tick():
    rule = StepRule(dt_s=0.1, n_steps=10)
    assert rule.on_clock(100_000_000, 0) is None  # step 1's tick before step 0 was published
    assert rule.on_clock(0, 0) == "start"


def test_lockstep_tick_of_a_step_that_does_not_divide_a_second():
    rule = StepRule(dt_s=1 / 31, n_steps=100)
    rule.on_clock(0, 0)
    assert rule.on_clock(32_258_065, 0) == "step"  # round(1e9 / 31)
    assert rule.on_clock(64_516_129, 1) == "step"  # round(2e9 / 31)


def test_realtime_catches_up_and_stops_at_the_last_step():
    rule = StepRule(dt_s=0.1, n_steps=10)
    assert rule.due(50_000_000, 0) == 0       # 0.05 s: nothing due yet
    assert rule.due(350_000_000, 0) == 3      # a late timer takes steps 1-3 at once
    assert rule.due(350_000_000, 3) == 0
    assert rule.due(5_000_000_000, 3) == 7    # never beyond step 10


def _pacer(n_steps=5, window=2, lag=1, robots=2):
    from kilobot_twin.ros.stepping import LockstepPacer

    # One robot's messages after step k: 3 per step (pose, light, led) + a clock at steps 0 and 5.
    after = [3 * (k + 1) + 1 + (k >= 5) for k in range(n_steps + 1)]
    p = LockstepPacer(0.1, n_steps, window, lag, after)
    p.robots = robots
    return p


def test_pacer_sends_a_window_ahead_of_the_slowest_robot():
    p = _pacer()
    assert p.next_steps(await_recorder=False) == [0, 1]  # window 2: steps 0 and 1 before any report
    assert not p.report(0, 1)  # one robot of two
    assert p.report(0, 1) and p.complete == 0
    assert p.next_steps(False) == [2]
    assert not p.report(300_000_000, 2)  # a step not sent yet: ignored
    assert not p.report(150_000_000, 2)  # not a step's stamp: ignored
    p.report(100_000_000, 2)
    p.report(200_000_000, 2)
    assert p.next_steps(False) == [3, 4]


def test_pacer_waits_for_the_recorder():
    p = _pacer(window=10, lag=1)
    # Step 0 needs nothing recorded (step -1); step 1 needs both robots' messages of step 0 (2 x 4).
    assert p.next_steps(await_recorder=True) == [0]
    p.recorded = 7
    assert p.next_steps(True) == []
    p.recorded = 8
    assert p.next_steps(True) == [1]
    p.recorded = 2 * (3 * 6 + 2)  # everything through step 5
    assert p.next_steps(True) == [2, 3, 4, 5] and p.all_recorded()


def test_pacer_without_robots_runs_free():
    p = _pacer(robots=0)
    assert p.next_steps(True) == [0, 1, 2, 3, 4, 5] and p.all_reported
