"""muscle_node's live coordination (``coordination.enabled``), between the node's inputs and the
model-side coordinator (vm_ros.coordination.receding); no rclpy here.

Each publish period, before the model steps it:

- the targets over the horizon (vm_ros.node.effort_targets) in the model's convention, for the
  joints of ``joints``;
- the horizon's motion. With a planned profile that gives positions: the geometry evaluated at
  the coming poses (``planned_poses``: the plan's positions, moved by a constant so that they
  start from the latest joint sample's; coordinates the plan does not give moved on by their
  sampled velocity; where the plan's numbers overflow, the sampled prediction), every
  PLAN_POSE_STEP_S of the horizon, the path lengths, velocities and moment arms linear between
  those poses. Otherwise:
  each joint-driven muscle's latest path length moved on by its velocity (as NodeInputs holds
  them; the node's extrapolation_max_s cap is not applied in the prediction), with the moment
  arms of the latest joint sample held. The range clamp of NodeInputs applies to both;
- RecedingHorizon.solve from the bank's state gives the joint-driven muscles' drives for the
  period. Before any target arrives their drive is 0.

After each publish: the reserve of each tracked joint, target - joint effort (robot convention,
0 where untracked), and a history for the tracking lag and error of /diagnostics
(vm_ros.coordination.receding.tracking_lag over ``coordination.lag_window_s``).
"""

from __future__ import annotations

import time
from collections import deque

import numpy as np

from vm_ros.blas_threads import limit_blas_threads
from vm_ros.coordination import receding  # a room below the node (docs/architecture.md)
from vm_ros.joint_space import JointEfforts, JointSpace
from vm_ros.node.effort_targets import EffortTargets
from vm_ros.node.health import DurationWindow, Issue


def horizon_settings(config) -> receding.HorizonSettings:
    """The coordinator's constants from the node's parameters (NodeConfig)."""
    return receding.HorizonSettings(horizon_s=config.coordination_horizon_s,
                           blocks=config.coordination_blocks, cost=config.coordination_cost,
                           eval_step_s=config.coordination_sample_period_s,
                           effort_weight=config.coordination_effort_weight or None,
                           smoothness=config.coordination_smoothness,
                           damping=config.coordination_damping,
                           probe_drive=config.coordination_probe_drive)


PLAN_DIFFERENCE_NS = 1_000_000  # half-step of the planned positions' central difference (1 ms)
# spacing of the planned poses the geometry is evaluated at over the horizon; the path lengths,
# velocities and moment arms are linear between them (on the walk over ROS the worst coordinate
# within 0.13 points of peak of its value with poses at every probe step, 5 ms; on myolegs 0.55
# against 0.95 ms per period: docs/node.md section 13)
PLAN_POSE_STEP_S = 0.02


def plan_offsets(targets: EffortTargets, space: JointSpace, sample) -> np.ndarray:
    """(c,) for the joints of ``joints``: the joint ``sample``'s q less the planned position at
    the sample's time (model convention), the constant planned_poses moves the plan by; NaN
    where the plan gives no position."""
    planned = targets.model_positions_at([sample.time_ns])[0]
    with np.errstate(over="ignore", invalid="ignore"):
        return sample.q[space.output] - planned


def planned_poses(targets: EffortTargets, space: JointSpace, times_ns, sample,
                  offset=None) -> tuple[np.ndarray, np.ndarray]:
    """(k, n_coordinates) q and q' (model convention) at ``times_ns`` from ``targets``' planned
    positions and the joint ``sample`` (JointSample; module docstring): a coordinate of the plan
    follows it shifted by ``offset`` (plan_offsets, computed when None), its velocity the plan's
    central difference over 2 PLAN_DIFFERENCE_NS; the others the sample's q moved on by its q'."""
    t = np.asarray(times_ns, dtype=np.int64)
    ahead_s = (t - sample.time_ns)[:, None] * 1e-9
    q = sample.q[None, :] + sample.qdot[None, :] * ahead_s
    qdot = np.repeat(np.asarray(sample.qdot, dtype=float)[None, :], len(t), axis=0)
    planned = targets.model_positions_at(t)
    offset = plan_offsets(targets, space, sample) if offset is None else offset
    given = np.isfinite(planned[0])
    columns = space.output[given]
    sampled_q, sampled_qdot = q.copy(), qdot.copy()
    with np.errstate(over="ignore", invalid="ignore"):
        q[:, columns] = planned[:, given] + offset[given]
        h = PLAN_DIFFERENCE_NS
        slope = targets.model_positions_at(t + h) - targets.model_positions_at(t - h)
        qdot[:, columns] = slope[:, given] / (2 * h * 1e-9)
    # positions near the float range overflow in these differences: those entries keep the
    # sampled prediction (the message passed the finite check, so it is not refused)
    finite = np.isfinite(q) & np.isfinite(qdot)
    return np.where(finite, q, sampled_q), np.where(finite, qdot, sampled_qdot)


