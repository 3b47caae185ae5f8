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
