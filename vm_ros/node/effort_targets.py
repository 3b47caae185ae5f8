"""Target joint efforts for muscle_node's live coordination (no rclpy here; vm_ros.node.shell
unpacks the messages). Targets are in the robot's convention and joints of the ``joints``
parameter; :meth:`EffortTargets.at` gives them in the model's (tau_model = sign * tau_robot, as
vm_ros.joint_space.JointMap.to_robot maps back).

Two sources; the latest message of either replaces the other:

- a planned profile (``joint_effort_trajectory``, trajectory_msgs/JointTrajectory): joint_names,
  points with time_from_start and effort[], and optionally positions[] (the planned motion:
  every point one per joint name, or none; velocities and accelerations are not used). It
  starts at header.stamp, or on receipt when the stamp is zero (the ROS convention); efforts and
  positions are linear between points and held before the first and after the last point.
  Joints of ``joints`` it does not name are not tracked while it holds. Planned positions give
  the coordinator the horizon's coming poses (:meth:`EffortTargets.model_positions_at`,
  vm_ros.node.live_coordination).
- a stream (``joint_effort_targets``, JointState effort[] by name, or
  ``joint_effort_targets_array``, Float64MultiArray data[] one per joint of ``joints``): each
  named joint's latest target held until the next. Joints never named are not tracked.

Bad messages are dropped whole and reported as Issues (vm_ros.node.health): sizes that do not
match, NaN or inf, a joint named twice, times not increasing or negative, a trajectory without
points. Names that are not joints of ``joints`` are ignored and counted per entry.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vm_ros import topics as tp
from vm_ros.joint_space import JointSpace
from vm_ros.node.health import Issue

PLANNED, STREAM = "planned profile", "stream"


class EffortTargets:
    """The latest target source for the joints of ``space.output`` (module docstring)."""

    def __init__(self, space: JointSpace):
        self.names = space.output_names
        self._index = {name: j for j, name in enumerate(self.names)}
        self._sign = space.map.sign[space.output]
        c = len(self.names)
        self.kind: str | None = None
        self.tracked = np.zeros(c, dtype=bool)
        self._times_ns = np.zeros(1, dtype=np.int64)  # planned: absolute point times
        self._efforts = np.zeros((1, c))              # robot convention, (points, c)
        self._positions: np.ndarray | None = None     # planned positions, robot, NaN: not given
        self._q_sign = space.map.sign[space.output]
        self._q_offset = space.map.offset[space.output]
        self.last_message_ns: int | None = None

    def _select(self, topic: str, names, size: int):
        """(issues, joint index or None when the message is dropped, message index)."""
        if len(names) == 0:
            if size != len(self.names):
                return [Issue("target_wrong_size", f"{topic}: {size} values without names, "
                              f"expected {len(self.names)} (one per joint of joints)")], None, []
            return [], np.arange(size), list(range(size))
        if len(names) != size:
            return [Issue("target_wrong_size", f"{topic}: {len(names)} joint names but {size} "
                          "efforts")], None, []
        issues, joints, entries = [], [], []
        unknown = [str(n) for n in names if n not in self._index]
        if unknown:
            shown = ", ".join(repr(u[:40]) for u in unknown[:3])
            issues.append(Issue("target_unknown_joint", f"{topic}: not joints of the joints "
                                f"parameter: {shown}", count=len(unknown)))
        for entry, name in enumerate(names):
            if name in self._index:
                joints.append(self._index[name])
                entries.append(entry)
        if len(set(joints)) != len(joints):
            repeated = next(j for j in joints if joints.count(j) > 1)
            return issues + [Issue("target_duplicate_name", f"{topic}: {self.names[repeated]!r} "
                                   "named twice")], None, []
        return issues, np.array(joints, dtype=int), entries

    def on_stream(self, topic: str, names, effort, now_ns: int) -> list[Issue]:
        """A stream message (JointState effort[] by name, or an array without names)."""
        effort = np.asarray(effort, dtype=float).ravel()
        issues, joints, entries = self._select(topic, names if names is not None else (),
                                               effort.size)
        if joints is None or joints.size == 0:
            return issues
        values = effort[entries]
        if not np.isfinite(values).all():
            return issues + [Issue("target_non_finite", f"{topic}: effort is not finite")]
        if self.kind != STREAM:
            self.kind, self.tracked = STREAM, np.zeros(len(self.names), dtype=bool)
            self._times_ns = np.zeros(1, dtype=np.int64)
            self._efforts = np.zeros((1, len(self.names)))
            self._positions = None
        self._efforts = self._efforts.copy()
        self._efforts[0, joints] = values
        self.tracked = self.tracked.copy()
        self.tracked[joints] = True
        self.last_message_ns = now_ns
        return issues

    def on_trajectory(self, names: Sequence[str], stamp_ns: int, times_from_start_ns,
                      efforts: Sequence, now_ns: int, positions: Sequence = ()) -> list[Issue]:
        """A planned profile: ``times_from_start_ns`` (k,), ``efforts`` and ``positions`` (k
        sequences each; positions all empty, or none given, when the plan has no motion) of the
        points, ``stamp_ns`` the header stamp (0: start on receipt)."""
        topic = tp.TOPIC_JOINT_EFFORT_TRAJECTORY
        times = np.asarray(times_from_start_ns, dtype=np.int64).ravel()
        if times.size == 0:
            return [Issue("target_wrong_size", f"{topic}: no points")]
        if len(names) == 0:
            return [Issue("target_wrong_size", f"{topic}: no joint_names")]
        issues, joints, entries = self._select(topic, names, len(names))
        if joints is None or joints.size == 0:
            return issues
        sizes = {len(e) for e in efforts}
        if sizes != {len(names)}:
            return issues + [Issue("target_wrong_size", f"{topic}: points with {sorted(sizes)} "
                                   f"efforts for {len(names)} joint names")]
        values = np.array([np.asarray(e, dtype=float) for e in efforts])[:, entries]
        if not np.isfinite(values).all():
            return issues + [Issue("target_non_finite", f"{topic}: effort is not finite")]
        planned = None
        position_sizes = {len(p) for p in positions}
        if position_sizes - {0}:
            if position_sizes != {len(names)} or len(positions) != times.size:
                return issues + [Issue("target_wrong_size", f"{topic}: points with "
                                       f"{sorted(position_sizes)} positions for {len(names)} joint "
                                       "names (give none, or one per name in every point)")]
            planned = np.array([np.asarray(p, dtype=float) for p in positions])[:, entries]
            if not np.isfinite(planned).all():
                return issues + [Issue("target_non_finite", f"{topic}: position is not finite")]
        if times[0] < 0 or np.any(np.diff(times) <= 0):
            return issues + [Issue("target_bad_time", f"{topic}: time_from_start must be >= 0 "
                                   "and increasing")]
        full = np.zeros((times.size, len(self.names)))
        full[:, joints] = values
        tracked = np.zeros(len(self.names), dtype=bool)
        tracked[joints] = True
        start = stamp_ns if stamp_ns > 0 else now_ns
        self.kind, self.tracked = PLANNED, tracked
        self._times_ns, self._efforts = start + times, full
        self._positions = None
        if planned is not None:
            self._positions = np.full((times.size, len(self.names)), np.nan)
            self._positions[:, joints] = planned
        self.last_message_ns = now_ns
        return issues

    @property
    def has_planned_positions(self) -> bool:
        """The planned profile that holds gives positions (of the joints it names)."""
        return self.kind == PLANNED and self._positions is not None

    def model_positions_at(self, times_ns) -> np.ndarray:
        """(k, c) planned coordinate values at ``times_ns`` in the model's convention (q_model =
        sign * q_robot + offset), linear between points and held beyond them; NaN for joints the
        plan does not name, everywhere without planned positions."""
        t = np.asarray(times_ns, dtype=np.int64)
        if not self.has_planned_positions:
            return np.full((len(t), len(self.names)), np.nan)
        return self._q_sign * self._between_points(self._positions, t) + self._q_offset

    def _between_points(self, values, t) -> np.ndarray:
        """(k, c) ``values`` (points, c) at the times ``t``: linear between the planned points'
        times, held beyond them."""
        return np.stack([np.interp(t, self._times_ns, column) for column in values.T], axis=1)

    def robot_at(self, times_ns) -> np.ndarray:
        """(k, c) target efforts (robot convention) at ``times_ns``; 0 where not tracked."""
        t = np.asarray(times_ns, dtype=np.int64)
        if self.kind != PLANNED:
            return np.repeat(self._efforts[:1], len(t), axis=0)
        return self._between_points(self._efforts, t)

    def at(self, times_ns) -> np.ndarray:
        """(k, c) target generalized forces at ``times_ns`` in the model's convention."""
        return self.robot_at(times_ns) * self._sign


__all__ = ["PLANNED", "STREAM", "EffortTargets"]
