"""muscle_node's joint space (vm_ros.joint_space): the joint map, conditioning of joint_states
into the joint-driven muscles' path kinematics, and the torques (no ROS needed).

References: the geometry evaluated directly, closed-form sign/offset conversions, and the power
identity sum(tau_robot * qdot_robot) = -sum(F * Ldot).
"""

from __future__ import annotations

import numpy as np
import pytest

from vm_ros.errors import ConfigError
from vm_ros.geometry import (
    Coordinate,
    CoupledCoordinate,
    MusclePath,
    PolynomialGeometry,
    write_geometry,
)
from vm_ros.joint_space import JointMap, JointSpace, parse_joint_map
from vm_ros.model import MuscleBank
from vm_ros.node.inputs import InputLimits, NodeInputs
from vm_ros.node.joint_inputs import JointInputs
from vm_ros.node.params import PARAMS_SOURCE, NodeConfig

MUSCLES = ("vasti", "rectus_femoris", "soleus")  # soleus: not in the geometry
DRIVEN = ("vasti", "rectus_femoris")
MS = 1_000_000


def small_geometry(backend: str = "numpy") -> PolynomialGeometry:
    """hip and knee (rad; flexion positive), a coupled patella, three paths whose lengths stay in
    the library's ranges over the box (vasti 0.286-0.338 m, rectus femoris 0.497-0.544 m):

    vasti           L = 0.29 + 0.022 knee + 0.001 knee^2
    rectus_femoris  L = 0.52 + 0.01 knee - 0.01 hip + 0.002 hip knee   (offset/scale exercised)
    gluteus_maximus L = 0.2 + 0.03 hip                                 (not a node muscle)
    """
    coordinates = [Coordinate("hip_flexion", "rad", -0.5, 1.5),
                   Coordinate("knee_angle", "rad", 0.0, 2.0),
                   Coordinate("ankle_angle", "rad", -0.7, 0.5)]
    # rectus in x = (q - offset) / scale with offset (0.5, 1.0), scale (2.0, 0.5):
    # hip = 2 x_h + 0.5, knee = 0.5 x_k + 1.0, expanded from the formula above
    rf = {(0, 0): 0.52 + 0.01 * 1.0 - 0.01 * 0.5 + 0.002 * 0.5 * 1.0,
          (1, 0): -0.01 * 2.0 + 0.002 * 2.0 * 1.0,
          (0, 1): 0.01 * 0.5 + 0.002 * 0.5 * 0.5,
          (1, 1): 0.002 * 2.0 * 0.5}
    muscles = [
        MusclePath("vasti", ("knee_angle",), (0.0,), (1.0,), [[0], [1], [2]],
                   [0.29, 0.022, 0.001]),
        MusclePath("rectus_femoris", ("hip_flexion", "knee_angle"), (0.5, 1.0), (2.0, 0.5),
                   [list(e) for e in rf], list(rf.values())),
        MusclePath("gluteus_maximus", ("hip_flexion",), (0.0,), (1.0,), [[0], [1]],
                   [0.2, 0.03]),
    ]
    coupled = [CoupledCoordinate("patella_angle", ("knee_angle",), "follows the knee")]
    return PolynomialGeometry(coordinates, muscles, coupled, backend=backend)


def reference_lengths(q) -> np.ndarray:
    """vasti and rectus femoris path lengths (m) at model q = (hip, knee, ankle), by formula."""
    hip, knee = q[0], q[1]
    return np.array([0.29 + 0.022 * knee + 0.001 * knee ** 2,
                     0.52 + 0.01 * knee - 0.01 * hip + 0.002 * hip * knee])


@pytest.fixture(scope="module")
def bank():
    return MuscleBank.from_config(list(MUSCLES))


def make(bank, joint_map="", joints=(), **params):
    """(JointInputs, NodeInputs) for the small geometry and the node's default input limits."""
    geometry = small_geometry()
    space = JointSpace(geometry, JointMap.build(joint_map, geometry, PARAMS_SOURCE), MUSCLES,
                       joints, PARAMS_SOURCE)
    config = NodeConfig.from_values({"muscles": list(MUSCLES), **params})
    inputs = NodeInputs(bank.names, InputLimits.for_bank(bank, config), joint_driven=space.driven)
    return JointInputs(space, inputs), inputs


