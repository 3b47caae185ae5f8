"""A planned profile's positions (JointTrajectory points' positions[]) for muscle_node's live
coordination, without ROS: parsed in the robot's convention and given back in the model's
(q_model = sign * q_robot + offset of the joint map), bad positions dropping the whole message
with a counted issue, and the horizon's poses built from them (vm_ros.node.live_coordination.
planned_poses). Expected values are written out from the plan's own numbers."""

from __future__ import annotations

import numpy as np
import pytest
from test_joint_space import small_geometry

from vm_ros.joint_space import JointMap, JointSpace
from vm_ros.node.effort_targets import PLANNED, EffortTargets
from vm_ros.node.joint_inputs import JointSample
from vm_ros.node.live_coordination import plan_far_issue, plan_offsets, planned_poses

S = 1_000_000_000
# the robot's "knee" is the model's knee_angle with the opposite sign and 0.1 rad apart
JOINT_MAP = "knee: {coordinate: knee_angle, sign: -1, offset: 0.1}\n"
KNEE_ROBOT = (-0.5, -1.5)   # planned knee, robot convention, at 0 and 1 s after the start
START_NS = 10 * S


@pytest.fixture
def space():
    geometry = small_geometry()
    return JointSpace(geometry, JointMap.build(JOINT_MAP, geometry, "test"),
                      ["vasti", "rectus_femoris"], ["knee", "hip_flexion"], "test")


def planned(space, positions=((KNEE_ROBOT[0],), (KNEE_ROBOT[1],))):
    targets = EffortTargets(space)
    issues = targets.on_trajectory(["knee"], START_NS, [0, S], [[-10.0], [-20.0]], START_NS,
                                   positions)
    return targets, issues


def test_planned_positions_come_back_in_the_model_convention(space):
    targets, issues = planned(space)
    assert issues == [] and targets.kind == PLANNED and targets.has_planned_positions
    q = targets.model_positions_at([START_NS - S, START_NS + S // 4, START_NS + 2 * S])
    knee = [-KNEE_ROBOT[0] + 0.1, 0.75 + 0.1, -KNEE_ROBOT[1] + 0.1]   # held, linear, held
    np.testing.assert_allclose(q[:, 0], knee, rtol=0, atol=1e-12)
    assert np.isnan(q[:, 1]).all()          # hip_flexion: a joint of `joints` the plan omits


@pytest.mark.parametrize(("positions", "kind"), [
    (((1.0,), (1.0, 2.0)), "target_wrong_size"),     # one point with two for one name
    (((1.0,), ()), "target_wrong_size"),             # positions in some points only
    (((1.0,), (float("nan"),)), "target_non_finite"),
])
def test_bad_positions_drop_the_message_with_a_counted_issue(space, positions, kind):
    targets, issues = planned(space, positions)
    assert [i.kind for i in issues] == [kind]
    assert targets.kind is None and not targets.has_planned_positions


def test_a_profile_without_positions_keeps_the_sampled_prediction(space):
    targets, issues = planned(space, ((), ()))
    assert issues == [] and targets.kind == PLANNED and not targets.has_planned_positions
    assert np.isnan(targets.model_positions_at([START_NS])).all()


def test_horizon_poses_follow_the_plan_from_the_sampled_pose(space):
    """The plan's knee runs 0.6 -> 1.6 rad (model) over 1 s, slope 1 rad/s; the sample, 0.25 s
    in, finds the knee 0.05 rad above the plan (0.85 + 0.05) and the hip at 0.3 rad moving at
    -0.4 rad/s. The knee's poses are the plan shifted by 0.05 with its slope; the hip and the
    ankle, which the plan does not give, move on from the sample by their velocities."""
    targets, _ = planned(space)
    t_sample = START_NS + S // 4
    q_sample = np.array([0.3, 0.9, -0.2])    # hip_flexion, knee_angle, ankle_angle (model)
    qdot_sample = np.array([-0.4, 2.0, 0.1])
    sample = JointSample(t_sample, q_sample, qdot_sample, np.zeros((2, 3)))
    ahead_s = np.array([0.0, 0.05, 0.1, 0.15])
    q, qdot = planned_poses(targets, space, t_sample + np.round(ahead_s * S).astype(np.int64),
                            sample)
    np.testing.assert_allclose(q[:, 1], 0.85 + ahead_s + 0.05, rtol=0, atol=1e-9)
    np.testing.assert_allclose(qdot[:, 1], 1.0, rtol=0, atol=1e-6)
    np.testing.assert_allclose(q[:, 0], 0.3 - 0.4 * ahead_s, rtol=0, atol=1e-12)
    np.testing.assert_allclose(q[:, 2], -0.2 + 0.1 * ahead_s, rtol=0, atol=1e-12)
    np.testing.assert_allclose(qdot[:, [0, 2]], np.tile([-0.4, 0.1], (4, 1)), rtol=0, atol=0)


def test_positions_near_the_float_range_keep_the_sampled_prediction(space):
    """Finite positions whose differences overflow (the plan holds +1.7e308 to 1 s, then goes to
    -1.7e308 at 1.05 s) are accepted, as finite values are; the sample at 0.95 s lies where the
    plan is finite, its horizon reaches where it overflows, and the poses stay finite: where the
    plan overflows the knee falls back to the sample moved on by its velocity (where it does
    not, the shift to the sampled pose rounds at this size: only finiteness is asked)."""
    targets = EffortTargets(space)
    issues = targets.on_trajectory(["knee"], START_NS, [0, S, S + S // 20],
                                   [[-10.0], [-20.0], [-20.0]], START_NS,
                                   [[1.7e308], [1.7e308], [-1.7e308]])
    assert issues == [] and targets.has_planned_positions
    sample = JointSample(START_NS + S - S // 20, np.array([0.3, 0.9, -0.2]),
                         np.array([0.0, 2.0, 0.0]), np.zeros((2, 3)))
    ahead_s = np.array([0.0, 0.03, 0.08])
    q, qdot = planned_poses(targets, space, sample.time_ns + np.round(ahead_s * S).astype(
        np.int64), sample)
    assert np.isfinite(q).all() and np.isfinite(qdot).all()
    assert q[2, 1] == pytest.approx(0.9 + 2.0 * 0.08, abs=1e-12) and qdot[2, 1] == 2.0


def test_a_plan_far_from_the_sampled_pose_is_named_with_its_offset(space):
    """The plan's knee is 0.85 rad (model) at 0.25 s. A sample there at 0.9 rad is 0.05 rad
    above it: 0.025 of the knee's 2 rad box, within 0.1 of it; at 1.3 rad it is 0.45 rad above,
    0.225 of the box: named, with its offset. The hip, which the plan omits, is never far."""
    targets, _ = planned(space)
    width = np.array([2.0, 2.0])   # knee_angle 0-2 rad, hip_flexion -0.5-1.5 rad (small_geometry)
    for knee, far in ((0.9, False), (1.3, True)):
        sample = JointSample(START_NS + S // 4, np.array([0.3, knee, -0.2]), np.zeros(3),
                             np.zeros((2, 3)))
        offset = plan_offsets(targets, space, sample)
        np.testing.assert_allclose(offset[0], knee - 0.85, rtol=0, atol=1e-12)
        assert np.isnan(offset[1])
        issue = plan_far_issue(offset, space.output_names, width, 0.1)
        assert (issue is not None) == far
    assert issue.kind == "plan_far_from_joints" and "knee +0.45 (0.23 of its box)" in issue.text
