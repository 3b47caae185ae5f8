"""muscle_node from joint space: joint_states in, joint_efforts and joint_effort_commands out,
equal to an offline computation (MuscleBank stepped on the geometry's path lengths with the node's
zero-order hold, tau = r^T F); joint_map sign and offset; bad joint inputs counted; start-up errors.
In-process rclpy like test_node.py (test/conftest.py), plus subprocesses of the installed node."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import require_ros, set_clock, stamp_ns
from test_joint_space import small_geometry

from vm_ros import telemetry as tm
from vm_ros.errors import ConfigError
from vm_ros.geometry import generalized_forces, write_geometry
from vm_ros.model import MuscleBank
from vm_ros.node.health import ISSUE_KINDS
from vm_ros.node.inputs import physical_path_length_range

pytestmark = pytest.mark.ros

MUSCLES = ["vasti", "rectus_femoris", "soleus"]  # soleus: muscle_kinematics
MS = 1_000_000
SIM_T0 = 1_000 * MS
KNEE_MAP = "{knee: {coordinate: knee_angle, sign: -1, offset: 0.3}}"  # model q = 0.3 - robot q
JOINTS = ["knee", "hip_flexion"]
SOLEUS_LENGTH = 0.318


@pytest.fixture
def geometry_file(tmp_path):
    return str(write_geometry(small_geometry(), tmp_path / "geometry.yaml"))


class JointProbe:
    """The conftest probe plus joint_states out and joint_efforts / joint_effort_commands in."""

    def __init__(self, ros):
        from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState
        from std_msgs.msg import Float64MultiArray

        self.base = ros.probe()
        node = self.base.node
        keep = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                          reliability=ReliabilityPolicy.RELIABLE)
        self.efforts, self.commands = [], []
        node.create_subscription(JointState, tm.TOPIC_JOINT_EFFORTS, self.efforts.append, keep)
        node.create_subscription(Float64MultiArray, tm.TOPIC_JOINT_EFFORT_COMMANDS,
                                 self.commands.append, keep)
        self.joint_states = node.create_publisher(JointState, tm.TOPIC_JOINT_STATES, keep)

    def send_joints(self, names, position, velocity=()):
        self.joint_states.publish(self.base.joint_state(names, position, velocity))


def connected(ros, node, probe: JointProbe) -> None:
    """Every endpoint used here matched, both ways."""
    base = probe.base
    assert ros.spin_until(lambda: all(p.get_subscription_count() > 0 for p in (
        base.excitation_array, base.kinematics, probe.joint_states))
        and all(p.get_subscription_count() > 0 for p in node._publishers_by_topic.values()),
        timeout_s=10)


def joint_node(ros, geometry_file, **params):
    """A joint-space node; a tick per step unless ``batch_steps`` is given (set_clock steps the
    clock 1 ms at a time)."""
    params = {"muscles": MUSCLES, "geometry": geometry_file, "batch_steps": 1, **params}
    node = ros.muscle_node(**params)
    probe = JointProbe(ros)
    connected(ros, node, probe)
    return node, probe


# --- outputs equal the offline computation -------------------------------------------------------


def test_joint_efforts_equal_the_offline_computation(ros, geometry_file):
    """Under /clock: three joint samples (one outside the box, one naming the joints without
    velocities); every joint_efforts and joint_effort_commands message equals tau = r^T F of an
    offline MuscleBank on the geometry's path lengths, held and extrapolated as the node
    documents; robot convention through the knee's sign and offset."""
    node, probe = joint_node(ros, geometry_file, use_sim_time=True, joint_map=KNEE_MAP,
                             joints=JOINTS, stale_input_policy="hold", input_timeout_s=1000.0,
                             extrapolation_max_s=0.005)
    geometry = small_geometry()
    names = ["hip_flexion", "knee", "ankle_angle"]
    samples = [  # (robot position, robot velocity) in `names` order
        ([0.4, -0.7, 0.1], [0.3, -0.8, 0.0]),
        ([1.9, -0.2, 0.0], [2.0, 0.5, 0.0]),  # hip beyond 1.5: clamped, its velocity 0
        ([-0.2, -1.5, 0.0], []),               # no velocities: 0
    ]
    switch_at = {0: 0, 9: 1, 21: 2}  # clock jump k (10 ms each) -> sample sent after it
    set_clock(ros, probe.base, node, SIM_T0)
    probe.base.send_kinematics(["soleus"], [SOLEUS_LENGTH])
    applied = []  # (model time the node applied it, index)

    def send_sample(index):
        before = node.joint_inputs.sample
        probe.send_joints(names, *samples[index])
        assert ros.spin_until(lambda: node.joint_inputs.sample is not before, timeout_s=5)
        applied.append((node.joint_inputs.sample.time_ns, index))

    send_sample(0)
    assert ros.spin_until(lambda: node.inputs.ready)
    assert applied[0][0] == SIM_T0
    drive = np.array([0.7, 0.4, 0.2])
    probe.base.send_excitation_array(drive)
    assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, drive))
    start = SIM_T0 + MS
    set_clock(ros, probe.base, node, start)
    assert node.scheduler.started and node.scheduler.anchor_ns == start
    for k in range(1, 31):
        set_clock(ros, probe.base, node, start + k * 10 * MS)
        if k in switch_at and k:
            send_sample(switch_at[k])
            assert applied[-1][0] == start + k * 10 * MS
    assert ros.spin_until(lambda: len(probe.efforts) >= 31 and len(probe.commands) >= 31
                          and len(probe.base.forces) >= 31)
    assert len(probe.efforts) == len(probe.commands) == 31

    # offline: each sample's model pose through the geometry; lengths held (and extrapolated for
    # extrapolation_max_s with the sample's path velocity, then held with velocity 0)
    horizon = 5 * MS
    sign, offset = np.array([1.0, -1.0, 1.0]), np.array([0.0, 0.3, 0.0])
    evaluated = []
    for position, velocity in samples:
        q = sign * np.array(position) + offset
        qdot = sign * np.array(velocity) if velocity else np.zeros(3)
        evaluated.append(geometry.evaluate(q, qdot))
    lo, hi = physical_path_length_range(MuscleBank.from_config(MUSCLES), 0.5)

    def inputs_at(t_ns):
        t_applied, index = max(a for a in applied if a[0] <= t_ns)
        out = evaluated[index]
        since = min(t_ns - t_applied, horizon)
        lp = out.length_m[:2] + out.velocity_m_per_s[:2] * (since * 1e-9)
        vp = out.velocity_m_per_s[:2] if t_ns - t_applied < horizon else np.zeros(2)
        lp = np.clip(np.append(lp, SOLEUS_LENGTH), lo, hi)
        return lp, np.append(vp, 0.0), out

    bank = MuscleBank.from_config(MUSCLES)
    lp, _, pose = inputs_at(start)
    expected = [(bank.reset(path_length=lp), pose)]
    for i in range(300):
        lp, vp, pose = inputs_at(start + i * MS)
        out = bank.step(1e-3, drive, lp, vp)
        if (i + 1) % 10 == 0:
            expected.append((out, pose))

    order = [1, 0]  # JOINTS = knee, hip_flexion
    for msg, command, force, (out, pose) in zip(probe.efforts, probe.commands, probe.base.forces,
                                                expected, strict=True):
        assert stamp_ns(msg) == stamp_ns(force)
        assert list(msg.name) == JOINTS
        np.testing.assert_allclose(force.effort, out.force, rtol=1e-9)
        tau = generalized_forces(pose.moment_arm[:2], out.force[:2])
        robot_tau = (sign * tau)[order]
        np.testing.assert_allclose(msg.effort, robot_tau, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(command.data, robot_tau, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(msg.position, (sign * (pose.q - offset))[order], rtol=1e-12)
        np.testing.assert_allclose(msg.velocity, (sign * pose.qdot)[order], rtol=1e-12,
                                   atol=1e-15)
    assert [d.label for d in probe.commands[0].layout.dim] == ["joint"]
    assert probe.efforts[10].position[1] == 1.5  # the clamped hip, as used
    assert probe.efforts[10].velocity[1] == 0.0
    assert node.issues.counts["joint_clamped"] == 1
    # the extensors pull the robot's knee (extension positive here) positive
    assert all(m.effort[0] > 0 for m in probe.efforts[1:])


# --- bad joint inputs ----------------------------------------------------------------------------


def test_bad_joint_inputs_are_counted_and_the_node_keeps_running(ros, geometry_file):
    node, probe = joint_node(ros, geometry_file, diagnostics_period_s=0.1,
                             input_timeout_s=1000.0, stale_input_policy="hold")
    names = ["hip_flexion", "knee_angle", "ankle_angle"]
    probe.base.send_kinematics(["soleus"], [SOLEUS_LENGTH])
    probe.send_joints(names, [0.2, 1.0, 0.0])
    probe.base.send_excitation_array([0.5, 0.5, 0.5])
    assert ros.spin_until(lambda: node.scheduler.started and len(probe.efforts) > 2)
    lengths = node.inputs.length_m.copy()
    cases = [
        ((names, [0.2, float("nan"), 0.0]), "joint_non_finite", 1),
        ((names, [0.2, 1.0, 0.0], [0.0, float("inf"), 0.0]), "joint_non_finite", 1),
        ((names, [0.2, 1.0]), "joint_wrong_size", 1),
        ((names, [0.2, 1.0, 0.0], [0.0]), "joint_wrong_size", 1),
        (([], [0.2, 1.0]), "joint_wrong_size", 1),
        ((["knee_angle", "knee_angle"], [1.0, 1.1]), "joint_duplicate_name", 1),
        ((["finger", "wheel"], [0.0, 0.0]), "joint_unknown_name", 2),
        ((["knee_angle", "hip_flexion"], [1.0, 0.2], [1e9, 0.0]), "non_physical_velocity", 1),
        ((["knee_angle", "hip_flexion"], [1.0, 9.0]), "joint_clamped", 1),  # used: last
    ]
    for args, kind, count in cases:
        before = node.issues.counts[kind]
        probe.send_joints(*args)
        assert ros.spin_until(lambda k=kind, b=before, c=count: node.issues.counts[k] == b + c,
                              timeout_s=3), (args, kind)
        if kind != "joint_clamped":
            np.testing.assert_array_equal(node.inputs.length_m, lengths, err_msg=kind)
    # muscle_kinematics for a joint-driven muscle: ignored and counted, soleus still taken
    before = node.issues.counts["joint_driven_kinematics"]
    probe.base.send_kinematics(["vasti", "soleus"], [0.3, 0.32])
    assert ros.spin_until(lambda: node.issues.counts["joint_driven_kinematics"] == before + 1)
    assert node.inputs.length_m[2] == 0.32 and node.inputs.length_m[0] != 0.3

    labels = {kind: label for kind, (label, _) in ISSUE_KINDS.items()}
    counts = {kind: node.issues.counts[kind] for kind in (
        "joint_non_finite", "joint_wrong_size", "joint_duplicate_name", "joint_unknown_name",
        "joint_clamped", "joint_driven_kinematics", "non_physical_velocity")}
    assert counts["joint_non_finite"] == 2 and counts["joint_wrong_size"] == 3

    def reported():
        diag = probe.base.last_diagnostics()
        return bool(diag) and all(diag.get(labels[k]) == str(v) for k, v in counts.items())
    assert ros.spin_until(reported, timeout_s=3)
    diag = probe.base.last_diagnostics()
    assert "joint_states age (s)" in diag and diag["state"] == "running"
    n = len(probe.efforts)
    assert ros.spin_until(lambda: len(probe.efforts) > n + 5)  # still running
    assert np.all(np.isfinite(probe.efforts[-1].effort)) and np.any(probe.efforts[-1].effort)


def test_inputs_the_model_would_refuse_are_counted_and_the_node_keeps_running(ros, tmp_path):
    """A geometry that loads (its paths are 0.01-0.21 m at every pose the loader samples) but
    reaches -0.005 m at an unsampled corner of its box, with the node's accepted range widened
    to the geometry's own (which starts below 0 m): joint_states at that corner, a pose clamped
    onto it, an overflowing coordinate, and muscle_kinematics and excitation values that the
    model refuses are each dropped and counted; the node keeps stepping (an exception in the
    timer callback would stop this in-process spin)."""
    from test_node_inputs import dipping_geometry

    geometry = str(write_geometry(dipping_geometry(), tmp_path / "dip.yaml"))
    node, probe = joint_node(ros, geometry, diagnostics_period_s=0.1, input_timeout_s=1000.0,
                             stale_input_policy="hold")
    names = ["hip_flexion", "knee_angle", "ankle_angle"]
    probe.base.send_kinematics(["soleus"], [SOLEUS_LENGTH])
    probe.send_joints(names, [0.5, 2.0, 0.0])
    probe.base.send_excitation_array([0.5, 0.5, 0.5])
    assert ros.spin_until(lambda: node.scheduler.started and len(probe.efforts) > 2)
    lengths = node.inputs.length_m.copy()
    cases = [
        (lambda: probe.send_joints(names, [1.5, 0.0, 0.0]), {"non_physical_length": 1}),
        (lambda: probe.send_joints(names, [9.0, -3.0, 0.0]),
         {"non_physical_length": 1, "joint_clamped": 2}),
        (lambda: probe.base.send_kinematics(["soleus"], [0.0]), {"non_physical_length": 1}),
        (lambda: probe.base.send_kinematics(["soleus"], [-0.3]), {"non_physical_length": 1}),
        (lambda: probe.base.send_kinematics(["soleus"], [SOLEUS_LENGTH], [float("nan")]),
         {"non_finite": 1}),
        (lambda: probe.base.send_excitation(["vasti"], [float("inf")]), {"non_finite": 1}),
        (lambda: probe.base.send_excitation_array([0.5, float("nan"), 0.5]), {"non_finite": 1}),
        # the knee past 1.8e308 (clamped, used), then moved on by its velocity: overflow
        (lambda: probe.send_joints(["knee_angle"], [1.79e308], [1.79e308]), {"joint_clamped": 1}),
        (lambda: probe.send_joints(["hip_flexion"], [0.5]), {"joint_non_finite": 1}),
    ]
    for send, expected in cases:
        before = {kind: node.issues.counts[kind] for kind in expected}
        n = len(probe.efforts)
        send()
        assert ros.spin_until(lambda e=expected, b=before: all(
            node.issues.counts[k] == b[k] + c for k, c in e.items()), timeout_s=3), expected
        if "joint_clamped" not in expected:
            np.testing.assert_array_equal(node.inputs.length_m, lengths, err_msg=str(expected))
        assert ros.spin_until(lambda n=n: len(probe.efforts) > n + 2)  # still stepping
    labels = {kind: label for kind, (label, _) in ISSUE_KINDS.items()}
    counts = {kind: node.issues.counts[kind] for kind in (
        "non_physical_length", "non_finite", "joint_non_finite", "joint_clamped")}
    assert counts["non_physical_length"] == 4 and counts["joint_non_finite"] == 1

    def reported():
        diag = probe.base.last_diagnostics()
        return bool(diag) and all(diag.get(labels[k]) == str(v) for k, v in counts.items())
    assert ros.spin_until(reported, timeout_s=3)
    assert probe.base.last_diagnostics()["state"] == "running"
    assert np.all(np.isfinite(probe.efforts[-1].effort))


def test_unknown_joints_alone_do_not_raise_a_warning(ros, geometry_file):
    """A robot's joint_states usually carries more joints than the geometry: counted, not WARN."""
    node, probe = joint_node(ros, geometry_file, diagnostics_period_s=0.05,
                             input_timeout_s=1000.0)
    probe.base.send_excitation_array([0.1, 0.1, 0.1])  # every input fresh: no stale WARN
    probe.base.send_kinematics(["soleus"], [SOLEUS_LENGTH])
    names = ["hip_flexion", "knee_angle", "ankle_angle", "gripper", "wheel"]
    probe.send_joints(names, [0.2, 1.0, 0.0, 0.01, 3.0])
    assert ros.spin_until(lambda: node.scheduler.started)
    for _ in range(5):
        probe.send_joints(names, [0.2, 1.0, 0.0, 0.01, 3.0])
    assert ros.spin_until(lambda: node.issues.counts["joint_unknown_name"] == 12)

    def ok_report():
        diag = probe.base.last_diagnostics()
        # not a WARN about joints (a WARN for falling behind on a loaded machine is pace)
        return diag.get(ISSUE_KINDS["joint_unknown_name"][0]) == "12" and (
            diag["_level"] == 0 or "joint" not in diag["_message"])
    assert ros.spin_until(ok_report, timeout_s=5), probe.base.last_diagnostics()


def test_the_model_waits_for_joint_states_and_says_so(ros, geometry_file):
    node, probe = joint_node(ros, geometry_file, diagnostics_period_s=0.05, joints=JOINTS[1:],
                             initial_path_length_m=[0.3, 0.52, SOLEUS_LENGTH])
    # soleus has its initial length; the joint-driven muscles wait for hip and knee
    assert ros.spin_until(lambda: probe.base.last_diagnostics().get("state", "").startswith(
        "waiting"), timeout_s=5)
    assert probe.base.last_diagnostics()["state"] == \
        "waiting for joint_states (hip_flexion, knee_angle)"
    probe.send_joints(["knee_angle"], [1.0])
    assert ros.spin_until(lambda: probe.base.last_diagnostics().get("state") ==
                          "waiting for joint_states (hip_flexion)", timeout_s=5)
    assert not node.scheduler.started
    probe.send_joints(["hip_flexion"], [0.2])  # the ankle is not needed: no driven path, not in
    assert ros.spin_until(lambda: node.scheduler.started and len(probe.efforts) > 0)  # joints
    assert list(probe.efforts[-1].name) == ["hip_flexion"]


def test_without_geometry_there_are_no_joint_topics(ros, tmp_path):
    from vm_ros.recording import read_run

    lo, hi = physical_path_length_range(MuscleBank.from_config(MUSCLES[:2]), 0.0)
    path = tmp_path / "run.mcap"
    node = ros.muscle_node(muscles=MUSCLES[:2], initial_path_length_m=list(0.5 * (lo + hi)),
                           mcap__enabled=True, mcap__path=str(path))
    assert tm.TOPIC_JOINT_STATES not in node._subscriptions_by_topic
    assert tm.TOPIC_JOINT_EFFORTS not in node._publishers_by_topic
    assert node.joint_inputs is None
    assert ros.spin_until(lambda: node.scheduler.started)
    node.close_run_log()
    run = read_run(path)
    assert not any("joint" in topic for topic in run.topic_types)
    assert "geometry.yaml" not in run.attachments and run.info.config.geometry is None


def test_the_run_log_holds_the_joint_topics_and_the_geometry(ros, geometry_file):
    """joint_states logged as received, joint_efforts/joint_effort_commands as published, the
    geometry file attached (exact bytes) with joint_map and joints in the run record."""
    from vm_ros.recording import read_run

    path = Path(geometry_file).with_name("run.mcap")
    node, probe = joint_node(ros, geometry_file, joint_map=KNEE_MAP, joints=JOINTS,
                             input_timeout_s=1000.0, mcap__enabled=True, mcap__path=str(path))
    probe.base.send_kinematics(["soleus"], [SOLEUS_LENGTH])
    probe.base.send_excitation_array([0.6, 0.3, 0.1])
    probe.send_joints(["hip_flexion", "knee", "wheel"], [0.3, -0.6, 1.0], [0.1, -0.2, 0.0])
    assert ros.spin_until(lambda: len(probe.efforts) >= 5 and len(probe.commands) >= 5)
    node.close_run_log()
    ros.spin_for(0.05)
    run = read_run(path)
    assert run.complete and run.info.source == "muscle_node"
    assert run.attachments["geometry.yaml"] == Path(geometry_file).read_bytes()
    config = run.info.config
    assert config.geometry == Path(geometry_file) and config.joint_map == KNEE_MAP
    assert config.joints == tuple(JOINTS)
    states = run.get(tm.TOPIC_JOINT_STATES)
    assert len(states) == 1 and states.names == ("hip_flexion", "knee", "wheel")
    np.testing.assert_array_equal(states.fields["position"][0], [0.3, -0.6, 1.0])
    efforts, commands = run.get(tm.TOPIC_JOINT_EFFORTS), run.get(tm.TOPIC_JOINT_EFFORT_COMMANDS)
    assert efforts.names == tuple(JOINTS) and len(efforts) == len(commands) >= 5
    logged = dict(zip(efforts.fields["stamp_ns"].tolist(), efforts.fields["effort"],
                      strict=True))
    for msg in probe.efforts:
        if stamp_ns(msg) in logged:
            np.testing.assert_array_equal(logged[stamp_ns(msg)], msg.effort)
    np.testing.assert_array_equal(commands.fields["data"], efforts.fields["effort"])


# --- parameters ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("params", "field", "reason"),
    [
        ({"joint_map": "{knee: thigh}"}, "joint_map", "unknown coordinate 'thigh'"),
        ({"joint_map": "{knee: {coordinate: knee_angle, sign: 2}}"}, "joint_map", "sign"),
        ({"joints": ["knee"]}, "joints", "not a robot joint"),
        ({"joints": ["knee_angle", "knee_angle"]}, "joints", "twice"),
        ({"muscles": ["soleus"]}, "geometry", "none of the geometry's muscles"),
        ({"geometry": "/no/such/geometry.yaml"}, "geometry", "cannot read"),
    ],
)
def test_bad_joint_parameters_stop_the_node_naming_the_field(ros, geometry_file, params, field,
                                                             reason):
    with pytest.raises(ConfigError) as info:
        ros.muscle_node(**{"muscles": MUSCLES, "geometry": geometry_file, **params})
    assert info.value.field == field and reason in str(info.value)


@pytest.fixture(scope="module")
def installed_node():
    require_ros()  # the subprocesses start rclpy
    path = Path(sys.prefix) / "bin" / "muscle_node"
    assert os.access(path, os.X_OK), f"{path}: `pip install .` into this venv"
    return str(path)


@pytest.mark.parametrize(
    ("params", "expected"),
    [
        ({"geometry": "/no/such/geometry.yaml"}, "'geometry'"),
        ({"joint_map": "{knee: thigh}"}, "'joint_map'"),
        ({"joint_map": "{knee: {sign: 0}}"}, "'joint_map'"),
        ({"joints": "[elbow]"}, "'joints'"),
        ({"geometry": "", "joints": "[knee_angle]"}, "'joints'"),
    ],
    ids=["missing-geometry", "unknown-coordinate", "bad-sign", "unmapped-joint", "no-geometry"],
)
def test_bad_joint_parameters_exit_2_with_one_line(installed_node, geometry_file, params,
                                                   expected):
    values = {"muscles": "[" + ", ".join(MUSCLES) + "]", "geometry": geometry_file, **params}
    args = ["--ros-args"]
    for name, value in values.items():  # rcl reads -p values as YAML: quote the YAML strings
        args += ["-p", f'{name}:="{value}"' if name in ("geometry", "joint_map") else
                 f"{name}:={value}"]
    proc = subprocess.run([installed_node, *args], capture_output=True, text=True, timeout=60,
                          env={**os.environ, "AMENT_PREFIX_PATH": sys.prefix})
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("muscle_node: error: "), proc.stderr
    assert expected in lines[0], lines[0]


@pytest.mark.parametrize(("trilong", "expected"), [
    ((-0.014, 0.017), "muscle TRIlong: path length -0.014 m at elbow_flexion=0.5 rad"),
    ((-0.03, -0.01), "muscle TRIlong: path length -0.03 m at elbow_flexion=0.5 rad"),
    (None, "muscle TRIlong: coefficient 0 is 1e+308 m"),
], ids=["negative-at-one-end", "negative-everywhere", "1e308"])
def test_a_geometry_with_non_physical_paths_stops_the_node_at_start(installed_node, tmp_path,
                                                                    trilong, expected):
    """Refused when loaded, in one line naming the muscle and the pose (exit 2), instead of a
    node that dies at the first joint sample there, or waits for ever (1e308)."""
    from test_geometry import elbow_geometry

    from vm_ros.geometry import MusclePath, PolynomialGeometry

    geometry = elbow_geometry(*(trilong or (0.1, 0.2)))
    if trilong is None:
        huge = MusclePath("TRIlong", ("elbow_flexion",), (0.0,), (1.0,), [[0], [1]],
                          [1e308, 1e308])
        geometry = PolynomialGeometry(geometry.coordinates, [geometry.muscles[0], huge])
    path = write_geometry(geometry, tmp_path / "elbow.yaml")
    proc = subprocess.run([installed_node, "--ros-args", "-p", "muscles:=[vasti, soleus]",
                           "-p", f'geometry:="{path}"'], capture_output=True, text=True,
                          timeout=60, env={**os.environ, "AMENT_PREFIX_PATH": sys.prefix})
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("muscle_node: error: "), proc.stderr
    assert "'geometry'" in lines[0] and expected in lines[0], lines[0]


def test_help_lists_the_joint_parameters(installed_node):
    proc = subprocess.run([installed_node, "--help"], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0
    for name in ("geometry", "joint_map", "joints"):
        assert f"  {name} (" in proc.stdout


def test_recompute_reproduces_a_node_joint_space_log_exactly(ros, geometry_file, tmp_path,
                                                             capsys):
    """A muscle_node run under /clock (joint samples switching mid-run, one between the start
    and the first step, one outside the box, knee sign -1 and offset) logged to MCAP;
    `vm-ros recompute` of it gives the same muscle forces and joint efforts at every stamp and
    says exact."""
    from vm_ros.cli import main
    from vm_ros.recording import read_run

    path = tmp_path / "node.mcap"
    node, probe = joint_node(ros, geometry_file, use_sim_time=True, joint_map=KNEE_MAP,
                             joints=JOINTS, stale_input_policy="hold", input_timeout_s=1000.0,
                             mcap__enabled=True, mcap__path=str(path))
    names = ["hip_flexion", "knee", "ankle_angle"]
    # k = 1 arrives after the tick that starts the model and before the next one: it is logged
    # at the start time, so the state at the start must take it (as recompute does)
    samples = {0: ([0.4, -0.7, 0.1], [0.3, -0.8, 0.0]), 1: ([0.5, -0.9, 0.1], [0.1, 0.2, 0.0]),
               7: ([1.9, -0.2, 0.0], [2.0, 0.5, 0.0]), 15: ([-0.2, -1.5, 0.0], [])}
    set_clock(ros, probe.base, node, SIM_T0)
    probe.base.send_kinematics(["soleus"], [SOLEUS_LENGTH])
    probe.base.send_excitation_array([0.7, 0.4, 0.2])
    for k in range(25):
        if k in samples:
            before = node.joint_inputs.sample
            probe.send_joints(names, *samples[k])
            assert ros.spin_until(lambda before=before: node.joint_inputs.sample is not before)
        set_clock(ros, probe.base, node, SIM_T0 + (k + 1) * 10 * MS)
    assert ros.spin_until(lambda: len(probe.efforts) >= 20)
    node.close_run_log()
    out = tmp_path / "again.mcap"
    assert main(["recompute", str(path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "exact: the recomputed outputs equal the recorded ones" in printed, printed
    original, again = read_run(path), read_run(out)
    for topic in (tm.TOPIC_FORCE, tm.TOPIC_JOINT_EFFORTS):
        first, second = original.get(topic), again.get(topic)
        common, i, j = np.intersect1d(first.fields["stamp_ns"], second.fields["stamp_ns"],
                                      return_indices=True)
        assert len(common) >= 20, topic
        np.testing.assert_array_equal(second.fields["effort"][j], first.fields["effort"][i],
                                      err_msg=topic)
