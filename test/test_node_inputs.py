"""muscle_node's input conditioning (vm_ros.node.inputs): every bad input has its behaviour, and
no message sequence can hand the model a bad input (no ROS needed)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vm_ros.model import MuscleBank
from vm_ros.node.inputs import InputLimits, NodeInputs, physical_path_length_range
from vm_ros.node.params import NodeConfig

MUSCLES = ("vasti", "rectus_femoris")
MS = 1_000_000


@pytest.fixture(scope="module")
def bank():
    return MuscleBank.from_config(list(MUSCLES))


def make_inputs(bank, **params):
    config = NodeConfig.from_values({"muscles": list(MUSCLES), **params})
    return NodeInputs(bank.names, InputLimits.for_bank(bank, config))


def mid_lengths(bank):
    lo, hi = physical_path_length_range(bank, 0.0)
    return 0.5 * (lo + hi)


def kinds(issues):
    return [i.kind for i in issues]


def test_physical_range_contains_the_library_range_and_is_positive(bank):
    lo, hi = physical_path_length_range(bank, 0.5)
    for spec, low, high in zip(bank.specs, lo, hi, strict=True):
        assert 0 < low < spec.path_length_min_m < spec.path_length_max_m < high


def test_excitation_by_name_keeps_missing_muscles(bank):
    inputs = make_inputs(bank, stale_input_policy="hold")
    assert inputs.on_excitation(["vasti", "rectus_femoris"], [0.2, 0.4], 0) == []
    assert inputs.on_excitation(["rectus_femoris"], [0.9], MS) == []
    np.testing.assert_array_equal(inputs.drive, [0.2, 0.9])


def test_excitation_without_names_is_positional(bank):
    inputs = make_inputs(bank)
    assert inputs.on_excitation([], [0.3, 0.6], 0) == []
    np.testing.assert_array_equal(inputs.drive, [0.3, 0.6])
    assert kinds(inputs.on_excitation([], [0.3], 0)) == ["wrong_size"]


@pytest.mark.parametrize(
    ("names", "values", "expected", "drive"),
    [
        (["vasti"], [0.5, 0.1], ["wrong_size"], [0.1, 0.1]),
        (["vasti", "biceps"], [0.5, 0.7], ["unknown_name"], [0.5, 0.1]),
        (["nobody"], [0.5], ["unknown_name"], [0.1, 0.1]),
        (["vasti", "vasti"], [0.5, 0.7], ["duplicate_name"], [0.1, 0.1]),
        (["vasti"], [float("nan")], ["non_finite"], [0.1, 0.1]),
        (["vasti"], [float("inf")], ["non_finite"], [0.1, 0.1]),
        (["vasti", "nobody"], [float("nan"), 0.5], ["unknown_name", "non_finite"], [0.1, 0.1]),
        (["vasti"], [7.0], ["drive_clipped"], [1.0, 0.1]),
        (["vasti"], [-1e300], ["drive_clipped"], [0.0, 0.1]),
    ],
)
def test_bad_excitation(bank, names, values, expected, drive):
    inputs = make_inputs(bank)
    inputs.on_excitation(MUSCLES, [0.1, 0.1], 0)
    assert kinds(inputs.on_excitation(names, values, MS)) == expected
    np.testing.assert_array_equal(inputs.drive, drive)


def test_unknown_names_are_counted_per_name(bank):
    issues = make_inputs(bank).on_excitation(["a", "b", "vasti"], [0.1, 0.2, 0.3], 0)
    assert [(i.kind, i.count) for i in issues] == [("unknown_name", 2)]


def test_every_muscle_in_order_and_an_unknown_name_stores_the_known_ones(bank):
    """The muscles in order, then names the node does not have (as a message with every muscle
    in order and nothing else, which takes a shorter path, must not): the unknown names counted,
    the known entries stored, the others' values (even a NaN) ignored."""
    inputs = make_inputs(bank, stale_input_policy="hold")
    names = (*MUSCLES, "knee")
    for _ in range(2):  # the second time from the remembered selection
        issues = inputs.on_excitation(names, [0.2, 0.4, np.nan], 0)
        assert [(i.kind, i.count) for i in issues] == [("unknown_name", 1)]
        np.testing.assert_array_equal(inputs.drive, [0.2, 0.4])
        lengths = mid_lengths(bank)
        issues = inputs.on_kinematics(names, [*lengths, np.nan], [0.01, 0.02, np.inf], 0)
        assert kinds(issues) == ["unknown_name"]
        np.testing.assert_array_equal(inputs.length_m, lengths)
        np.testing.assert_array_equal(inputs.velocity_m_per_s, [0.01, 0.02])