def kinds(issues):
    return [i.kind for i in issues]


# --- the joint map ------------------------------------------------------------------------------


def test_parse_joint_map_forms_and_defaults():
    assert parse_joint_map("", PARAMS_SOURCE) == {}
    assert parse_joint_map("{}", PARAMS_SOURCE) == {}
    text = ("{hip: hip_flexion, knee_joint: {coordinate: knee_angle, sign: -1, offset: 0.25},"
            " ankle_angle: {sign: -1}}")
    assert parse_joint_map(text, PARAMS_SOURCE) == {
        "hip": ("hip_flexion", 1.0, 0.0), "knee_joint": ("knee_angle", -1.0, 0.25),
        "ankle_angle": ("ankle_angle", -1.0, 0.0)}


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("{hip: [unclosed", "not valid YAML"),
        ("[hip, knee]", "must be a YAML mapping"),
        ("{hip: {coordinate: hip_flexion, sign: 2}}", "sign must be 1 or -1"),
        ("{hip: {sign: true}}", "sign must be 1 or -1"),
        ("{hip: {sign: 0.5}}", "sign must be 1 or -1"),
        ("{hip: {offset: .nan}}", "offset must be a finite number"),
        ("{hip: {offset: ten}}", "offset must be a finite number"),
        ("{hip: {coordinate: hip_flexion, gain: 2}}", "unknown key 'gain'"),
        ("{1: hip_flexion}", "non-empty strings"),
        ("{hip: }", "each entry maps"),
        ("{hip: {coordinate: [a]}}", "coordinate must be"),
    ],
)
def test_bad_joint_map_syntax_names_the_parameter(text, reason):
    with pytest.raises(ConfigError) as info:
        parse_joint_map(text, PARAMS_SOURCE)
    assert info.value.field == "joint_map" and reason in str(info.value)
    with pytest.raises(ConfigError) as info:  # the node's parameter validation says the same
        NodeConfig.from_values({"geometry": "g.yaml", "joint_map": text})
    assert info.value.field == "joint_map"


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("{hip: thigh}", "unknown coordinate 'thigh'"),
        ("{kneecap: patella_angle}", "coupled coordinate"),
        ("{a: knee_angle, b: knee_angle}", "already mapped from robot joint 'a'"),
        ("{hip_flexion: knee_angle}", "map 'hip_flexion' from another robot joint"),
    ],
)
def test_joint_map_is_checked_against_the_geometry(text, reason):
    with pytest.raises(ConfigError) as info:
        JointMap.build(text, small_geometry(), PARAMS_SOURCE)
    assert info.value.field == "joint_map" and reason in str(info.value)


def test_joint_map_names_and_conversions():
    geometry = small_geometry()
    swapped = JointMap.build("{hip_flexion: knee_angle, knee_angle: hip_flexion}", geometry,
                             PARAMS_SOURCE)
    assert swapped.robot_names == ("knee_angle", "hip_flexion", "ankle_angle")
    jmap = JointMap.build("{knee: {coordinate: knee_angle, sign: -1, offset: 0.3}}", geometry,
                          PARAMS_SOURCE)
    assert jmap.robot_names == ("hip_flexion", "knee", "ankle_angle")
    assert jmap.index_of("knee") == 1 and jmap.index_of("knee_angle") is None
    q, qdot = jmap.to_model([0, 1], [0.2, -0.5], [1.0, 2.0])
    np.testing.assert_allclose(q, [0.2, 0.5 + 0.3])  # q = sign * robot q + offset
    np.testing.assert_allclose(qdot, [1.0, -2.0])
    robot_q, robot_qdot, robot_tau = jmap.to_robot([0, 1], q, qdot, [3.0, 4.0])
    np.testing.assert_allclose(robot_q, [0.2, -0.5], rtol=1e-15)
    np.testing.assert_allclose(robot_qdot, [1.0, 2.0])
    np.testing.assert_allclose(robot_tau, [3.0, -4.0])  # tau transforms like qdot
    np.testing.assert_array_equal(jmap.select([], PARAMS_SOURCE), [0, 1, 2])
    np.testing.assert_array_equal(jmap.select(["knee", "hip_flexion"], PARAMS_SOURCE), [1, 0])
    for joints, reason in ((["knee_angle"], "not a robot joint"), (["knee", "knee"], "twice")):
        with pytest.raises(ConfigError) as info:
            jmap.select(joints, PARAMS_SOURCE)
        assert info.value.field == "joints" and reason in str(info.value)


