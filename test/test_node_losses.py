"""muscle_node's loss counter (vm_ros.node.health.SequenceGaps) on sequences of publication
sequence numbers, against the numbers left out of them (no ROS needed; the node with rclpy:
test_node_counters.py)."""

from __future__ import annotations

import numpy as np

from vm_ros.node.health import SequenceGaps


def _count(numbers) -> SequenceGaps:
    gaps = SequenceGaps()
    for seq in numbers:
        gaps.add(int(seq))
    return gaps


def test_one_publisher_counts_exactly_the_numbers_left_out():
    rng = np.random.default_rng(7)
    sent = np.arange(1, 5001)
    kept = np.sort(rng.choice(sent, size=3000, replace=False))
    # what the counter can see: the numbers left out between the first and last taken
    unseen = np.setdiff1d(np.arange(kept[0], kept[-1] + 1), kept).size
    assert _count(kept).lost == unseen > 0


def test_a_restarted_publisher_is_no_loss():
    assert _count([*range(1, 41), *range(1, 21), *range(1, 6)]).lost == 0


def test_two_publishers_interleaved_without_loss_count_nothing():
    a, b = range(1, 301), range(1, 101)  # b joins late and runs slower
    interleaved = [*a[:50], *(x for pair in zip(a[50:150], b, strict=True) for x in pair), *a[150:]]
    assert _count(interleaved).lost == 0


def test_two_publishers_each_losing_messages_count_their_gaps():
    a = [n for n in range(1, 201) if n % 10]  # 20 lost: 10, 20, ..., 200 (200 is never seen)
    b = [n for n in range(1, 101) if n not in (50, 51, 52)]  # 3 lost
    interleaved = [x for pair in zip(a[:len(b)], b, strict=True) for x in pair] + a[len(b):]
    assert _count(interleaved).lost == 19 + 3


def test_no_numbers_from_the_middleware_are_not_counted():
    gaps = SequenceGaps()
    assert gaps.supported is None
    assert [gaps.add(seq) for seq in (None, 0, None)] == [0, 0, 0]
    assert gaps.supported is False and gaps.lost == 0
