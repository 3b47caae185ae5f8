"""The inputs muscle_node holds after each message since its model's last step, by the model time
from which the steps use it (no rclpy here).

muscle_node runs a publish period of model steps at each tick, after the inputs of that period
have arrived. Each message is placed at its time (vm_ros.node.inputs.input_time_ns: its header
stamp when that is on the node's clock, else its arrival), but never before the model time
reached when it arrived (those steps have run) nor before the message before it: the steps that
start before that place use what was held before it, the ones from there on use it. So a
period's samples are applied one after the other at their own times, as a replay of the log
applies them (vm_ros.node.replay), not all at the model time the node had reached when they
arrived.

The node applies every message to its NodeInputs (and JointInputs) when it arrives, as before
(staleness, ages and diagnostics are of the latest inputs), and then :meth:`InputTimeline.record`
keeps a copy of what is held with its place (:meth:`InputTimeline.place`);
:meth:`InputTimeline.sample_many` gives each
step the row of the last message at or before its start (NodeInputs.sample_held: the same bits
as a replay's NodeInputs.sample step by step); :meth:`InputTimeline.consume` drops the rows that
no later step can use.

    timeline = InputTimeline(inputs, joint_inputs)    # at the model start: timeline.restart()
    placed_ns = timeline.place(time_ns, model_time_ns)  # where a message goes (it is logged there)
    timeline.record(placed_ns)                        # after the message was applied
    u, lp, vp, rows = timeline.sample_many(times_ns)  # the tick's steps
    timeline.joint_sample(rows[-1])                   # the joint sample the last step used
    timeline.consume(times_ns[-1])                    # after the steps ran
"""

from __future__ import annotations

import numpy as np

from vm_ros.node.inputs import HeldInputs, NodeInputs


class InputTimeline:
    """What ``inputs`` (and ``joint_inputs``, or None) held before the messages not yet consumed
    (row 0) and after each of them (rows 1 ...), with the messages' model times."""

    def __init__(self, inputs: NodeInputs, joint_inputs=None):
        self.inputs, self.joint_inputs = inputs, joint_inputs
        self.restart()

    def _held(self) -> HeldInputs:
        # copies: NodeInputs stores into its arrays in place
        return HeldInputs(*(array.copy() for array in self.inputs.held()))

    def _joints(self):
        return self.joint_inputs.sample if self.joint_inputs is not None else None

    def restart(self) -> None:
        """Forget the rows: what is held now is row 0 (the model start, a clock jump)."""
        self._times_ns: list[int] = []
        self._rows = [self._held()]
        self._joint_rows = [self._joints()]

    @property
    def pending(self) -> int:
        """Messages recorded and not yet consumed."""
        return len(self._times_ns)

    def place(self, time_ns: int, model_time_ns: int) -> int:
        """Where a message of time ``time_ns`` goes: there, but not before the model time reached
        (its steps have run) nor before the last message recorded (the rows stay in order)."""
        last = self._times_ns[-1] if self._times_ns else model_time_ns
        return max(int(time_ns), int(model_time_ns), last)

    def record(self, time_ns: int) -> None:
        """After a message was applied: what is held now, from ``time_ns`` (not before the last
        message's time: the rows stay in order)."""
        last = self._times_ns[-1] if self._times_ns else time_ns
        time_ns = max(int(time_ns), last)
        if self._times_ns and time_ns == last:  # no step can take the row it replaces: the
            # rows stay as many as the distinct times (a clock that stands still keeps one)
            self._rows[-1], self._joint_rows[-1] = self._held(), self._joints()
            return
        self._times_ns.append(time_ns)
        self._rows.append(self._held())
        self._joint_rows.append(self._joints())

    def rows_at(self, times_ns) -> np.ndarray:
        """(k,) the row each step starting at ``times_ns`` uses: the last message at or before
        it (0: none, what was held before the first)."""
        return np.searchsorted(np.asarray(self._times_ns, dtype=np.int64),
                               np.asarray(times_ns, dtype=np.int64), side="right")

    def sample_many(self, times_ns):
        """(drive, path length, path velocity), (k, n) each, for the steps starting at
        ``times_ns`` (k,), and the row each used (rows_at)."""
        rows = self.rows_at(times_ns)
        if not self._times_ns:  # no message since the last step: what is held now
            return (*self.inputs.sample_many(times_ns), rows)
        stacked = (np.concatenate(column) for column in zip(*self._rows, strict=True))
        held = HeldInputs(*(column[rows] for column in stacked))
        return (*self.inputs.sample_held(times_ns, held), rows)

    def joint_sample(self, row: int):
        """The joint sample held at ``row`` (None without a joint space or before the first)."""
        return self._joint_rows[int(row)]

    def consume(self, through_ns: int) -> None:
        """Drop the messages at or before ``through_ns`` (the last step run): the row after the
        last of them becomes row 0."""
        used = int(self.rows_at([through_ns])[0])
        if used:
            del self._times_ns[:used]
            del self._rows[:used]
            del self._joint_rows[:used]


__all__ = ["InputTimeline"]