def test_joint_space_driven_ignored_and_needed_coordinates():
    geometry = small_geometry()
    jmap = JointMap.build("", geometry, PARAMS_SOURCE)
    space = JointSpace(geometry, jmap, MUSCLES, ["knee_angle"], PARAMS_SOURCE)
    assert space.driven == DRIVEN and space.ignored == ("gluteus_maximus",)
    np.testing.assert_array_equal(space.driven_index, [0, 1])
    np.testing.assert_array_equal(space.rows, [0, 1])
    assert space.output_names == ("knee_angle",)
    np.testing.assert_array_equal(space.needed, [True, True, False])  # ankle: no driven path
    everything = JointSpace(geometry, jmap, ["soleus", "rectus_femoris"], [], PARAMS_SOURCE)
    assert everything.driven == ("rectus_femoris",)
    np.testing.assert_array_equal(everything.driven_index, [1])
    np.testing.assert_array_equal(everything.needed, [True, True, True])  # joints [] = all
    with pytest.raises(ConfigError) as info:
        JointSpace(geometry, jmap, ["soleus"], [], PARAMS_SOURCE)
    assert info.value.field == "geometry" and "none of the geometry's muscles" in str(info.value)


def test_geometry_parameter_errors_name_the_parameter(tmp_path):
    path = write_geometry(small_geometry(), tmp_path / "geometry.yaml")
    space = JointSpace.load(path, "", MUSCLES, [], PARAMS_SOURCE)
    assert space.driven == DRIVEN
    for bad, reason in ((tmp_path / "missing.yaml", "cannot read"),
                        (tmp_path / "bad.yaml", "version")):
        if bad.name == "bad.yaml":
            bad.write_text(path.read_text().replace("version: 1", "version: 7"))
        with pytest.raises(ConfigError) as info:
            JointSpace.load(bad, "", MUSCLES, [], PARAMS_SOURCE)
        assert info.value.field == "geometry" and reason in str(info.value)
        assert str(bad) in str(info.value)
    for name, value in (("joint_map", "{a: b}"), ("joints", ["knee"])):
        with pytest.raises(ConfigError) as info:
            NodeConfig.from_values({name: value})
        assert info.value.field == name and "needs a geometry file" in str(info.value)


# --- conditioning of joint_states ---------------------------------------------------------------


def test_good_message_feeds_the_driven_muscles_paths(bank):
    joints, inputs = make(bank)
    q, qdot = np.array([0.3, 1.2, 0.1]), np.array([0.5, -1.0, 2.0])
    names = ["ankle_angle", "knee_angle", "hip_flexion"]  # any order
    assert joints.on_joint_states(names, q[[2, 1, 0]], qdot[[2, 1, 0]], 5 * MS) == []
    assert joints.ready and inputs.length_seen.tolist() == [True, True, False]
    np.testing.assert_allclose(inputs.length_m[:2], reference_lengths(q), rtol=1e-14)
    out = small_geometry().evaluate(q, qdot)
    np.testing.assert_allclose(inputs.velocity_m_per_s[:2], out.velocity_m_per_s[:2], rtol=1e-14)
    np.testing.assert_array_equal(inputs.length_time_ns[:2], [5 * MS, 5 * MS])
    np.testing.assert_allclose(joints.sample.moment_arm, out.moment_arm[:2], rtol=1e-14)
    assert not inputs.ready  # soleus still waits for muscle_kinematics
    assert inputs.last_kinematics_ns is None and joints.age_s(7 * MS) == pytest.approx(0.002)