def test_excitation_array(bank):
    inputs = make_inputs(bank)
    assert inputs.on_excitation_array([0.2, 0.3], 0) == []
    assert kinds(inputs.on_excitation_array([0.2, 0.3, 0.4], 0)) == ["wrong_size"]
    assert kinds(inputs.on_excitation_array([], 0)) == ["wrong_size"]
    assert kinds(inputs.on_excitation_array([np.nan, 0.3], 0)) == ["non_finite"]
    np.testing.assert_array_equal(inputs.drive, [0.2, 0.3])


@pytest.mark.parametrize(
    ("scale", "velocity", "expected"),
    [
        (1.0, [0.0, 0.0], []),
        (1.0, [], []),
        (1000.0, [0.0, 0.0], ["non_physical_length"]),  # mm sent as m
        (0.01, [0.0, 0.0], ["non_physical_length"]),
        (-1.0, [0.0, 0.0], ["non_physical_length"]),
        (1.0, [0.0, 500.0], ["non_physical_velocity"]),  # mm/s sent as m/s
        (1.0, [0.0], ["wrong_size"]),
        (1.0, [np.nan, 0.0], ["non_finite"]),
        (np.inf, [0.0, 0.0], ["non_finite"]),
    ],
)
def test_kinematics(bank, scale, velocity, expected):
    inputs = make_inputs(bank)
    lengths = mid_lengths(bank) * scale
    assert kinds(inputs.on_kinematics(MUSCLES, lengths, velocity, 0)) == expected
    assert inputs.ready == (expected == [])


def test_kinematics_by_name_waits_for_every_muscle(bank):
    inputs = make_inputs(bank)
    lengths = mid_lengths(bank)
    assert inputs.on_kinematics(["vasti"], lengths[:1], [], 0) == []
    assert not inputs.ready
    assert inputs.on_kinematics(["rectus_femoris"], lengths[1:], [], MS) == []
    assert inputs.ready


def test_extrapolation_is_bounded_and_clamped(bank):
    inputs = make_inputs(bank, extrapolation_max_s=0.02)
    lengths, velocity = mid_lengths(bank), np.array([0.1, -0.2])
    inputs.on_kinematics(MUSCLES, lengths, velocity, 0)
    _, lp, vp = inputs.sample(10 * MS)
    np.testing.assert_allclose(lp, lengths + 0.01 * velocity)
    np.testing.assert_array_equal(vp, velocity)
    _, lp, vp = inputs.sample(500 * MS)  # past the horizon: held, velocity 0
    np.testing.assert_allclose(lp, lengths + 0.02 * velocity)
    np.testing.assert_array_equal(vp, [0.0, 0.0])
    wide = make_inputs(bank, extrapolation_max_s=5.0, input_timeout_s=10.0)
    wide.on_kinematics(MUSCLES, lengths, [5.0, -5.0], 0)
    _, lp, vp = wide.sample(4_000 * MS)  # would leave the physical range: clamped, velocity 0
    lo, hi = wide.limits.path_length_min_m, wide.limits.path_length_max_m
    np.testing.assert_array_equal(lp, [hi[0], lo[1]])
    np.testing.assert_array_equal(vp, [0.0, 0.0])


def test_sample_before_and_at_receipt_uses_the_sample(bank):
    inputs = make_inputs(bank)
    lengths = mid_lengths(bank)
    inputs.on_kinematics(MUSCLES, lengths, [0.1, 0.1], 50 * MS)
    _, lp, _ = inputs.sample(40 * MS)
    np.testing.assert_array_equal(lp, lengths)


