"""`vm-ros bench --only joint` in its quickest form writes every item in the documented structure
(no timing assertions: the timings are benchmarks on shared machines, not tests), and says why
when the mujoco extra is missing."""

from __future__ import annotations

import csv
import json

import pytest
from conftest import require_ros

from vm_ros.cli import main
from vm_ros_bench import joint_bench

QUICKEST = ["bench", "--only", "joint", "--quick", "--repeats", "1", "--node-duration", "2"]


def _csv(out):
    return list(csv.DictReader((out / "bench.csv").read_text().splitlines()))


@pytest.mark.ros
@pytest.mark.slow
def test_joint_section_quickest_writes_every_item(tmp_path, capsys):
    require_ros()  # the node item runs muscle_node and the driver with rclpy
    if joint_bench.missing_extra():
        pytest.skip(joint_bench.missing_extra())
    out = tmp_path / "bench"
    assert main([*QUICKEST, "--out", str(out)]) == 0
    results = json.loads((out / "bench.json").read_text())
    assert results["sections"] == ["joint"]
    joint = results["joint"]

    imported = joint["import"]
    assert imported["model"] == "myolegs" and imported["options"] == joint_bench.IMPORTS["quick"]
    assert not imported["reused"]
    again = joint_bench.import_myolegs(out / "joint-cache" / "myolegs-quick", quick=True)
    assert again["reused"] and again["geometry"] == imported["geometry"]

    geometry = joint["geometry"]
    assert geometry["muscles"] == 80 and geometry["coordinates"] == 14
    calls = {(r["backend"], r["call"]): r for r in geometry["rows"]}
    assert set(calls) == {("compiled", "evaluate"), ("numpy", "evaluate"),
                          ("mujoco", "evaluate"), ("numpy", "generalized_forces")}
    for row in calls.values():
        if "skipped" not in row:  # compiled without Numba
            assert 0 < row["call_us_min"] <= row["call_us"] <= row["call_us_max"]
    assert geometry["length_max_diff_vs_mujoco_mm"] >= 0

    node = joint["node"]
    assert "error" not in node, node.get("error")
    assert node["input"] == "joint_states" and node["n_coordinates"] == 14
    assert node["n_muscles"] == imported["library_muscles"]
    assert node["node_exit_code"] == 0 and node["forces_finite"] and node["efforts_finite"]
    for key in ("cpu_percent_one_core", "rss_final_mib", "model_wall_drift_percent",
                "model_time_skipped_s", "rate_joint_states_sent_hz", "rate_joint_efforts_hz"):
        assert key in node, key
    assert joint["node_repeats"] == []  # --quick: one pair
    floor = joint["floor"][0]
    assert "error" not in floor, floor.get("error")
    assert floor["floor_level"] == "mcap" and floor["input"] == "joint_states"
    assert floor["rate_joint_efforts_hz"] > 0 and floor["rate_joint_effort_commands_hz"] > 0
    assert floor["node_exit_code"] == 0 and floor["cpu_percent_one_core"] > 0

    motion = joint["motion"]
    assert motion["muscles"] == imported["library_muscles"] and motion["motion_s"] == 1.0
    assert motion["simulate_s_min"] <= motion["simulate_s"] <= motion["simulate_s_max"]
    assert motion["simulate_cpu_s"] > 0
    assert motion["log"].startswith("log: ") and motion["model_s"] > 0

    loops = {(r["model"], r["root"]): r for r in joint["closed_loop"]}
    assert set(loops) == {("myoelbow", "fixed base"), ("myolegs", "pelvis fixed"),
                          ("myolegs", "pelvis free")}
    for row in loops.values():
        assert row["wall_per_sim_s_min"] <= row["wall_per_sim_s"] <= row["wall_per_sim_s_max"]
        assert row["dt_s"] == 1e-3 and row["simulated_s"] > 0
    assert loops["myolegs", "pelvis fixed"]["free_joints_removed"] == ["root"]
    assert "root_height_end_m" in loops["myolegs", "pelvis free"]

    rows = [r for r in _csv(out) if r["section"] == "joint"]
    metrics = {r["metric"] for r in rows}
    assert {"per call median", "cpu_percent_one_core", "wall per simulated s",
            "cpu above the rclpy floor"} <= metrics
    assert all(r["min"] and r["max"] for r in rows if r["metric"] == "per call median")
    assert "wall per simulated s" in capsys.readouterr().out


def test_joint_section_without_mujoco_says_why(tmp_path, monkeypatch, capsys):
    reason = "needs the mujoco extra (mujoco is not installed): pip install 'vm_ros[mujoco]'"
    monkeypatch.setattr(joint_bench, "missing_extra", lambda: reason)
    out = tmp_path / "bench"
    assert main([*QUICKEST, "--out", str(out)]) == 0
    joint = json.loads((out / "bench.json").read_text())["joint"]
    assert joint["geometry"] == {"skipped": reason} and joint["node"] == {"skipped": reason}
    assert joint["closed_loop"] == [{"skipped": reason}] and joint["motion"] == {"skipped": reason}
    assert {r["metric"] for r in _csv(out)} == {"skipped"}
    assert "skipped" in capsys.readouterr().out