def plan_far_issue(offset, names, box_width, limit_of_box: float) -> Issue | None:
    """plan_far_from_joints naming the joints (``names``) whose ``offset`` (plan_offsets)
    exceeds ``limit_of_box`` of their coordinate's geometry box width ``box_width`` (None when
    none does)."""
    with np.errstate(invalid="ignore"):
        far = np.abs(offset) > limit_of_box * box_width  # NaN (not planned) is never far
    if not far.any():
        return None
    details = ", ".join(f"{names[j]} {offset[j]:+.4g} ({abs(offset[j]) / box_width[j]:.2f} of "
                        "its box)" for j in np.flatnonzero(far))
    return Issue("plan_far_from_joints", "planned positions far from joint_states (sample - "
                 f"plan, model convention): {details}")


def motion_at_poses(geometry, rows, output, q, qdot, poses_s, offsets_s) -> tuple:
    """The geometry at the poses ``q``, ``qdot`` (p, n_coordinates) taken at ``poses_s`` (p,),
    linear between them (receding.at_times) at ``offsets_s`` (k + 1,): path length and velocity
    (k, m) of the muscles ``rows`` at offsets_s[:-1] (the probe steps' starts), moment arms
    (k, m, c) on the coordinates ``output`` at offsets_s[1:] (their ends)."""
    out = geometry.evaluate_many(q, qdot)
    length = receding.at_times(out.length_m[:, rows], poses_s, offsets_s[:-1])
    velocity = receding.at_times(out.velocity_m_per_s[:, rows], poses_s, offsets_s[:-1])
    arms = receding.at_times(out.moment_arm[:, rows][:, :, output], poses_s, offsets_s[1:])
    return length, velocity, arms