@pytest.mark.parametrize(("policy", "stale_drive"), [("hold", 0.7), ("zero_drive", 0.0),
                                                     ("pause", 0.7)])
def test_stale_policies(bank, policy, stale_drive):
    inputs = make_inputs(bank, stale_input_policy=policy, input_timeout_s=0.1)
    inputs.on_kinematics(MUSCLES, mid_lengths(bank), [], 0)
    inputs.on_excitation(MUSCLES, [0.7, 0.7], 0)
    assert inputs.update_staleness(50 * MS) == []
    assert not inputs.any_stale
    u, _, _ = inputs.sample(50 * MS)
    np.testing.assert_array_equal(u, [0.7, 0.7])
    issues = inputs.update_staleness(200 * MS)
    assert sorted(kinds(issues)) == ["stale_excitation", "stale_kinematics"]
    assert inputs.any_stale
    assert inputs.update_staleness(300 * MS) == []  # reported once per fresh -> stale
    u, _, _ = inputs.sample(200 * MS)
    np.testing.assert_array_equal(u, [stale_drive] * 2)
    inputs.on_excitation(MUSCLES, [0.7, 0.7], 300 * MS)
    inputs.on_kinematics(MUSCLES, mid_lengths(bank), [], 300 * MS)
    assert inputs.update_staleness(310 * MS) == [] and not inputs.any_stale


def test_never_received_excitation_is_zero_drive(bank):
    inputs = make_inputs(bank, stale_input_policy="hold")
    u, _, _ = inputs.sample(0)
    np.testing.assert_array_equal(u, [0.0, 0.0])


def test_rebase_after_time_went_backwards(bank):
    inputs = make_inputs(bank, input_timeout_s=0.1)
    inputs.on_excitation(MUSCLES, [0.5, 0.5], 10_000 * MS)
    inputs.rebase(1_000 * MS)
    assert inputs.update_staleness(1_050 * MS) == []
    assert inputs.ages_s(1_050 * MS)["excitation"] == pytest.approx(0.05)
    assert inputs.ages_s(1_050 * MS)["kinematics"] is None


# --- no message sequence reaches the model as a bad input ----------------------------------------

names_strategy = st.lists(st.sampled_from([*MUSCLES, "soleus", "", "x" * 300, "vasti "]),
                          max_size=4)
values_strategy = st.lists(st.floats(allow_nan=True, allow_infinity=True, width=64)
                           | st.sampled_from([0.0, 0.3, 1.0, 0.3, 0.45, 1e308]), max_size=4)
message_strategy = st.tuples(st.sampled_from(["excitation", "array", "kinematics"]),
                             names_strategy, values_strategy, values_strategy,
                             st.integers(min_value=0, max_value=2_000 * MS))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(messages=st.lists(message_strategy, max_size=12))
def test_any_message_sequence_gives_valid_model_inputs(bank, messages):
    inputs = make_inputs(bank, extrapolation_max_s=0.05)
    inputs.on_kinematics(MUSCLES, mid_lengths(bank), [], 0)
    lo, hi = inputs.limits.path_length_min_m, inputs.limits.path_length_max_m
    for topic, names, values, velocity, t in sorted(messages, key=lambda m: m[-1]):
        if topic == "excitation":
            issues = inputs.on_excitation(names, values, t)
        elif topic == "array":
            issues = inputs.on_excitation_array(values, t)
        else:
            issues = inputs.on_kinematics(names, values, velocity, t)
        assert all(i.count >= 1 for i in issues)
        inputs.update_staleness(t)
        u, lp, vp = inputs.sample(t + 3 * MS)
        assert np.all((u >= 0) & (u <= 1))
        assert np.all(np.isfinite(lp)) and np.all((lp >= lo) & (lp <= hi))
        assert np.all(np.isfinite(vp))
        assert np.all(np.abs(vp) <= inputs.limits.path_speed_max_m_per_s)