def test_missing_velocities_are_zero_like_muscle_kinematics(bank):
    joints, inputs = make(bank, joints=["hip_flexion", "knee_angle"])
    assert joints.on_joint_states(["hip_flexion", "knee_angle"], [0.1, 0.5], [], 0) == []
    assert joints.ready and inputs.length_seen[:2].all()
    np.testing.assert_array_equal(inputs.velocity_m_per_s[:2], [0.0, 0.0])
    np.testing.assert_array_equal(joints.sample.qdot, [0.0, 0.0, 0.0])


def test_model_waits_for_every_needed_coordinate(bank):
    joints, inputs = make(bank)
    assert joints.on_joint_states(["knee_angle"], [1.0], [], 0) == []
    assert not joints.ready and joints.missing() == ["hip_flexion", "ankle_angle"]
    assert not inputs.length_seen.any()
    assert joints.on_joint_states(["hip_flexion"], [0.2], [], MS) == []
    assert joints.missing() == ["ankle_angle"] and not joints.ready  # joints [] = all needed
    assert joints.on_joint_states(["ankle_angle"], [0.0], [], 2 * MS) == []
    assert joints.ready
    np.testing.assert_allclose(inputs.length_m[:2], reference_lengths([0.2, 1.0, 0.0]))
    # with joints = [knee_angle], the ankle (crossed by no driven path) is not waited for
    only_knee, inputs = make(bank, joints=["knee_angle"])
    only_knee.on_joint_states(["knee_angle", "hip_flexion"], [1.0, 0.2], [], 0)
    assert only_knee.ready and only_knee.missing() == []


def test_partial_message_updates_only_the_muscles_crossing_its_joints(bank):
    joints, inputs = make(bank)
    joints.on_joint_states(["hip_flexion", "knee_angle", "ankle_angle"], [0.2, 1.0, 0.0],
                           [0.0, 0.5, 0.0], 0)
    vasti_length = inputs.length_m[0]
    assert joints.on_joint_states(["hip_flexion"], [0.4], [1.0], 10 * MS) == []
    np.testing.assert_array_equal(inputs.length_time_ns[:2], [0, 10 * MS])  # vasti untouched
    assert inputs.length_m[0] == vasti_length
    # the held knee moved on by its velocity (0.5 rad/s for 10 ms), as vasti's length does
    np.testing.assert_allclose(inputs.length_m[1], reference_lengths([0.4, 1.005, 0.0])[1])
    np.testing.assert_allclose(joints.sample.q, [0.4, 1.005, 0.0])
    np.testing.assert_allclose(joints.sample.qdot, [1.0, 0.5, 0.0])  # the knee keeps its own
    before = inputs.length_time_ns.copy()
    assert joints.on_joint_states(["ankle_angle"], [0.3], [], 20 * MS) == []  # no driven path
    np.testing.assert_array_equal(inputs.length_time_ns, before)
    np.testing.assert_allclose(joints.sample.q, [0.41, 1.01, 0.3])


def test_muscles_sharing_a_joint_agree_after_a_partial_message(bank):
    """A message naming the hip only: rectus femoris (hip and knee) is evaluated at the knee
    where vasti's extrapolated length has it, not at the knee's last received angle; beyond
    extrapolation_max_s a held coordinate stops (velocity 0), as path lengths do."""
    joints, inputs = make(bank, extrapolation_max_s=0.05)
    joints.on_joint_states(["hip_flexion", "knee_angle", "ankle_angle"], [0.2, 1.0, 0.0],
                           [0.0, 2.0, 0.0], 0)
    joints.on_joint_states(["hip_flexion"], [0.2], [0.0], 10 * MS)
    knee = 1.0 + 2.0 * 0.010
    vasti_now = inputs.sample(10 * MS)[1][0]            # extrapolated by NodeInputs
    assert vasti_now == pytest.approx(reference_lengths([0.2, knee, 0.0])[0], abs=1e-6)
    assert inputs.length_m[1] == pytest.approx(reference_lengths([0.2, knee, 0.0])[1], abs=1e-12)
    joints.on_joint_states(["hip_flexion"], [0.2], [0.0], 80 * MS)   # knee held 80 ms > 50 ms
    np.testing.assert_allclose(joints.sample.q[1], 1.0 + 2.0 * 0.050)
    assert joints.sample.qdot[1] == 0.0


