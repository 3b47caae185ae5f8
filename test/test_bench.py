"""`vm-ros bench` runs and writes its results (a smoke run: the timings themselves are
benchmarks, not tests, on shared machines)."""

from __future__ import annotations

import csv
import json

from vm_ros.bench.model_bench import knee_extension_offline
from vm_ros.cli import main


def test_bench_model_section_writes_json_and_csv(tmp_path, capsys):
    out = tmp_path / "bench"
    assert main(["bench", "--only", "model", "--quick", "--repeats", "1", "--out", str(out)]) == 0
    results = json.loads((out / "bench.json").read_text())
    steps = {(r["backend"], r["muscles"]): r["step_us"] for r in results["model"]
             if "step_us" in r}
    assert {n for _, n in steps} == {1, 10, 100, 1000}
    assert all(value > 0 for value in steps.values())
    rows = list(csv.DictReader((out / "bench.csv").read_text().splitlines()))
    assert any(r["target"] == "<= 30 us" for r in rows) or ("numba", 1) not in steps
    assert "step median" in capsys.readouterr().out


def test_knee_extension_offline_energy_matches_stepwise_run():
    """The offline benchmark's result is the scenario's (same energy as stepping one by one)."""
    fast = knee_extension_offline(duration_s=3.0)
    slow = knee_extension_offline(duration_s=3.0, backend="numpy")
    assert fast["steps"] == slow["steps"] == 3000
    assert fast["total_energy_j"] > 0
    assert abs(fast["total_energy_j"] - slow["total_energy_j"]) <= 1e-9 * slow["total_energy_j"]


def test_node_memory_runs_only_when_named_and_is_held_to_five_mib():
    """The 10-minute node-memory item is not in the default run; its growth row has the +5 MiB
    target, met or not by the largest growth after the warm-up."""
    from vm_ros.cli import bench

    assert "node-memory" in bench.SECTIONS and "node-memory" not in bench.DEFAULT_SECTIONS
    run = {"muscles": 100, "max_bag_duration_s": 60.0, "duration_s": 600.0,
           "rss_window_start_mib": 230.0, "rss_final_mib": 231.0, "rss_growth_mib": 1.0,
           "rss_slope_mib_per_hour": 6.0, "log_files": 11, "log_read_complete": True,
           "log_messages_read": 360000, "mcap_file_mib": 550.0, "cpu_percent_one_core": 45.0,
           "model_wall_drift_percent": 0.0}
    for growth, met in ((4.9, True), (5.1, False)):
        rows = bench._csv_rows({"node-memory": {**run, "rss_max_growth_mib": growth}})
        target = [r for r in rows if r["target"] == "<= 5 MiB"]
        assert len(target) == 1 and target[0]["value"] == growth and target[0]["met"] is met
        files = [r for r in rows if r["metric"] == "bag files"]
        assert files[0]["value"] == 11
