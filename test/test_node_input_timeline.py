"""muscle_node places each input at its arrival (vm_ros.node.input_timeline): the steps of a tick
that start before a message use what was held before it, the ones from its arrival on use it,
the same inputs a replay gets by applying the messages at their times and sampling step by step
(NodeInputs.sample, vm_ros.node.replay). Before, a tick's messages were all placed at the model
time reached when they arrived, so the last of a period's samples drove the whole period."""

from __future__ import annotations

import numpy as np
import pytest

from vm_ros.model import MuscleBank
from vm_ros.node.input_timeline import InputTimeline
from vm_ros.node.inputs import (
    InputLimits,
    NodeInputs,
    input_time_ns,
    physical_path_length_range,
)
from vm_ros.node.params import NodeConfig

MUSCLES = ("vasti", "rectus_femoris")
MS = 1_000_000


@pytest.fixture(scope="module")
def bank():
    return MuscleBank.from_config(list(MUSCLES))


def make_inputs(bank):
    config = NodeConfig.from_values({"muscles": list(MUSCLES)})
    return NodeInputs(bank.names, InputLimits.for_bank(bank, config))


def messages(bank, count, start_ns, period_ns, seed=0):
    """``count`` (time, drive, length, velocity) messages, one every ``period_ns`` with a jitter."""
    rng = np.random.default_rng(seed)
    lo, hi = physical_path_length_range(bank, 0.0)
    times = start_ns + period_ns * np.arange(count) + rng.integers(0, period_ns // 2, count)
    return [(int(t), rng.uniform(0, 1, 2), lo + (hi - lo) * rng.uniform(0.3, 0.7, 2),
             rng.uniform(-0.2, 0.2, 2)) for t in times]


def apply(inputs, message):
    t, drive, length, velocity = message
    inputs.on_excitation(MUSCLES, drive, t)
    inputs.on_kinematics(MUSCLES, length, velocity, t)


def test_each_step_uses_the_messages_that_arrived_before_it_as_a_replay_does(bank):
    step, start = MS, 1000 * MS
    msgs = messages(bank, 60, start + 1, 700_000)  # faster than the steps, with jitter
    node, replay = make_inputs(bank), make_inputs(bank)
    apply(node, msgs[0])
    apply(replay, msgs[0])
    timeline = InputTimeline(node)
    pending = iter(msgs[1:])
    waiting = next(pending)
    model_ns, got, expected = start, [], []
    for _ in range(5):  # ticks of 10 steps; the messages of a tick arrive before it runs
        end = model_ns + 10 * step
        while waiting is not None and waiting[0] <= end:
            apply(node, waiting)
            timeline.record(waiting[0])
            waiting = next(pending, None)
        times = model_ns + step * np.arange(10)
        u, lp, vp, _ = timeline.sample_many(times)
        got.append(np.concatenate([u, lp, vp], axis=1))
        timeline.consume(end)
        model_ns = end
    replayed = iter(msgs[1:])
    waiting = next(replayed)
    for t in start + step * np.arange(50):  # the replay: messages at or before each step's start
        while waiting is not None and waiting[0] <= t:
            apply(replay, waiting)
            waiting = next(replayed, None)
        expected.append(np.concatenate(replay.sample(int(t))))
    got = np.concatenate(got)
    np.testing.assert_array_equal(got, np.array(expected))
    # and a tick's steps do not all take its last sample (what the node did before)
    assert len(np.unique(got[:10, 0])) > 5


def test_a_message_after_the_last_step_waits_for_the_next_tick(bank):
    inputs = make_inputs(bank)
    first, late = messages(bank, 2, 0, 50 * MS)
    apply(inputs, first)
    timeline = InputTimeline(inputs)
    late = (20 * MS + 500_000, *late[1:])  # after the tick's last step start (19 ms)
    apply(inputs, late)
    timeline.record(late[0])
    u, _, _, rows = timeline.sample_many(10 * MS + MS * np.arange(10))
    np.testing.assert_array_equal(u, np.tile(first[1], (10, 1)))
    assert rows.tolist() == [0] * 10
    timeline.consume(20 * MS)
    assert timeline.pending == 1  # kept for the next tick
    u, _, _, rows = timeline.sample_many(20 * MS + MS * np.arange(2))
    np.testing.assert_array_equal(u, [first[1], late[1]])
    timeline.consume(22 * MS)
    assert timeline.pending == 0
    u, *_ = timeline.sample_many([22 * MS])
    np.testing.assert_array_equal(u[0], late[1])  # the held inputs once consumed


def test_out_of_order_arrival_times_are_kept_in_order(bank):
    """A message placed before the previous one (a stamp older than the last message's) takes
    the previous one's place, and supersedes it there."""
    inputs = make_inputs(bank)
    a, b = messages(bank, 2, 0, 5 * MS)
    timeline = InputTimeline(inputs)
    apply(inputs, (3 * MS, *a[1:]))
    timeline.record(3 * MS)
    apply(inputs, (2 * MS, *b[1:]))
    timeline.record(2 * MS)
    assert timeline.rows_at([2 * MS, 3 * MS]).tolist() == [0, 1]
    u, *_ = timeline.sample_many([3 * MS])
    np.testing.assert_array_equal(u[0], b[1])


def test_a_sample_takes_its_header_stamp_when_that_is_on_the_nodes_clock():
    timeout = 500 * MS
    assert input_time_ns(995 * MS, 1000 * MS, timeout) == 995 * MS
    assert input_time_ns(1000 * MS, 1000 * MS, timeout) == 1000 * MS
    assert input_time_ns(500 * MS, 1000 * MS, timeout) == 500 * MS  # at the timeout: kept
    assert input_time_ns(500 * MS - 1, 1000 * MS, timeout) == 1000 * MS  # older: another clock
    assert input_time_ns(1000 * MS + 1, 1000 * MS, timeout) == 1000 * MS  # in the future
    assert input_time_ns(0, 1000 * MS, timeout) == 1000 * MS  # no stamp (or no header)


def test_a_late_sample_continues_the_motion_from_its_stamp(bank):
    """A kinematics sample stamped 4 ms before the model time it could still be placed at is
    extrapolated from its stamp: the path length at the step is where the motion is then, not
    where it was when measured (which stepped the length back by 4 ms of motion)."""
    inputs = make_inputs(bank)
    _, drive, length, velocity = messages(bank, 1, 0, MS)[0]
    placed, stamp = 104 * MS, 100 * MS
    inputs.on_excitation(MUSCLES, drive, placed)
    inputs.on_kinematics(MUSCLES, length, velocity,
                         input_time_ns(stamp, placed, inputs.limits.timeout_ns))
    _, lp, vp = inputs.sample(placed)
    np.testing.assert_allclose(lp, length + velocity * 4e-3, rtol=1e-12)
    np.testing.assert_array_equal(vp, velocity)


def test_messages_at_one_time_keep_one_row(bank):
    """A clock that stands still (a paused simulation's /clock) with inputs still coming: the
    rows do not grow, and the step at that time takes the last message."""
    inputs = make_inputs(bank)
    timeline = InputTimeline(inputs)
    for drive in np.linspace(0.1, 0.9, 500):
        inputs.on_excitation(MUSCLES, [drive, drive], 5 * MS)
        timeline.record(5 * MS)
    assert timeline.pending == 1
    u, *_ = timeline.sample_many([4 * MS, 5 * MS])
    np.testing.assert_array_equal(u[1], [0.9, 0.9])
    assert timeline.rows_at([4 * MS]).tolist() == [0]
