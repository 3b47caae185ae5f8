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