def test_unnamed_message_is_in_joints_order(bank):
    joints, inputs = make(bank, joints=["knee_angle", "hip_flexion"])
    assert joints.on_joint_states([], [1.0, 0.2], [], 0) == []
    np.testing.assert_allclose(inputs.length_m[:2], reference_lengths([0.2, 1.0, 0.0]))
    assert kinds(joints.on_joint_states([], [1.0, 0.2, 0.0], [], 0)) == ["joint_wrong_size"]


@pytest.mark.parametrize(
    ("names", "position", "velocity", "expected"),
    [
        (["hip_flexion", "knee_angle"], [0.1], [], ["joint_wrong_size"]),
        (["hip_flexion", "knee_angle"], [0.1, 0.2], [0.0], ["joint_wrong_size"]),
        (["hip_flexion", "knee_angle"], [np.nan, 0.2], [], ["joint_non_finite"]),
        (["hip_flexion", "knee_angle"], [0.1, 0.2], [0.0, np.inf], ["joint_non_finite"]),
        (["hip_flexion", "hip_flexion"], [0.1, 0.2], [], ["joint_duplicate_name"]),
        (["wheel", "hip_flexion", "hip_flexion"], [0, 0.1, 0.2], [],
         ["joint_unknown_name", "joint_duplicate_name"]),
        (["hip_flexion", "knee_angle"], [0.1, 0.2], [0.0, 1e9], ["non_physical_velocity"]),
    ],
)
def test_bad_joint_states_are_dropped_whole(bank, names, position, velocity, expected):
    joints, inputs = make(bank)
    good = ["hip_flexion", "knee_angle", "ankle_angle"], [0.3, 0.6, 0.0]
    assert joints.on_joint_states(*good, [], 0) == []
    lengths, sample = inputs.length_m.copy(), joints.sample
    assert kinds(joints.on_joint_states(names, position, velocity, MS)) == expected
    np.testing.assert_array_equal(inputs.length_m, lengths)  # nothing stored
    np.testing.assert_array_equal(inputs.length_time_ns[:2], [0, 0])
    assert joints.sample is sample and joints.q.tolist() == [0.3, 0.6, 0.0]


def test_unknown_joints_are_ignored_and_counted_per_entry(bank):
    joints, inputs = make(bank)
    names = ["finger_1", "hip_flexion", "knee_angle", "ankle_angle", "wheel", "finger_1"]
    issues = joints.on_joint_states(names, [9.0, 0.2, 1.0, 0.0, 9.0, 9.0], [], 0)
    assert [(i.kind, i.count) for i in issues] == [("joint_unknown_name", 3)]
    assert "'finger_1', 'wheel'" in issues[0].text
    assert joints.ready
    np.testing.assert_allclose(inputs.length_m[:2], reference_lengths([0.2, 1.0, 0.0]))


def test_coordinates_outside_the_box_are_clamped_and_counted(bank):
    joints, inputs = make(bank, joint_map="{knee: {coordinate: knee_angle, sign: -1}}")
    issues = joints.on_joint_states(["hip_flexion", "knee", "ankle_angle"], [3.0, -2.5, 0.0],
                                    [1.0, -4.0, 0.5], 0)
    assert [(i.kind, i.count) for i in issues] == [("joint_clamped", 2)]
    assert "knee 2.5" not in issues[0].text and "knee -2.5 -> -2" in issues[0].text
    np.testing.assert_array_equal(joints.sample.q, [1.5, 2.0, 0.0])
    np.testing.assert_array_equal(joints.sample.qdot, [0.0, 0.0, 0.5])  # clamped: velocity 0
    np.testing.assert_allclose(inputs.length_m[:2], reference_lengths([1.5, 2.0, 0.0]))
    np.testing.assert_array_equal(inputs.velocity_m_per_s[:2], [0.0, 0.0])