def test_hostile_inputs_keep_the_model_finite(bank):
    """The extremes the conditioning lets through (full drive, range edges, top speed)."""
    inputs = make_inputs(bank)
    lo, hi = inputs.limits.path_length_min_m, inputs.limits.path_length_max_m
    bank.reset(path_length=mid_lengths(bank))
    vmax = inputs.limits.path_speed_max_m_per_s
    for k, (lp, vp, u) in enumerate([(lo, -vmax, 1.0), (hi, vmax, 1.0), (lo, vmax, 0.0),
                                     (hi, -vmax, 1.0)] * 25):
        inputs.on_kinematics(MUSCLES, lp, [vp, vp], k * MS)
        inputs.on_excitation_array([u, u], k * MS)
        out = bank.step(1e-3, *inputs.sample(k * MS))
        assert np.all(np.isfinite(out.force)) and np.isfinite(out.total_energy_rate)


def test_initial_length_holds_without_kinematics(bank):
    """initial_path_length_m and no kinematics topic: not stale (it was WARN 'stale inputs'
    forever); once kinematics arrived, their age counts as before."""
    config = NodeConfig.from_values({"muscles": list(MUSCLES), "input_timeout_s": 0.1})
    inputs = NodeInputs(bank.names, InputLimits.for_bank(bank, config), mid_lengths(bank))
    inputs.on_excitation_array([0.2, 0.2], 0)
    assert inputs.update_staleness(50 * MS) == [] and not inputs.any_stale
    assert not inputs.length_stale.any()
    inputs.on_excitation_array([0.2, 0.2], 1000 * MS)
    assert not inputs.update_staleness(1000 * MS) and not inputs.any_stale  # still holding
    inputs.on_kinematics(list(MUSCLES), mid_lengths(bank), [], 1000 * MS)
    issues = inputs.update_staleness(1200 * MS)
    assert kinds(issues) == ["stale_excitation", "stale_kinematics"]
    assert inputs.length_stale.all()


@pytest.mark.parametrize(("policy", "excitation", "kinematics"), [
    ("hold", "last drive held", "length held, velocity 0"),
    ("zero_drive", "drive 0", "length held, velocity 0"),
    ("pause", "model paused", "model paused")])
def test_stale_reports_say_what_the_policy_does(bank, policy, excitation, kinematics):
    inputs = make_inputs(bank, stale_input_policy=policy, input_timeout_s=0.1)
    inputs.on_excitation_array([0.2, 0.2], 0)
    inputs.on_kinematics(list(MUSCLES), mid_lengths(bank), [], 0)
    assert inputs.update_staleness(10 * MS) == []
    issues = {i.kind: i for i in inputs.update_staleness(500 * MS)}
    assert excitation in issues["stale_excitation"].behaviour
    assert kinematics in issues["stale_kinematics"].behaviour
    assert f"stale_input_policy {policy}" in issues["stale_kinematics"].behaviour


# --- every input check of the model, from every input path ---------------------------------------
# MuscleBank.check_inputs (and the compiled kernel, which checks the same) raises on: a drive
# that is not finite, a path length that is not finite or <= 0 m, a path velocity that is not
# finite. The node's input paths: excitation, excitation_array, muscle_kinematics, joint_states.
MODEL_CHECKS = ("drive finite", "length finite", "length > 0", "velocity finite")
JOINT_MUSCLES = ("vasti", "rectus_femoris", "soleus")  # soleus: from muscle_kinematics
HIP_KNEE_ANKLE = ["hip_flexion", "knee_angle", "ankle_angle"]


def dipping_geometry():
    """The small leg geometry (test_joint_space) with vasti over hip and knee, x = q - (0.5, 1):

        vasti  L = 0.11 + 0.1 x_knee - 0.015 (x_hip x_knee)^20

    0.01-0.21 m at the poses the loader samples (it loads), so the node's widened range
    (geometry_length_range) starts at 0.01 - 0.1 x 0.2 = -0.01 m; but at the unsampled corners
    (hip 1.5, knee 0) and (hip -0.5, knee 0) L = 0.11 - 0.1 - 0.015 = -0.005 m."""
    from test_joint_space import small_geometry

    from vm_ros.geometry import MusclePath, PolynomialGeometry

    leg = small_geometry()
    vasti = MusclePath("vasti", ("hip_flexion", "knee_angle"), (0.5, 1.0), (1.0, 1.0),
                       [[0, 0], [0, 1], [20, 20]], [0.11, 0.1, -0.015])
    return PolynomialGeometry(leg.coordinates, [vasti, *leg.muscles[1:]], leg.coupled)


