"""muscle_node's step scheduling and health bookkeeping (vm_ros.node.timing, vm_ros.node.health;
no ROS needed)."""

from __future__ import annotations

import math

import pytest

from vm_ros.node.health import (
    ISSUE_KINDS,
    DurationWindow,
    Issue,
    IssueLog,
    SequenceGaps,
    format_seconds,
    format_value,
)
from vm_ros.node.timing import StepScheduler

MS = 1_000_000


def run(scheduler: StepScheduler, now_ns: int, end_on_multiple_of: int = 0) -> int:
    scheduler.went_backwards(now_ns)
    due = scheduler.due(now_ns, end_on_multiple_of)
    for _ in range(due):
        scheduler.advance()
    return due


def test_steps_follow_elapsed_time_exactly():
    s = StepScheduler(MS, max_catch_up_steps=50)
    s.start(5_000 * MS)
    assert run(s, 5_000 * MS + MS // 2) == 0
    assert run(s, 5_001 * MS) == 1
    assert run(s, 5_011 * MS + 999_999) == 10  # a late tick catches up
    assert s.model_time_ns == 5_011 * MS
    assert s.catch_up_ticks == 1 and s.skipped_ns == 0


def test_a_tick_of_its_period_is_not_a_catch_up():
    """With a tick every 10 steps (batch_steps), 10 steps due is on time; 11 is a catch-up."""
    s = StepScheduler(MS, max_catch_up_steps=50, steps_per_tick=10)
    s.start(0)
    assert run(s, 10 * MS) == 10 and s.catch_up_ticks == 0
    assert run(s, 21 * MS) == 11 and s.catch_up_ticks == 1
    with pytest.raises(ValueError):
        StepScheduler(MS, 50, steps_per_tick=0)


def test_a_late_tick_ends_on_a_multiple_and_the_rest_waits():
    """Publishing every 10 steps: a tick 13 steps due runs 10 (to the publish step) and the 3
    past it wait for the next tick, which runs them with its own 10; fewer than the steps to the
    next multiple all run; nothing is lost (model time follows the clock at each multiple)."""
    s = StepScheduler(MS, max_catch_up_steps=50, steps_per_tick=10)
    s.start(0)
    assert run(s, 13 * MS, end_on_multiple_of=10) == 10
    assert run(s, 20 * MS, end_on_multiple_of=10) == 10 and s.model_time_ns == 20 * MS
    assert run(s, 27 * MS, end_on_multiple_of=10) == 7   # not past the next multiple: all run
    assert run(s, 55 * MS, end_on_multiple_of=10) == 23  # to 50: 3 to the multiple, then 20
    assert s.total_steps == 50 and s.skipped_ns == 0
    assert run(s, 55 * MS) == 5  # without the option every due step runs


def test_catch_up_is_bounded_and_the_rest_skipped():
    s = StepScheduler(MS, max_catch_up_steps=20)
    s.start(0)
    assert run(s, 500 * MS) == 20
    assert s.model_time_ns == 500 * MS  # skipped 480 steps: the model is back on time
    assert s.skipped_ns == 480 * MS and s.stalls == 1
    assert s.total_steps == 20
    assert run(s, 501 * MS) == 1


def test_time_skipped_after_a_stall_keeps_the_publish_steps_in_phase_with_the_ticks():
    """Publishing every 10 steps, ticks 0.5 ms after each multiple of 10 ms: a stall of 73.5
    ms (more than the 50 steps' catch-up) skips 30 steps, whole publish periods, so the tick
    after it and every later one end at the publish step just behind it, as before the stall.
    Skipping the 23 steps beyond the catch-up moved the publish steps 3 ms behind the ticks:
    every tick after ended at the publish step before it, 7.5 ms behind the clock, a catch-up
    each time."""
    s = StepScheduler(MS, max_catch_up_steps=50, steps_per_tick=10)
    s.start(0)
    for k in range(1, 4):
        assert run(s, k * 10 * MS + MS // 2, end_on_multiple_of=10) == 10
    assert run(s, 30 * MS + MS // 2 + 73 * MS, end_on_multiple_of=10) == 40
    assert s.skipped_ns == 30 * MS and s.stalls == 1 and s.total_steps % 10 == 0
    catch_up = s.catch_up_ticks
    for k in range(11, 20):
        now = k * 10 * MS + MS // 2
        assert run(s, now, end_on_multiple_of=10) == 10
        assert now - s.model_time_ns == MS // 2
    assert s.catch_up_ticks == catch_up
    plain = StepScheduler(MS, max_catch_up_steps=50)  # without the option: the rest exactly
    plain.start(0)
    assert run(plain, 73 * MS + MS // 2) == 50 and plain.skipped_ns == 23 * MS
    short = StepScheduler(MS, max_catch_up_steps=5)  # a catch-up shorter than a period: no
    short.start(0)                                   # whole period fits, the rest exactly
    assert run(short, 7 * MS, end_on_multiple_of=10) == 5 and short.skipped_ns == 2 * MS
    assert run(short, 30 * MS, end_on_multiple_of=10) == 3 and short.skipped_ns == 22 * MS


def test_time_going_backwards_reanchors():
    s = StepScheduler(MS, max_catch_up_steps=50)
    s.start(10_000 * MS)
    run(s, 10_005 * MS)
    assert s.went_backwards(2_000 * MS)
    assert s.backward_jumps == 1 and s.model_time_ns == 2_000 * MS
    assert s.due(2_000 * MS) == 0
    assert run(s, 2_003 * MS) == 3
    assert s.total_steps == 8


def test_hold_pauses_without_catch_up():
    s = StepScheduler(MS, max_catch_up_steps=50)
    s.start(0)
    run(s, 10 * MS)
    s.hold(110 * MS)
    assert s.paused_ns == 100 * MS
    assert run(s, 111 * MS) == 1 and s.stalls == 0



def test_a_pause_keeps_the_publish_steps_in_phase_with_the_ticks():
    """Publishing every 10 steps, ticks 0.5 ms after each multiple of 10 ms; paused from the
    tick at 40.5 ms to the one at 60.5 ms, whose wake-up comes 2.2 ms late (62.7 ms): the time
    held is whole periods (30 steps), the 2 steps beyond stay due, and every tick after the
    pause runs its 10 steps to the publish step just behind it. Holding all 32 steps moved the
    publish steps 2 ms behind the ticks: every later tick ran 2 steps, left 8 waiting and ended
    8 ms behind the clock."""
    s = StepScheduler(MS, max_catch_up_steps=50, steps_per_tick=10)
    s.start(0)
    for k in range(1, 4):
        assert run(s, k * 10 * MS + MS // 2, end_on_multiple_of=10) == 10
    for now in (40 * MS + MS // 2, 50 * MS + MS // 2, 62 * MS + 7 * MS // 10):
        s.hold(now, whole_multiple_of=10)
    assert s.paused_ns == 30 * MS and s.model_time_ns == 60 * MS
    for k in range(7, 12):
        now = k * 10 * MS + MS // 2
        assert run(s, now, end_on_multiple_of=10) == 10
        assert now - s.model_time_ns == MS // 2 and s.total_steps % 10 == 0
    plain = StepScheduler(MS, max_catch_up_steps=50)  # without a multiple: every step held
    plain.start(0)
    plain.hold(62 * MS + 7 * MS // 10)
    assert plain.paused_ns == 62 * MS

def test_scheduler_rejects_nonsense():
    with pytest.raises(ValueError):
        StepScheduler(0, 10)
    with pytest.raises(RuntimeError):
        _ = StepScheduler(MS, 10).model_time_ns


def test_issue_log_counts_everything_and_throttles_per_kind():
    log = IssueLog(throttle_s=2.0)
    first = log.record(Issue("non_finite", "excitation: nan"), now_s=0.0)
    assert first is not None and "excitation: nan" in first
    assert log.record(Issue("non_finite", "again"), now_s=0.5) is None
    assert log.record(Issue("unknown_name", "x", count=3), now_s=0.6) is not None  # other kind
    assert log.record(Issue("non_finite", "again"), now_s=1.0) is None
    later = log.record(Issue("non_finite", "later"), now_s=2.5)
    assert later is not None and "+2 more" in later
    assert log.counts["non_finite"] == 4 and log.counts["unknown_name"] == 3
    assert log.total() == 7


def test_every_issue_kind_has_a_label_with_and_a_behaviour():
    for kind, (label, behaviour) in ISSUE_KINDS.items():
        assert label and behaviour, kind
    with pytest.raises(ValueError):
        Issue("bogus", "text")


def test_duration_window_percentiles():
    window = DurationWindow(capacity=8)
    assert all(math.isnan(v) for v in window.percentiles_ms())
    for ms in range(1, 11):  # 10 samples into 8 slots: the last 8 are kept
        window.add(ms * MS)
    p50, p99, top = window.percentiles_ms()
    assert window.count == 10 and top == pytest.approx(10.0) and 3.0 <= p50 <= 8.0 <= p99
    window.clear()
    assert window.count == 0


def test_format_value():
    assert format_value(None) == "never"
    assert format_value(0.123456) == "0.123456"
    # 4 digits showed 1000000.05 s as 1e+06, and a later skip of 0.05 s changed nothing
    assert format_value(1e6 + 0.05) == "1000000.05" != format_value(1e6)
    assert format_seconds(1_000_000_050_000_000) == "1000000.05"
    assert format_seconds(9_900_000_000) == "9.9" and format_seconds(0) == "0"
    assert format_seconds(1) == "0.000000001"
    assert format_value(float("nan")) == "nan"
    assert format_value(True) == "true"
    assert format_value(12) == "12"


def test_sequence_gaps_count_lost_messages_per_publisher():
    gaps = SequenceGaps()
    assert gaps.supported is None
    assert [gaps.add(s) for s in (5, 6, 7, 10, 11)] == [0, 0, 0, 2, 0]  # 8, 9 lost
    assert [gaps.add(s) for s in (1, 2, 12, 4, 15)] == [0, 0, 0, 1, 2]  # a second publisher
    assert gaps.lost == 5 and gaps.supported


def test_sequence_gaps_without_numbers_count_nothing_and_say_so():
    gaps = SequenceGaps()
    assert gaps.add(None) == 0 and gaps.add(0) == 0
    assert gaps.supported is False and gaps.lost == 0


def test_stale_lines_name_the_policy_in_force():
    for policy in ("hold", "zero_drive", "pause"):
        log = IssueLog()
        line = log.record(Issue("stale_kinematics", "kinematics stale",
                                behaviour=f"x (stale_input_policy {policy})"), 0.0)
        assert line.endswith(f"(stale_input_policy {policy})")
