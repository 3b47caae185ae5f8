"""The node benchmark (vm_ros.bench.node_bench) end to end: a short run of muscle_node as a
process, driven and measured from this process, gives sane numbers."""

from __future__ import annotations

import math

import pytest
from conftest import require_ros

from vm_ros.bench.node_bench import run_node_benchmark

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_short_run_gives_sane_numbers(tmp_path):
    require_ros()  # the benchmark starts rclpy here and in the node process
    result = run_node_benchmark(3, duration_s=3.0, warmup_s=1.0, workdir=tmp_path)

    assert result["node_exit_code"] == 0, (tmp_path / "muscle_node.log").read_text()
    assert result["forces_finite"]
    assert result["cpu_percent_one_core"] > 0
    assert 0 < result["rss_final_mib"] <= result["rss_peak_mib"]
    assert result["latency_from_node_log"] and result["latency_samples"] > 100
    for key in ("latency_p50_ms", "latency_p99_ms"):
        assert math.isfinite(result[key]) and result[key] > 0, key
    assert result["latency_p50_ms"] <= result["latency_p99_ms"]
    assert math.isfinite(result["model_wall_drift_percent"])
    assert result["rate_muscle_force_hz"] > 10 and result["rate_excitation_sent_hz"] > 10
    assert result["mcap_file_mib"] > 0 and (tmp_path / "node_bench.mcap").is_file()