@pytest.fixture(scope="module")
def joint_bank():
    return MuscleBank.from_config(list(JOINT_MUSCLES))


def joint_inputs(bank, geometry, joint_map=""):
    """(JointInputs, NodeInputs) for ``geometry``, the node's default limits and input times
    that never go stale."""
    from vm_ros.joint_space import JointMap, JointSpace
    from vm_ros.node.joint_inputs import JointInputs

    space = JointSpace(geometry, JointMap.build(joint_map, geometry, "test"), JOINT_MUSCLES, (),
                       "test")
    config = NodeConfig.from_values({"muscles": list(JOINT_MUSCLES), "input_timeout_s": 1000.0})
    inputs = NodeInputs(bank.names, InputLimits.for_bank(bank, config), joint_driven=space.driven)
    return JointInputs(space, inputs), inputs


def test_the_dipping_geometry_loads_and_its_widened_range_reaches_below_zero(tmp_path):
    """The premise of the tests below: the loader's check passes it and, without the node's
    1 mm floor, a joint_states message at the corner would be accepted."""
    from vm_ros.geometry import load_geometry, write_geometry
    from vm_ros.node.joint_inputs import geometry_length_range

    geometry = load_geometry(write_geometry(dipping_geometry(), tmp_path / "dip.yaml"))
    lo, _ = geometry_length_range(geometry, [0])
    assert lo[0] == pytest.approx(-0.01)
    assert geometry.evaluate([1.5, 0.0, 0.0]).length_m[0] == pytest.approx(-0.005)


def model_check_cases(bank):
    """(input path, model check it would break if passed on, message sender, issue kinds)."""
    lengths = mid_lengths(bank)
    soleus = float(lengths[2])
    nan, inf = float("nan"), float("inf")

    def kinematics(length, velocity=()):
        return lambda j, i, t: i.on_kinematics(["soleus"], [length], list(velocity), t)

    def joints(position, velocity=(), names=HIP_KNEE_ANKLE):
        return lambda j, i, t: j.on_joint_states(names, position, list(velocity), t)

    return [
        ("excitation", "drive finite",
         lambda j, i, t: i.on_excitation(["vasti"], [nan], t), ["non_finite"]),
        ("excitation", "drive finite",
         lambda j, i, t: i.on_excitation([], [0.5, inf, 0.5], t), ["non_finite"]),
        ("excitation_array", "drive finite",
         lambda j, i, t: i.on_excitation_array([0.5, 0.5, -inf], t), ["non_finite"]),
        ("muscle_kinematics", "length finite", kinematics(nan), ["non_finite"]),
        ("muscle_kinematics", "length finite", kinematics(inf), ["non_finite"]),
        ("muscle_kinematics", "length > 0", kinematics(0.0), ["non_physical_length"]),
        ("muscle_kinematics", "length > 0", kinematics(-soleus), ["non_physical_length"]),
        ("muscle_kinematics", "length > 0", kinematics(1e-300), ["non_physical_length"]),
        ("muscle_kinematics", "velocity finite", kinematics(soleus, [nan]), ["non_finite"]),
        ("muscle_kinematics", "velocity finite", kinematics(soleus, [1e308]),
         ["non_physical_velocity"]),  # would overflow when extrapolated
        ("joint_states", "length finite", joints([0.5, nan, 0.0]), ["joint_non_finite"]),
        ("joint_states", "velocity finite", joints([0.5, 1.0, 0.0], [0.0, -inf, 0.0]),
         ["joint_non_finite"]),
        ("joint_states", "length > 0", joints([1.5, 0.0, 0.0]), ["non_physical_length"]),
        ("joint_states", "length > 0", joints([-0.5, 0.0, 0.0]), ["non_physical_length"]),
        ("joint_states", "length > 0", joints([9.0, -3.0, 0.0]),  # clamped to the corner
         ["joint_clamped", "non_physical_length"]),
        # a coordinate past 1.8e308 once moved on by its velocity (the knee, when a later
        # message names the hip only)
        ("joint_states", "length finite", joints([1.79e308], [1.79e308], ["knee_angle"]),
         ["joint_clamped"]),
        ("joint_states", "length finite", joints([0.5], [], ["hip_flexion"]),
         ["joint_non_finite"]),
    ]