def test_non_physical_geometry_length_drops_the_message(bank):
    joints, inputs = make(bank, path_length_margin_l0=0.0)
    # rectus femoris at hip -0.5, knee 2: 0.52 + 0.02 + 0.005 - 0.002 = 0.543 (< 0.54385, kept);
    # shrink the accepted range (the library's and the geometry's own) so that it is rejected
    inputs.limits = InputLimits(inputs.limits.path_length_min_m,
                                np.array([0.34, 0.54, 0.34]), 10.0, 10 ** 9, 5 * 10 ** 7,
                                "hold")
    inputs.allow_path_range(np.array([0, 1]), np.array([0.28, 0.5]), np.array([0.34, 0.54]))
    issues = joints.on_joint_states(["hip_flexion", "knee_angle", "ankle_angle"],
                                    [-0.5, 2.0, 0.0], [], 0)
    assert kinds(issues) == ["non_physical_length"] and "joint_states" in issues[0].text
    assert not joints.ready and not inputs.length_seen.any()
    assert joints.on_joint_states(["hip_flexion", "knee_angle", "ankle_angle"],
                                  [0.0, 1.0, 0.0], [], MS) == []
    assert joints.ready


def test_muscle_kinematics_for_joint_driven_muscles_is_ignored_and_counted(bank):
    joints, inputs = make(bank)
    joints.on_joint_states(["hip_flexion", "knee_angle", "ankle_angle"], [0.2, 1.0, 0.0], [], 0)
    from_joints = inputs.length_m[:2].copy()
    issues = inputs.on_kinematics(["vasti", "soleus", "rectus_femoris"], [0.3, 0.32, 0.5], [],
                                  MS)
    assert [(i.kind, i.count) for i in issues] == [("joint_driven_kinematics", 2)]
    np.testing.assert_array_equal(inputs.length_m[:2], from_joints)
    assert inputs.length_m[2] == 0.32 and inputs.ready
    issues = inputs.on_kinematics([], [0.3, 0.5, 0.31], [], 2 * MS)  # positional: same rule
    assert kinds(issues) == ["joint_driven_kinematics"] and inputs.length_m[2] == 0.31
    issues = inputs.on_kinematics(["vasti"], [0.3], [], 3 * MS)
    assert kinds(issues) == ["joint_driven_kinematics"] and inputs.last_kinematics_ns == 2 * MS


def test_initial_lengths_of_joint_driven_muscles_are_not_used(bank):
    space = make(bank)[0].space
    config = NodeConfig.from_values({"muscles": list(MUSCLES)})
    inputs = NodeInputs(bank.names, InputLimits.for_bank(bank, config), [0.3, 0.52, 0.32],
                        joint_driven=space.driven)
    assert np.isnan(inputs.length_m[:2]).all() and inputs.length_m[2] == 0.32
    assert not inputs.ready


# --- torques ------------------------------------------------------------------------------------


@pytest.mark.parametrize("joint_map", [
    "", "{hip: {coordinate: hip_flexion, sign: -1, offset: 0.2}, "
        "knee: {coordinate: knee_angle, sign: -1, offset: -0.1}, ankle: ankle_angle}"])
def test_joint_power_equals_muscle_power(bank, joint_map):
    """sum(tau_robot * qdot_robot) = -sum(F * Ldot) over the joint-driven muscles, in the robot's
    convention, including clamped poses (velocity 0 there on both sides)."""
    joints, inputs = make(bank, joint_map=joint_map)
    robot = joints.space.map.robot_names
    rng = np.random.default_rng(3)
    for k in range(50):
        q = rng.uniform(-1.0, 2.5, 3)
        qdot = rng.normal(scale=2.0, size=3)
        assert kinds(joints.on_joint_states(robot, q, qdot, k * MS)) in ([], ["joint_clamped"])
        force = rng.uniform(0.0, 3000.0, 3)
        efforts = joints.efforts(joints.sample, force)
        assert efforts.names == robot
        joint_power = float(np.sum(efforts.effort * efforts.velocity))
        muscle_power = -float(np.sum(force[:2] * inputs.velocity_m_per_s[:2]))
        assert joint_power == pytest.approx(muscle_power, rel=1e-9, abs=1e-9 * np.abs(
            force[:2] * inputs.velocity_m_per_s[:2]).sum())


