"""`vm-ros recompute` of a `vm-ros simulate --motion` log: the recorded joint_states go through the
same joint conditioning with the attached geometry, and every output is reproduced exactly."""

from __future__ import annotations

import numpy as np
import pytest
from test_simulate_joint_space import _run, simulate_leg

from vm_ros.recording.run_log import read_run

OUTPUTS = ("muscle_force", "energy_rate", "energy_rate_total", "energy_total", "joint_efforts",
           "joint_effort_commands", "muscle_telemetry")
INPUTS = ("excitation", "joint_states")


@pytest.fixture(scope="module")
def leg_log(tmp_path_factory):
    out, _ = simulate_leg(tmp_path_factory.mktemp("recompute-leg"), "--excitation", "0.3",
                          "--input-rate", "500", "--telemetry-rate", "50")
    return out


def test_recompute_reproduces_a_motion_run_exactly(leg_log, tmp_path):
    out = tmp_path / "again.mcap"
    printed = _run(["recompute", str(leg_log), "--out", str(out)])
    assert "exact: the recomputed outputs equal the recorded ones" in printed
    assert "joint effort vs recorded: max |difference| 0 " in printed
    assert "inputs: muscle_node conditioning" in printed
    original, again = read_run(leg_log), read_run(out)
    assert again.info.source == "recompute"
    assert again.attachments["geometry.yaml"] == original.attachments["geometry.yaml"]
    assert set(again.topic_types) == set(original.topic_types)
    for topic in OUTPUTS + INPUTS:
        first, second = original.get(topic), again.get(topic)
        np.testing.assert_array_equal(second.time_ns, first.time_ns, err_msg=topic)
        assert second.names == first.names
        assert set(second.fields) == set(first.fields)
        for key, value in first.fields.items():
            np.testing.assert_array_equal(second.fields[key], value, err_msg=f"{topic}.{key}")
    assert len(original.get("joint_efforts")) == 21


def test_changed_muscle_changes_the_torques_and_says_so(leg_log, tmp_path):
    out = tmp_path / "changed.mcap"
    printed = _run(["recompute", str(leg_log), "--out", str(out), "--override",
                    "vasti.mass_kg=1.0", "--telemetry-rate", "0"])
    assert "not exact" in printed
    original, changed = read_run(leg_log), read_run(out)
    knee, knee_changed = (r.get("joint_efforts").fields["effort"][:, 1] for r in
                          (original, changed))
    assert np.max(np.abs(knee_changed - knee)) > 0.1
    np.testing.assert_array_equal(changed.get("joint_states").fields["position"],
                                  original.get("joint_states").fields["position"])
