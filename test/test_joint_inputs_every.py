"""JointInputs.on_joint_states takes a shorter way for a message that names every coordinate
with velocities after the first joint sample (a robot's usual stream: _on_every_coordinate).
Against the general way (the same JointInputs with the shorter way switched off), on a stream of
such messages mixed with ones that name some joints, have no velocities, name joints in another
order, hold NaN, inf or values that overflow with joint_map's offset, leave the box or give path
lengths the node refuses: the same issues and, bit for bit, the same joint samples and held
inputs after every message."""

from __future__ import annotations

import numpy as np
import pytest
from test_joint_block import JOINT_MAP, JOINTS, assert_same_bits
from test_joint_space import MUSCLES, small_geometry

from vm_ros.joint_space import JointMap, JointSpace
from vm_ros.model import MuscleBank
from vm_ros.node.joint_inputs import JointInputs
from vm_ros.node.params import PARAMS_SOURCE, NodeConfig
from vm_ros.node.replay import NodeConditioning


def conditioning(bank, backend: str, extrapolation_s: float) -> NodeConditioning:
    geometry = small_geometry(backend)
    space = JointSpace(geometry, JointMap.build(JOINT_MAP, geometry, PARAMS_SOURCE), MUSCLES,
                       (), PARAMS_SOURCE)
    config = NodeConfig.from_values({"muscles": list(MUSCLES), "geometry": "small.yaml",
                                     "joint_map": JOINT_MAP, "extrapolation_max_s": extrapolation_s,
                                     "initial_path_length_m": [0.3, 0.5, 0.33]})
    return NodeConditioning(bank, config, space)


def stream(seed: int = 5, count: int = 400):
    """(names, position, velocity, time_ns) messages: mostly every joint in JOINTS order, with
    the other kinds of message mixed in."""
    rng = np.random.default_rng(seed)
    out, t = [], 0
    for k in range(count):
        t += int(rng.integers(200_000, 3_000_000))
        position = np.array([rng.uniform(-0.6, 1.6), rng.uniform(-2.0, 0.1),
                             rng.uniform(-0.8, 0.6)])
        velocity = rng.uniform(-2.0, 2.0, 3)
        names = JOINTS
        kind = k % 23
        if kind == 3:
            names = ("ankle_angle", "hip_flexion", "knee")  # another order
            position, velocity = position[[2, 0, 1]], velocity[[2, 0, 1]]
        elif kind == 5:
            velocity = np.zeros(0)  # no velocities
        elif kind == 7:
            names, position, velocity = ("knee",), position[1:2], velocity[1:2]  # some joints
        elif kind == 11:
            position[int(rng.integers(3))] = np.nan
        elif kind == 13:
            velocity[int(rng.integers(3))] = -np.inf
        elif kind == 17:
            position[1] = -1.79e308  # model knee 1.79e308 + 0.1: finite, clamped
        elif kind == 19:
            position[0], velocity[0] = 1.0e308, 1.0e308  # q + q' * 0.0 is NaN
        elif kind == 21:
            velocity[2] = 1.0e308  # finite; the ankle crosses no path of the geometry
            velocity[1] = -1000.0  # the knee's paths faster than the node accepts
        out.append((names, position, velocity, t))
    return out


def state(joints: JointInputs, cond: NodeConditioning):
    inputs = cond.inputs
    sample = joints.sample
    return (joints.q, joints.qdot, joints.seen, joints.q_time_ns, joints.last_message_ns,
            *((sample.time_ns, sample.q, sample.qdot, sample.moment_arm) if sample else ()),
            inputs.length_m, inputs.velocity_m_per_s, inputs.length_seen, inputs.length_time_ns)


@pytest.mark.parametrize("backend", ["numpy", "compiled"])
@pytest.mark.parametrize("extrapolation_s", [0.0, 0.005])
def test_a_full_message_is_conditioned_as_the_general_way_does(backend, extrapolation_s,
                                                               monkeypatch):
    if backend == "compiled":
        pytest.importorskip("numba")
    bank = MuscleBank.from_config(list(MUSCLES))
    shorter = conditioning(bank, backend, extrapolation_s)
    general = conditioning(bank, backend, extrapolation_s)
    monkeypatch.setattr(general.joints, "_every_coordinate", lambda index, entries: None)
    taken, kinds = [], set()
    original = JointInputs._on_every_coordinate

    def counting(self, *args):
        result = original(self, *args)
        taken.append(result is not None)
        return result

    monkeypatch.setattr(JointInputs, "_on_every_coordinate", counting)
    for names, position, velocity, t in stream():
        got = shorter.joints.on_joint_states(names, position, velocity, t)
        expected = general.joints.on_joint_states(names, position, velocity, t)
        assert [(i.kind, i.text, i.count) for i in got] == \
            [(i.kind, i.text, i.count) for i in expected]
        kinds.update(i.kind for i in expected)
        for a, b in zip(state(shorter.joints, shorter), state(general.joints, general),
                        strict=True):
            assert_same_bits(a, b)
    # the shorter way was taken for most messages, and declined the ones that are not finite
    assert sum(taken) > 250 and not all(taken)
    assert {"joint_clamped", "joint_non_finite"} <= kinds
    # with extrapolation_max_s 0 the paths are evaluated at velocity 0: none is too fast
    assert ("non_physical_velocity" in kinds) == (extrapolation_s > 0)
