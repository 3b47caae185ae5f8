"""`vm-ros report` of a joint-space log: joint torques beside forces and energy (CSV and PNG);
a muscle-space log gets none of the joint files."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from test_simulate_joint_space import _run, simulate_leg

from vm_ros.recording.run_log import read_run

JOINT_FILES = ("joint_efforts.csv", "joint_states.csv", "joint_summary.csv", "joint_torque.png")


@pytest.fixture(scope="module")
def leg_log(tmp_path_factory):
    out, _ = simulate_leg(tmp_path_factory.mktemp("report-leg"), "--excitation", "0.5",
                          "--telemetry-rate", "0")
    return out


def _table(path):
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    return rows[0], np.array(rows[1:], dtype=float)


def test_report_writes_joint_torques_beside_forces_and_energy(leg_log, tmp_path):
    out = tmp_path / "report"
    printed = _run(["report", str(leg_log), "--out", str(out)])
    for name in JOINT_FILES + ("force.png", "forces.csv", "energy_rate.csv", "totals.png",
                               "energy_partition.png", "summary.csv", "summary.png",
                               "energy_rate.png"):
        assert (out / name).is_file(), name
    run = read_run(leg_log)
    efforts = run.get("joint_efforts")
    header, data = _table(out / "joint_efforts.csv")
    assert header == ["time_s", "hip_flexion.position_rad", "knee_angle.position_rad",
                      "hip_flexion.velocity_rad_per_s", "knee_angle.velocity_rad_per_s",
                      "hip_flexion.effort_N_m", "knee_angle.effort_N_m"]
    np.testing.assert_allclose(data[:, 0], np.arange(21) * 0.01, atol=1e-12)
    np.testing.assert_array_equal(data[:, 5:], efforts.fields["effort"])
    header, data = _table(out / "joint_states.csv")
    assert header == ["time_s", "hip_flexion.position_rad", "knee_angle.position_rad"]
    assert len(data) == 200
    with open(out / "joint_summary.csv", newline="") as handle:
        summary = {row["joint"]: row for row in csv.DictReader(handle)}
    assert summary["knee_angle"]["clamped_samples"] == "17"
    assert summary["knee_angle"]["effort_unit"] == "N m"
    assert float(summary["knee_angle"]["mean_effort"]) == pytest.approx(
        efforts.fields["effort"][:, 1].mean(), rel=1e-12)
    assert "knee_angle" in printed


def test_muscle_space_report_has_no_joint_files(tmp_path):
    log = tmp_path / "ramp.mcap"
    _run(["simulate", "--scenario", "isometric_ramp", "--duration", "0.05", "--telemetry-rate",
          "0", "--out", str(log)])
    out = tmp_path / "report"
    _run(["report", str(log), "--out", str(out), "--no-plots"])
    assert (out / "forces.csv").is_file()
    assert not any((out / name).exists() for name in JOINT_FILES)