def test_no_input_path_can_hand_the_model_an_input_it_refuses(joint_bank):
    """Every check of the model, from every input path that can reach it: the message is
    dropped and reported as its issue kind, nothing is stored, and what the next model steps get
    passes the model's checks (MuscleBank.check_inputs and a compiled run)."""
    bank = joint_bank
    joints, inputs = joint_inputs(bank, dipping_geometry())
    t = 0
    assert joints.on_joint_states(HIP_KNEE_ANKLE, [0.5, 2.0, 0.0], [], t) == []
    assert inputs.on_kinematics(["soleus"], [mid_lengths(bank)[2]], [], t) == []
    assert inputs.on_excitation_array([0.5, 0.5, 0.5], t) == []
    bank.reset(inputs.sample(t)[1])
    cases = model_check_cases(bank)
    assert {(path, check) for path, check, _, _ in cases} == {
        ("excitation", "drive finite"), ("excitation_array", "drive finite"),
        *(("muscle_kinematics", c) for c in MODEL_CHECKS[1:]),
        *(("joint_states", c) for c in MODEL_CHECKS[1:])}
    for path, check, send, expected in cases:
        t += 10 * MS
        stored = (inputs.drive.copy(), inputs.length_m.copy(), inputs.velocity_m_per_s.copy())
        issues = send(joints, inputs, t)
        assert kinds(issues) == expected, (path, check, issues)
        assert all(i.count >= 1 for i in issues)
        if expected != ["joint_clamped"]:  # the first half of the overflow case is used
            for before, now in zip(stored, (inputs.drive, inputs.length_m,
                                            inputs.velocity_m_per_s), strict=True):
                np.testing.assert_array_equal(now, before, err_msg=f"{path}: {check}")
        u, lp, vp = inputs.sample_many(t + np.arange(0, 100 * MS, MS))
        for row in range(len(u)):
            bank.check_inputs(u[row], lp[row], vp[row])
        bank.run(1e-3, u, lp, vp)


def test_the_path_lengths_accepted_never_reach_zero(bank):
    """A widened range that reaches 0 m (allow_path_range) is floored at the loader's 1 mm:
    a muscle_kinematics length of 0.5 mm is refused, 1 mm is taken, and extrapolation towards
    0 stops at 1 mm."""
    from vm_ros.geometry.checks import MIN_PATH_LENGTH_M

    inputs = make_inputs(bank)
    inputs.allow_path_range(np.array([0, 1]), np.array([-1.0, -1.0]), np.array([0.5, 0.6]))
    assert inputs.path_bounds()[0].tolist() == [MIN_PATH_LENGTH_M, MIN_PATH_LENGTH_M]
    assert kinds(inputs.on_kinematics(MUSCLES, [0.0005, 0.3], [], 0)) == ["non_physical_length"]
    assert inputs.on_kinematics(MUSCLES, [0.001, 0.3], [-10.0, 0.0], 0) == []
    _, lp, vp = inputs.sample(40 * MS)
    assert lp.tolist() == [0.001, 0.3] and vp.tolist() == [0.0, 0.0]


def test_an_offset_that_overflows_a_position_drops_the_message(joint_bank):
    joints, inputs = joint_inputs(joint_bank, dipping_geometry(),
                                  joint_map="{knee: {coordinate: knee_angle, offset: 1.0e+308}}")
    issues = joints.on_joint_states(["hip_flexion", "knee", "ankle_angle"], [0.5, 1e308, 0.0],
                                    [], 0)
    assert kinds(issues) == ["joint_non_finite"] and "overflow" in issues[0].text
    assert not joints.seen.any() and not inputs.length_seen.any()
    assert joints.on_joint_states(["hip_flexion", "knee", "ankle_angle"], [0.5, -1e308, 0.0],
                                  [], MS) == []   # knee 0 rad
    assert joints.ready and joints.sample.q.tolist() == [0.5, 0.0, 0.0]
