"""muscle_node's live coordination over ROS: a planned torque profile (JointTrajectory efforts) in,
the muscles' joint_efforts out within 5 % RMS of it; muscle_drive and joint_reserves; stream
targets with the tracking lag and error in /diagnostics; every bad target message counted. The
knee of test_joint_space's small geometry, extended by vasti and rectus femoris. In-process rclpy
(test/conftest.py); simulated time where the test paces the model, so that the result does not
depend on the machine's load."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest
from conftest import set_clock, stamp_ns
from test_joint_space import small_geometry

from vm_ros import telemetry as tm
from vm_ros.geometry import write_geometry
from vm_ros.node.health import ISSUE_KINDS

pytestmark = pytest.mark.ros

MUSCLES = ["vasti", "rectus_femoris"]
JOINT_NAMES = ["hip_flexion", "knee_angle", "ankle_angle"]
MS = 1_000_000
T0 = 1_000 * MS
PERIOD_NS = 10 * MS


def knee_pose(t_s: float) -> tuple[list, list]:
    """Positions and velocities of JOINT_NAMES: the knee swings 1 +- 0.3 rad at 0.5 Hz."""
    w = 2 * math.pi * 0.5
    return [0.2, 1.0 + 0.3 * math.sin(w * t_s), 0.0], [0.0, 0.3 * w * math.cos(w * t_s), 0.0]


def knee_target(t_s):
    """An extension moment (negative knee flexion) of 30 +- 20 N m at 0.5 Hz."""
    return -(30.0 + 20.0 * np.sin(2 * np.pi * 0.5 * np.asarray(t_s)))


class CoordinationProbe:
    """The conftest probe plus joint_states, the target topics out, and the coordination
    outputs in."""

    def __init__(self, ros):
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray
        from trajectory_msgs.msg import JointTrajectory

        self.base = ros.probe()
        node = self.base.node
        keep = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                          reliability=ReliabilityPolicy.RELIABLE)
        self.efforts, self.drives, self.reserves = [], [], []
        for topic, store in ((tm.TOPIC_JOINT_EFFORTS, self.efforts),
                             (tm.TOPIC_MUSCLE_DRIVE, self.drives),
                             (tm.TOPIC_JOINT_RESERVES, self.reserves)):
            node.create_subscription(JointState, topic, store.append, keep)
        self.joint_states = node.create_publisher(JointState, tm.TOPIC_JOINT_STATES, keep)
        self.trajectory = node.create_publisher(JointTrajectory,
                                                tm.TOPIC_JOINT_EFFORT_TRAJECTORY, keep)
        self.targets = node.create_publisher(JointState, tm.TOPIC_JOINT_EFFORT_TARGETS, keep)
        self.targets_array = node.create_publisher(Float64MultiArray,
                                                   tm.TOPIC_JOINT_EFFORT_TARGETS_ARRAY, keep)

    def publishers(self):
        return (self.joint_states, self.trajectory, self.targets, self.targets_array)

    def send_joints(self, t_s: float):
        self.joint_states.publish(self.base.joint_state(JOINT_NAMES, *knee_pose(t_s)))

    def send_trajectory(self, names, times_s, efforts, stamp_ns: int = 0, positions=None):
        """A JointTrajectory of ``efforts`` (points, joints) and, when given, ``positions``
        (points, joints) at ``times_s`` from ``stamp_ns``."""
        from builtin_interfaces.msg import Duration, Time
        from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

        msg = JointTrajectory()
        msg.header.stamp = Time(sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
        msg.joint_names = list(names)
        planned = [()] * len(times_s) if positions is None else positions
        for t, effort, position in zip(times_s, efforts, planned, strict=True):
            ns = int(round(t * 1e9))
            msg.points.append(JointTrajectoryPoint(
                effort=[float(e) for e in effort], positions=[float(q) for q in position],
                time_from_start=Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)))
        self.trajectory.publish(msg)


@pytest.fixture
def geometry_file(tmp_path):
    return str(write_geometry(small_geometry(), tmp_path / "geometry.yaml"))


def coordinating_node(ros, geometry_file, **params):
    params = {"muscles": MUSCLES, "geometry": geometry_file, "joints": ["knee_angle"],
              "coordination__enabled": True, **params}
    node = ros.muscle_node(**params)
    probe = CoordinationProbe(ros)
    assert ros.spin_until(lambda: all(p.get_subscription_count() > 0 for p in probe.publishers())
                          and all(node._publishers_by_topic[t].get_subscription_count() > 0
                                  for t in (tm.TOPIC_JOINT_EFFORTS, tm.TOPIC_MUSCLE_DRIVE,
                                            tm.TOPIC_JOINT_RESERVES)), timeout_s=10)
    return node, probe


def test_a_planned_profile_replayed_gives_its_joint_efforts(ros, geometry_file):
    """Simulated time, 100 Hz periods for 3 s: the knee moves as joint_states say, the planned
    profile (points every 20 ms from T0) asks for an extension moment of 30 +- 20 N m. After the
    first second (the start from rest), joint_efforts are within 5 % RMS of the target's peak
    (the issue's bound for the walk replayed over ROS); joint_reserves are target - effort,
    muscle_drive carries every muscle's drive in [0, 1]."""
    node, probe = coordinating_node(ros, geometry_file, use_sim_time=True,
                                    stale_input_policy="hold", input_timeout_s=1000.0)
    set_clock(ros, probe.base, node, T0)
    times = np.arange(0.0, 4.0, 0.02)
    probe.send_trajectory(["knee_angle"], times, knee_target(times)[:, None], stamp_ns=T0)
    assert ros.spin_until(lambda: node.coordination.targets.kind == "planned profile")

    def send_pose(t_ns):
        before = node.joint_inputs.sample
        probe.send_joints((t_ns - T0) * 1e-9)
        assert ros.spin_until(lambda: node.joint_inputs.sample is not before, timeout_s=10)

    send_pose(T0)
    periods = 300
    for k in range(1, periods + 1):
        set_clock(ros, probe.base, node, T0 + k * PERIOD_NS)
        send_pose(T0 + k * PERIOD_NS)
    assert ros.spin_until(lambda: len(probe.efforts) >= periods
                          and len(probe.reserves) == len(probe.efforts), timeout_s=20)
    start_ns = node.scheduler.anchor_ns
    assert start_ns <= T0 + 2 * PERIOD_NS
    stamps = np.array([stamp_ns(m) for m in probe.efforts])
    effort = np.array([m.effort[0] for m in probe.efforts])
    target = np.interp(stamps, T0 + np.round(times * 1e9), knee_target(times))  # as planned
    late = stamps >= start_ns + 1_000 * MS
    assert late.sum() >= 150
    rms = np.sqrt(np.mean((effort[late] - target[late]) ** 2))
    print(f"planned profile over ROS: RMS error {rms:.3f} N m = "
          f"{100 * rms / np.abs(target).max():.2f} % of the target's peak "
          f"({late.sum()} published steps after the first second)")
    assert rms < 0.05 * np.abs(target).max()
    by_stamp = {stamp_ns(m): m for m in probe.reserves}
    for msg, tau, want in zip([m for m, keep in zip(probe.efforts, late, strict=True) if keep],
                              effort[late], target[late], strict=True):
        reserve = by_stamp[stamp_ns(msg)]
        assert list(reserve.name) == ["knee_angle"]
        assert reserve.effort[0] == pytest.approx(want - tau, abs=1e-9)
    drives = np.array([m.position for m in probe.drives])
    assert list(probe.drives[-1].name) == MUSCLES
    assert np.all((drives >= 0) & (drives <= 1)) and drives[-50:].max() > 0.01
    assert node.issues.counts["stale_excitation"] == 0


def test_stream_targets_report_lag_and_error_and_bad_targets_are_counted(ros, geometry_file):
    """Real time: a constant stream target (Float64MultiArray in joints order, then JointState
    by name) with the knee held: /diagnostics names the source and reports the tracking lag and
    error; each kind of bad target message is counted and the node keeps stepping."""
    node, probe = coordinating_node(ros, geometry_file, diagnostics_period_s=0.2,
                                    input_timeout_s=1000.0, stale_input_policy="hold")
    from std_msgs.msg import Float64MultiArray

    probe.send_joints(0.0)
    assert ros.spin_until(lambda: node.scheduler.started, timeout_s=10)
    probe.targets_array.publish(Float64MultiArray(data=[-25.0]))
    assert ros.spin_until(lambda: node.coordination.targets.kind == "stream")

    def diagnostics_have_tracking():
        values = probe.base.last_diagnostics()
        return values.get("coordination targets") == "stream" and \
            values.get("tracking lag (s)") not in (None, "nan")
    assert ros.spin_until(diagnostics_have_tracking, timeout_s=30)
    values = probe.base.last_diagnostics()
    assert 0.0 <= float(values["tracking lag (s)"]) <= 0.15
    assert values["coordination QP not solved (periods)"] == "0"
    assert float(values["tracking error RMS (N m)"]) >= 0.0

    bad = [  # (kind, send)
        ("target_wrong_size", lambda: probe.targets_array.publish(
            Float64MultiArray(data=[1.0, 2.0]))),
        ("target_non_finite", lambda: probe.targets.publish(
            _effort_state(probe, ["knee_angle"], [float("nan")]))),
        ("target_duplicate_name", lambda: probe.targets.publish(
            _effort_state(probe, ["knee_angle", "knee_angle"], [1.0, 2.0]))),
        ("target_unknown_joint", lambda: probe.targets.publish(
            _effort_state(probe, ["elbow"], [1.0]))),
        ("target_bad_time", lambda: probe.send_trajectory(
            ["knee_angle"], [0.2, 0.1], [[1.0], [2.0]])),
        ("target_wrong_size", lambda: probe.send_trajectory(
            ["knee_angle"], [0.1, 0.2], [[1.0], [2.0, 3.0]])),
        ("target_wrong_size", lambda: probe.send_trajectory(   # planned positions: one per name
            ["knee_angle"], [0.1, 0.2], [[1.0], [2.0]], positions=[[1.0], [1.0, 2.0]])),
    ]
    for kind, send in bad:
        before = node.issues.counts[kind]
        send()
        assert ros.spin_until(lambda k=kind, b=before: node.issues.counts[k] > b,
                              timeout_s=10), kind
    assert node.coordination.targets.kind == "stream"  # no bad message replaced the source
    ticks = node.ticks
    assert ros.spin_until(lambda: node.ticks > ticks + 5, timeout_s=10)
    probe.targets.publish(_effort_state(probe, ["knee_angle"], [-10.0]))
    assert ros.spin_until(lambda: node.coordination.targets.robot_at([0])[0, 0] == -10.0)
    labels = {kind: ISSUE_KINDS[kind][0] for kind, _ in bad}
    assert ros.spin_until(lambda: all(
        int(probe.base.last_diagnostics().get(label, "0")) >= 1 for label in labels.values()),
        timeout_s=10)

    # planned positions: the knee held at 1.0 rad (box 0-2 rad); a plan at 1.05 rad (0.025 of
    # the box away) is not counted, one at 1.5 rad (0.25 of the box, above
    # coordination.plan_offset_max's 0.1) is, once per publish period it is used
    far_label = ISSUE_KINDS["plan_far_from_joints"][0]
    for plan_q, far in ((1.05, False), (1.5, True)):
        probe.send_joints(0.0)
        probe.send_trajectory(["knee_angle"], [0.0, 10.0], [[-10.0], [-10.0]],
                              positions=[[plan_q], [plan_q]])
        assert ros.spin_until(lambda q=plan_q: node.coordination.targets.has_planned_positions
                              and node.coordination.targets.model_positions_at([0])[0, 0] == q,
                              timeout_s=10)
        ticks = node.ticks
        assert ros.spin_until(lambda t=ticks: node.ticks > t + 5, timeout_s=10)
        assert (node.issues.counts["plan_far_from_joints"] > 0) == far, plan_q
    assert ros.spin_until(lambda: int(probe.base.last_diagnostics().get(far_label, "0")) >= 1,
                          timeout_s=10)


def _effort_state(probe, names, effort):
    msg = probe.base.joint_state(names)
    msg.effort = list(effort)
    return msg


def test_coordination_needs_a_geometry(ros):
    from vm_ros.errors import ConfigError

    with pytest.raises(ConfigError, match="coordination.enabled"):
        ros.muscle_node(muscles=MUSCLES, coordination__enabled=True)


def test_recompute_reproduces_a_live_coordination_log_exactly(ros, geometry_file, tmp_path,
                                                              capsys):
    """Simulated time, 100 Hz periods: a planned profile, then a stream target that replaces it
    mid-run, logged to MCAP. The log holds the targets as received, the drives the coordinator
    applied (coordination_drive, one per period at its start, equal to what muscle_drive
    reports the steps used), joint_reserves = target - joint effort; `vm-ros recompute` of it
    gives the same tendon forces, joint efforts and energy at every stamp and says exact."""
    from std_msgs.msg import Float64MultiArray

    from vm_ros.cli import main
    from vm_ros.recording import read_run
    from vm_ros.recording.replay import recorded_messages

    path = tmp_path / "coordination.mcap"
    node, probe = coordinating_node(ros, geometry_file, use_sim_time=True,
                                    stale_input_policy="hold", input_timeout_s=1000.0,
                                    mcap__enabled=True, mcap__path=str(path))
    set_clock(ros, probe.base, node, T0)
    times = np.arange(0.0, 2.0, 0.02)
    probe.send_trajectory(["knee_angle"], times, knee_target(times)[:, None], stamp_ns=T0)
    assert ros.spin_until(lambda: node.coordination.targets.kind == "planned profile")
    periods = 60
    for k in range(periods + 1):
        if k == 40:  # a stream replaces the profile
            probe.targets_array.publish(Float64MultiArray(data=[-15.0]))
            assert ros.spin_until(lambda: node.coordination.targets.kind == "stream")
        before = node.joint_inputs.sample
        probe.send_joints(k * PERIOD_NS * 1e-9)
        assert ros.spin_until(lambda b=before: node.joint_inputs.sample is not b, timeout_s=10)
        set_clock(ros, probe.base, node, T0 + (k + 1) * PERIOD_NS)
    assert ros.spin_until(lambda: len(probe.efforts) >= periods, timeout_s=30)
    node.close_run_log()

    original = read_run(path)
    applied = original.get(tm.TOPIC_COORDINATION_DRIVE)
    assert applied is not None and len(applied) >= periods
    assert list(applied.names) == MUSCLES
    drives = original.get(tm.TOPIC_MUSCLE_DRIVE)
    # the drive a published step used is the one applied at its period's start
    period_start = drives.fields["stamp_ns"] - PERIOD_NS
    common, i, j = np.intersect1d(period_start, applied.fields["stamp_ns"],
                                  return_indices=True)
    assert len(common) >= periods - 2
    np.testing.assert_array_equal(drives.fields["position"][i], applied.fields["position"][j])
    assert applied.fields["position"].max() > 0.05
    logged = Counter(m.topic for m in recorded_messages(path, include_offline=True))
    assert logged["/" + tm.TOPIC_JOINT_EFFORT_TRAJECTORY] == 1
    assert logged["/" + tm.TOPIC_JOINT_EFFORT_TARGETS_ARRAY] == 1
    reserves, efforts = original.get(tm.TOPIC_JOINT_RESERVES), original.get(tm.TOPIC_JOINT_EFFORTS)
    late = reserves.fields["stamp_ns"] > efforts.fields["stamp_ns"][-1] - 10 * PERIOD_NS
    common, i, j = np.intersect1d(reserves.fields["stamp_ns"][late], efforts.fields["stamp_ns"],
                                  return_indices=True)
    np.testing.assert_allclose(reserves.fields["effort"][late][i, 0],
                               -15.0 - efforts.fields["effort"][j, 0], atol=1e-9)

    out = tmp_path / "again.mcap"
    assert main(["recompute", str(path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "exact: the recomputed outputs equal the recorded ones" in printed, printed
    again = read_run(out)
    for topic, field in ((tm.TOPIC_FORCE, "effort"), (tm.TOPIC_JOINT_EFFORTS, "effort"),
                         (tm.TOPIC_ENERGY_TOTAL, "data")):  # energy_total: no header, log time
        first, second = original.get(topic), again.get(topic)
        common, i, j = np.intersect1d(first.fields.get("stamp_ns", first.time_ns),
                                      second.fields.get("stamp_ns", second.time_ns),
                                      return_indices=True)
        assert len(common) >= periods, topic
        np.testing.assert_array_equal(second.fields[field][j], first.fields[field][i],
                                      err_msg=topic)
    copied = again.get(tm.TOPIC_COORDINATION_DRIVE)
    np.testing.assert_array_equal(copied.fields["position"], applied.fields["position"])
