"""Fixed model steps by elapsed ROS time, with bounded catch-up (no rclpy here).

rclpy timers drop ticks after a stall and do not catch up, and a simulated clock may advance in
jumps of several steps. So the node asks, at every tick, how many fixed steps of ``step_ns`` are
due since the time base (``anchor``): model time is ``anchor + steps * step_ns``, in integer
nanoseconds, so it never drifts.

- time advances by k steps: k steps due (at most ``max_catch_up_steps``);
- more than ``max_catch_up_steps`` due: that many run; the rest of the elapsed time is skipped by
  moving the anchor forward (counted in ``skipped_ns`` and ``stalls``); with ``end_on_multiple_of``
  k, by whole multiples of k steps (at most k - 1 steps more than the rest, never more than is
  due), so that the multiples (muscle_node's publish steps) keep their phase against the clock;
- time goes backwards: nothing due; the anchor is re-set at the new time, so model time restarts
  there (counted in ``backward_jumps``);
- ``hold(now)`` (pause policy): nothing due; the anchor follows ``now`` so that no catch-up
  follows (counted in ``paused_ns``); with a multiple k, in whole multiples of k steps (the rest,
  fewer than k steps, stays due), for the same reason as after a stall.
"""

from __future__ import annotations


class StepScheduler:
    """Which model steps are due at a given clock time (all times integer ns)."""

    def __init__(self, step_ns: int, max_catch_up_steps: int, steps_per_tick: int = 1):
        if step_ns <= 0 or max_catch_up_steps < 1 or steps_per_tick < 1:
            raise ValueError("step_ns, max_catch_up_steps and steps_per_tick must be positive")
        self.steps_per_tick = int(steps_per_tick)  # steps a tick runs on time (the timer period)
        self.step_ns = int(step_ns)
        self.max_catch_up_steps = int(max_catch_up_steps)
        self.anchor_ns: int | None = None
        self.steps = 0  # steps run since the anchor
        self.total_steps = 0  # steps run since start
        self._last_now_ns: int | None = None
        self.skipped_ns = 0
        self.paused_ns = 0
        self.stalls = 0
        self.backward_jumps = 0
        self.catch_up_ticks = 0  # ticks that ran more than steps_per_tick steps

    @property
    def started(self) -> bool:
        return self.anchor_ns is not None

    @property
    def model_time_ns(self) -> int:
        """ROS time of the model state (ns)."""
        if self.anchor_ns is None:
            raise RuntimeError("scheduler not started")
        return self.anchor_ns + self.steps * self.step_ns

    def start(self, now_ns: int) -> None:
        self._reanchor(now_ns)
        self._last_now_ns = now_ns

    def _reanchor(self, now_ns: int) -> None:
        self.anchor_ns, self.steps = int(now_ns), 0

    def went_backwards(self, now_ns: int) -> bool:
        """True (and re-anchored at ``now_ns``) when the clock is earlier than at the last call."""
        last, self._last_now_ns = self._last_now_ns, now_ns
        if last is None or now_ns >= last:
            return False
        self.backward_jumps += 1
        if self.started:
            self._reanchor(now_ns)
        return True

    def due(self, now_ns: int, end_on_multiple_of: int = 0) -> int:
        """Steps to run now; call :meth:`advance` after each. Call went_backwards() first.

        ``end_on_multiple_of`` (k > 0): when more than the steps up to the next multiple of k
        (counted in total_steps) are due, the ones past the last multiple reached wait for the
        next call, so that a late tick's steps end on a publish step and run in one call
        (muscle_node on the system clock, docs/performance.md); time skipped after a stall is
        then skipped in whole multiples of k steps: any other count moved the publish steps
        against the node's timer, whose ticks then ended at the publish step before them and
        published up to a period late for the rest of the run."""
        behind = (now_ns - self.model_time_ns) // self.step_ns
        if behind <= 0:
            return 0
        if behind > self.max_catch_up_steps:
            skipped = behind - self.max_catch_up_steps
            whole = skipped + (-skipped % end_on_multiple_of if end_on_multiple_of > 0 else 0)
            if whole <= behind:  # else (a catch-up shorter than a period) the rest exactly
                skipped = whole
            self.anchor_ns += skipped * self.step_ns
            self.skipped_ns += skipped * self.step_ns
            self.stalls += 1
            behind -= skipped
        if behind > self.steps_per_tick:
            self.catch_up_ticks += 1
        if end_on_multiple_of > 0:
            to_multiple = end_on_multiple_of - self.total_steps % end_on_multiple_of
            if behind > to_multiple:
                behind -= (behind - to_multiple) % end_on_multiple_of
        return int(behind)

    def advance(self) -> None:
        self.steps += 1
        self.total_steps += 1

    def hold(self, now_ns: int, whole_multiple_of: int = 0) -> None:
        """Pause: no steps due at ``now_ns``; the elapsed time is counted as paused. With
        ``whole_multiple_of`` k > 0 (the ``end_on_multiple_of`` of :meth:`due`) the time held is
        whole multiples of k steps and the rest (fewer than k steps) stays due, so that the
        multiples (muscle_node's publish steps) keep their phase against the clock: holding
        every step behind moved them by a late last pause tick's lateness, and every tick after
        the pause then ended at the publish step before its own, up to a period late."""
        behind = (now_ns - self.model_time_ns) // self.step_ns
        if whole_multiple_of > 0:
            behind -= behind % whole_multiple_of
        if behind > 0:
            self.anchor_ns += behind * self.step_ns
            self.paused_ns += behind * self.step_ns


__all__ = ["StepScheduler"]
