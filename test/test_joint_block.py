"""The array conditioning of a block of excitation and joint_states messages
(NodeConditioning.block, used by `vm-ros simulate --motion`) against muscle_node's message by
message conditioning (on_excitation, on_joint_states, sample at each step start): the same bits
step by step, the same joint samples, counts and state afterwards, on messages at irregular
times with coordinates clamped at the box (first and last frames included)."""

from __future__ import annotations

import numpy as np
import pytest
from test_joint_space import MUSCLES, small_geometry

from vm_ros.joint_space import JointMap, JointSpace
from vm_ros.model import MuscleBank
from vm_ros.node.params import PARAMS_SOURCE, NodeConfig
from vm_ros.node.replay import NodeConditioning

MS = 1_000_000
# robot knee = -(model knee) + 0.1: the block's to_model must give the node's bits
JOINT_MAP = "{knee: {coordinate: knee_angle, sign: -1, offset: 0.1}}"
JOINTS = ("hip_flexion", "knee", "ankle_angle")


@pytest.fixture(scope="module")
def bank():
    return MuscleBank.from_config(list(MUSCLES))


def conditioning(bank, backend: str) -> NodeConditioning:
    geometry = small_geometry(backend)
    space = JointSpace(geometry, JointMap.build(JOINT_MAP, geometry, PARAMS_SOURCE), MUSCLES,
                       (), PARAMS_SOURCE)
    # soleus is not in the geometry: an initial length makes the bank ready (the joint-driven
    # muscles' are not used)
    config = NodeConfig.from_values({"muscles": list(MUSCLES), "geometry": "small.yaml",
                                     "joint_map": JOINT_MAP,
                                     "initial_path_length_m": [0.3, 0.5, 0.33]})
    return NodeConditioning(bank, config, space)


def messages(seed: int = 3, count: int = 120):
    """Message times at irregular gaps (0.3 to 2.7 ms, to the ns) from 0; drives in [0, 1] with
    0 and 1 themselves; hip beyond the box's upper end (1.5) at the first and last frames and
    every 7th, the robot knee beyond the model knee's lower end (0) every 5th."""
    rng = np.random.default_rng(seed)
    times = np.concatenate([[0], np.cumsum(rng.integers(300_000, 2_700_000, count - 1))])
    drives = rng.uniform(0.0, 1.0, (count, len(MUSCLES)))
    drives[::4, 0], drives[1::4, 1] = 0.0, 1.0
    hip = rng.uniform(-0.4, 1.4, count)
    hip[::7] = 1.5 + rng.uniform(0.01, 0.5, len(hip[::7]))
    hip[-1] = 1.7
    knee = rng.uniform(-1.8, 0.0, count)  # robot: model knee 0.1 - knee in (0.1, 1.9)
    knee[::5] = 0.3                       # model knee -0.2: below the box
    ankle = rng.uniform(-0.6, 0.4, count)
    positions = np.stack([hip, knee, ankle], axis=1)
    velocities = rng.uniform(-2.0, 2.0, positions.shape)
    return times.astype(np.int64), drives, positions, velocities


def one_by_one(cond, times, drives, positions, velocities, steps):
    """muscle_node's way (MotionInputs.advance_to): before each step, the messages due, each
    excitation before its joint_states; then sample at the step start."""
    u, lp, vp, samples, done = [], [], [], [], 0
    for step in steps.tolist():
        while done < len(times) and times[done] <= step:
            cond.on_excitation(MUSCLES, drives[done], int(times[done]))
            cond.on_joint_states(JOINTS, positions[done], velocities[done], int(times[done]))
            done += 1
        for rows, value in zip((u, lp, vp), cond.sample(step), strict=True):
            rows.append(value)
        samples.append(cond.joints.sample)
    return np.array(u), np.array(lp), np.array(vp), samples


def assert_same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype
    assert a.tobytes() == b.tobytes()  # -0.0 and 0.0 told apart


def state(cond):
    joints, inputs = cond.joints, cond.inputs
    return (joints.q, joints.qdot, joints.seen, joints.q_time_ns, joints.last_message_ns,
            inputs.drive, inputs.drive_seen, inputs.drive_time_ns, inputs.length_m,
            inputs.velocity_m_per_s, inputs.length_seen, inputs.length_time_ns,
            inputs.last_excitation_ns, cond.clamped)


@pytest.mark.parametrize("backend", ["numpy", "compiled"])
def test_a_block_conditions_as_the_node_does_message_by_message(bank, backend):
    if backend == "compiled":
        pytest.importorskip("numba")
    times, drives, positions, velocities = messages()
    steps = np.arange(0, int(times[-1]) + 3 * MS, MS, dtype=np.int64)  # past the last frame
    reference, blocks = conditioning(bank, backend), conditioning(bank, backend)
    u, lp, vp, samples = one_by_one(reference, times, drives, positions, velocities, steps)
    # two blocks, the first from the very first message (no joint sample yet), split at a step
    split_step = len(steps) // 3
    split = np.searchsorted(times, steps[split_step], side="right")
    results = []
    for messages_at, steps_at in ((slice(0, split), slice(0, split_step)),
                                  (slice(split, None), slice(split_step, None))):
        result = blocks.block(MUSCLES, drives[messages_at], JOINTS, positions[messages_at],
                              velocities[messages_at], times[messages_at], steps[steps_at])
        assert result is not None  # the array path, not declined
        results.append(result)
    for got, expected in zip((np.concatenate([r[k] for r in results]) for k in range(3)),
                             (u, lp, vp), strict=True):
        assert_same_bits(got, expected)
    got_samples = [r[3].row(i) for r in results for i in range(len(r[3]))]
    assert len(got_samples) == len(samples)
    for got, expected in zip(got_samples, samples, strict=True):
        assert got.time_ns == expected.time_ns
        for field in ("q", "qdot", "moment_arm"):
            assert_same_bits(getattr(got, field), getattr(expected, field))
    for got, expected in zip(state(blocks), state(reference), strict=True):
        assert_same_bits(got, expected)
    assert blocks.issues == reference.issues
    assert blocks.issue_text() == reference.issue_text()
    # against the inputs themselves: hip clamped in every frame beyond 1.5, the knee in every
    # frame with robot 0.3 (model -0.2 below 0)
    hip_out = int((positions[:, 0] > 1.5).sum())
    knee_out = int((positions[:, 1] == 0.3).sum())
    assert blocks.clamped.tolist() == [hip_out, knee_out, 0]
    assert blocks.issues["joint_clamped"] == hip_out + knee_out


def test_a_block_with_a_message_the_node_would_drop_is_declined_untouched(bank):
    times, drives, positions, velocities = messages(count=20)
    steps = np.arange(0, int(times[-1]) + MS, MS, dtype=np.int64)
    cond = conditioning(bank, "numpy")
    before = [np.copy(a) if a is not None else None for a in state(cond)]
    bad = positions.copy()
    bad[10, 2] = np.inf  # dropped by the node: the block goes message by message
    assert cond.block(MUSCLES, drives, JOINTS, bad, velocities, times, steps) is None
    clipped = drives.copy()
    clipped[4, 1] = 1.5  # clipped by the node, with an issue
    assert cond.block(MUSCLES, clipped, JOINTS, positions, velocities, times, steps) is None
    for got, expected in zip(state(cond), before, strict=True):
        if expected is None:
            assert got is None
        else:
            assert_same_bits(got, expected)
    assert cond.joints.sample is None and not cond.issues