class LiveCoordination:
    """Targets, the coordinator and the tracking history of one muscle_node (module docstring)."""

    def __init__(self, bank, space: JointSpace, inputs, config, period_s: float):
        self.space, self.inputs = space, inputs
        limit_blas_threads(1)  # the node is one thread (vm_ros.blas_threads)
        self.index = space.driven_index
        self.names = [bank.names[i] for i in self.index]
        self.targets = EffortTargets(space)
        self.coordinator = receding.RecedingHorizon(bank, self.index, period_s,
                                                    horizon_settings(config))
        inputs.exempt_drive(self.index)
        keep = max(int(round(config.coordination_lag_window_s / period_s)), 2)
        self.history: deque = deque(maxlen=keep)  # (stamp ns, target, effort, tracked) robot
        self.max_lag_s = config.coordination_horizon_s
        self.plan_offset_max = config.coordination_plan_offset_max
        self.box_width = (space.geometry.upper - space.geometry.lower)[space.output]
        self.solve_times = DurationWindow()
        self.drive = np.zeros(len(self.index))  # of the current period

    def _horizon_paths(self, t0_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """(k, m) path length (m) and velocity (m/s) of the joint-driven muscles at the starts of
        the coordinator's steps."""
        inputs, i = self.inputs, self.index
        t = t0_ns + np.round(self.coordinator.start_offsets_s * 1e9).astype(np.int64)
        since_s = np.maximum(t[:, None] - inputs.length_time_ns[i], 0) * 1e-9
        length = inputs.length_m[i] + inputs.velocity_m_per_s[i] * since_s
        return self._within_range(length, np.broadcast_to(inputs.velocity_m_per_s[i],
                                                          length.shape))

    def _planned_motion(self, t0_ns: int, sample, plan_offset) -> tuple:
        """(path length, velocity) (k, m) at the probe steps' starts and moment arms (k, m, c)
        at their ends, from the geometry at the planned poses (the plan shifted by
        ``plan_offset``: plan_offsets)."""
        c = self.coordinator
        offsets = np.append(c.start_offsets_s, c.end_offsets_s[-1])
        poses = np.linspace(0.0, offsets[-1], int(np.ceil(offsets[-1] / PLAN_POSE_STEP_S)) + 1)
        q, qdot = planned_poses(self.targets, self.space,
                                t0_ns + np.round(poses * 1e9).astype(np.int64), sample, plan_offset)
        length, velocity, arms = motion_at_poses(self.space.geometry, self.space.rows,
                                                 self.space.output, q, qdot, poses, offsets)
        return (*self._within_range(length, velocity), arms)

    def _within_range(self, length, velocity) -> tuple[np.ndarray, np.ndarray]:
        """Path lengths (k, m) clamped to NodeInputs' range of the joint-driven muscles, their
        velocities 0 where clamped."""
        lo, hi = (bound[self.index] for bound in self.inputs.path_bounds())
        clamped = np.minimum(np.maximum(length, lo), hi)
        return clamped, np.where(clamped == length, velocity, 0.0)

    def solve(self, state, t0_ns: int, sample) -> list[Issue]:
        """Set ``drive``, the joint-driven muscles' drives for the period starting at ``t0_ns``,
        from the bank's ``state`` and the joint ``sample`` (JointInputs.sample) held; the issues
        met (plan_far_from_joints)."""
        if self.targets.kind is None or sample is None:
            self.drive = np.zeros(len(self.index))
            return []
        started = time.perf_counter_ns()
        c = self.coordinator
        ends = t0_ns + np.round(c.end_offsets_s * 1e9).astype(np.int64)
        issues = []
        if self.targets.has_planned_positions:
            offset = plan_offsets(self.targets, self.space, sample)
            far = plan_far_issue(offset, self.space.output_names, self.box_width,
                                 self.plan_offset_max)
            issues += [far] if far is not None else []
            length, velocity, arms = self._planned_motion(t0_ns, sample, offset)
        else:
            length, velocity = self._horizon_paths(t0_ns)
            arms = np.broadcast_to(sample.moment_arm[:, self.space.output],
                                   (c.steps, len(self.index), len(self.space.output)))
        plan = c.solve(state, length, velocity, arms, self.targets.at(ends),
                       self.targets.tracked)
        self.solve_times.add(time.perf_counter_ns() - started)
        self.drive = plan.drive
        return issues

    def reserves(self, stamp_ns: int, efforts: JointEfforts) -> np.ndarray:
        """Target - effort (robot convention) per joint of ``joints`` at a published step, 0
        where untracked; kept for the tracking diagnostics."""
        tracked = self.targets.tracked
        target = self.targets.robot_at([stamp_ns])[0]
        reserve = np.where(tracked, target - efforts.effort, 0.0)
        if tracked.any():
            self.history.append((stamp_ns, target, np.asarray(efforts.effort, float), tracked))
        return reserve

    def diagnostics(self, now_ns: int) -> list[tuple[str, object]]:
        """/diagnostics entries (key with unit, value)."""
        _, solve_p99, solve_max = self.solve_times.percentiles_ms()
        age = (None if self.targets.last_message_ns is None
               else max(now_ns - self.targets.last_message_ns, 0) * 1e-9)
        values = [("coordination targets", self.targets.kind or "none yet"),
                  ("coordination target age (s)", age),
                  ("coordination solve time p99 (ms)", solve_p99),
                  ("coordination solve time max (ms)", solve_max),
                  ("coordination QP not solved (periods)", self.coordinator.qp.unsolved)]
        rows = [h for h in self.history if np.array_equal(h[3], self.targets.tracked)]
        if len(rows) >= 2:
            times = np.array([h[0] for h in rows]) * 1e-9
            columns = self.targets.tracked
            target = np.array([h[1][columns] for h in rows])
            effort = np.array([h[2][columns] for h in rows])
            lag, lag_rms = receding.tracking_lag(times, target, effort, self.max_lag_s)
            values += [("tracking error RMS (N m)", float(np.sqrt(np.mean((effort - target)
                                                                          ** 2)))),
                       ("tracking lag (s)", lag),
                       ("tracking error RMS at that lag (N m)", lag_rms),
                       ("reserve peak (N m)", float(np.abs(target - effort).max()))]
        self.solve_times.clear()
        return values


__all__ = ["LiveCoordination", "horizon_settings", "motion_at_poses", "plan_far_issue",
           "plan_offsets", "planned_poses"]