def test_torque_signs_and_offsets_in_the_robot_convention(bank):
    """The knee extensors (vasti, rectus femoris: r = -dL/dq < 0 in the model's flexion-positive
    knee) give a negative model knee torque; a robot whose knee is extension-positive (sign -1)
    sees it positive. Robot positions are given back as sent."""
    plain, _ = make(bank)
    flipped, _ = make(bank, joint_map="{knee: {coordinate: knee_angle, sign: -1, offset: 0.5}}")
    plain.on_joint_states(["hip_flexion", "knee_angle", "ankle_angle"], [0.2, 1.0, 0.0],
                          [0.0, 0.3, 0.0], 0)
    flipped.on_joint_states(["hip_flexion", "knee", "ankle_angle"], [0.2, -0.5, 0.0],
                            [0.0, -0.3, 0.0], 0)  # the same model pose: q = -(-0.5) + 0.5
    force = np.array([2000.0, 500.0, 800.0])
    a, b = plain.efforts(plain.sample, force), flipped.efforts(flipped.sample, force)
    vasti_r = -(0.022 + 0.002 * 1.0)
    rf_r = -(0.01 + 0.002 * 0.2)
    assert a.effort[1] == pytest.approx(2000.0 * vasti_r + 500.0 * rf_r, rel=1e-12)
    assert a.effort[1] < 0 and b.effort[1] == pytest.approx(-a.effort[1], rel=1e-12)
    assert a.effort[0] == pytest.approx(b.effort[0], rel=1e-12)
    assert a.effort[2] == 0.0  # no driven path crosses the ankle; soleus is muscle space only
    np.testing.assert_allclose(b.position, [0.2, -0.5, 0.0], rtol=1e-15)
    np.testing.assert_allclose(b.velocity, [0.0, -0.3, 0.0], rtol=1e-15)
    assert b.names == ("hip_flexion", "knee", "ankle_angle")


def test_joint_driven_paths_are_accepted_over_the_geometrys_whole_range(bank):
    """An importer that clips Lmax into 1.1-1.4 writes a library maximum shorter than the
    geometry's longest path; poses inside the box must still be accepted (the geometry's own
    length range widens the library's for joint-driven muscles), with the same range in every
    process (fixed poses)."""
    from vm_ros.node.joint_inputs import geometry_length_range

    long_vasti = PolynomialGeometry(
        [Coordinate("knee_angle", "rad", 0.0, 2.0)],
        [MusclePath("vasti", ("knee_angle",), (0.0,), (1.0,), [[0], [1]], [0.29, 0.2])])
    space = JointSpace(long_vasti, JointMap.build("", long_vasti, PARAMS_SOURCE), MUSCLES, (),
                       PARAMS_SOURCE)
    config = NodeConfig.from_values({"muscles": list(MUSCLES)})
    inputs = NodeInputs(bank.names, InputLimits.for_bank(bank, config), joint_driven=space.driven)
    library_max = inputs.limits.path_length_max_m[0]
    assert library_max < 0.69   # the library (plus its margin) alone would reject knee 2.0
    joints = JointInputs(space, inputs)
    assert joints.on_joint_states(["knee_angle"], [2.0], [0.0], 0) == []
    assert inputs.length_m[0] == pytest.approx(0.29 + 0.2 * 2.0)
    lo, hi = geometry_length_range(long_vasti, [0])
    assert lo[0] <= 0.29 and hi[0] >= 0.69
    np.testing.assert_array_equal(geometry_length_range(long_vasti, [0]), (lo, hi))
