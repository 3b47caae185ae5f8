"""The node benchmark (vm_ros_bench.node_bench) end to end: a short run of muscle_node as a
process, driven and measured from this process, gives sane numbers."""

from __future__ import annotations

import math

import pytest
from conftest import require_ros

from vm_ros_bench.node_bench import rss_growth, run_node_benchmark

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


def test_split_bag_run_reads_back_and_samples_memory(tmp_path):
    """--bag with a 1 s split: a bag directory of >= 2 files whose messages all read back, and
    the memory keys of the sampled window."""
    require_ros()
    duration_s, period_s = 4.0, 0.5
    result = run_node_benchmark(3, duration_s=duration_s, warmup_s=1.0, workdir=tmp_path,
                                bag=True, max_bag_duration_s=1.0, rss_sample_period_s=period_s)

    assert result["node_exit_code"] == 0, (tmp_path / "muscle_node.log").read_text()
    bag = tmp_path / "node_bench"
    files = sorted(bag.glob("node_bench_*.mcap"))
    assert (bag / "metadata.yaml").is_file() and len(files) >= 2
    assert result["bag"] and result["max_bag_duration_s"] == 1.0
    assert result["log_files"] == result["log_metadata_files"] == len(files)
    assert result["log_read_complete"]
    assert result["log_messages_read"] == result["log_messages_summary"] > 0
    total = sum(f.stat().st_size for f in files)
    assert result["mcap_file_mib"] * 1024 * 1024 == pytest.approx(total)
    # about one sample per period over the window, plus its two ends
    assert result["rss_samples"] >= duration_s / period_s - 1
    trace = result["rss_trace"]
    mib = 1e-3  # the trace is rounded to 1 kB
    assert trace[0][1] == pytest.approx(result["rss_window_start_mib"], abs=mib)
    assert trace[-1][1] == pytest.approx(result["rss_final_mib"], abs=mib)
    assert result["rss_max_growth_mib"] == pytest.approx(max(m for _, m in trace) - trace[0][1],
                                                         abs=2 * mib)
    assert result["rss_growth_mib"] == pytest.approx(trace[-1][1] - trace[0][1], abs=2 * mib)
    assert math.isfinite(result["rss_slope_mib_per_hour"])
    assert result["rss_growth_mib_per_min"] == pytest.approx(
        result["rss_growth_mib"] / (result["duration_s"] / 60.0), rel=1e-9)
    assert math.isfinite(result["rss_slope_second_half_mib_per_hour"])
    assert result["latency_from_node_log"] and result["latency_samples"] > 100  # read the bag


def test_rss_growth_of_known_traces():
    """A steady climb of 1 MiB in 10 minutes is 6 MiB/h and 0.1 MiB/min; a warm-up step of
    3 MiB in the first half followed by a flat second half has a second-half slope of 0."""
    steady = rss_growth([(t, 200.0 + t / 600.0) for t in range(0, 601, 5)])
    assert steady["rss_growth_mib"] == pytest.approx(1.0)
    assert steady["rss_growth_mib_per_min"] == pytest.approx(0.1)
    assert steady["rss_slope_mib_per_hour"] == pytest.approx(6.0)
    assert steady["rss_slope_second_half_mib_per_hour"] == pytest.approx(6.0)
    settling = rss_growth([(t, 200.0 + (3.0 if t >= 100 else 0.0)) for t in range(0, 601, 5)])
    assert settling["rss_growth_mib"] == pytest.approx(3.0)
    assert settling["rss_max_growth_mib"] == pytest.approx(3.0)
    assert settling["rss_slope_mib_per_hour"] > 0
    assert settling["rss_slope_second_half_mib_per_hour"] == pytest.approx(0.0, abs=1e-9)


def test_splitting_needs_a_bag():
    with pytest.raises(ValueError, match="needs bag"):
        run_node_benchmark(3, duration_s=1.0, max_bag_duration_s=1.0)
