"""The node benchmark (vm_ros_bench.node_bench) end to end: a short run of muscle_node as a
process, driven and measured from this process, gives sane numbers."""

from __future__ import annotations

import math

import numpy as np
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
    # each excitation's wait for the publish step is at least a model step, so the latency
    # without it is positive (delivery both ways) and below the latency, percentile by percentile
    after = result["latency_after_publish_step_p50_ms"]
    assert result["latency_publish_wait_p50_ms"] >= 1.0
    assert 0 < after < result["latency_p50_ms"]
    assert after <= result["latency_after_publish_step_p99_ms"] < result["latency_p99_ms"]
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


def test_the_rclpy_floor_publishes_the_node_s_bytes_sizes():
    """The floor's outputs have the sizes of rclpy's own serialisation of muscle_node's messages
    for the same muscles (JointState with a name and position, velocity, effort per muscle;
    Float64; Float64MultiArray of 3 fibre labels x 4 components per muscle and its layout)."""
    require_ros()
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from vm_ros_bench.rclpy_floor import output_bytes

    names = ["soleus_0", "gastrocnemius_medial_1", "tibialis_anterior_2"]
    zeros = [0.0] * len(names)
    expected = {"muscle_force": serialize_message(JointState(
                    name=names, position=zeros, velocity=zeros, effort=zeros)),
                "energy_rate_total": serialize_message(Float64()),
                "energy_total": serialize_message(Float64())}
    steps = output_bytes(names, steps=4)
    assert len(steps) == 4
    for step in steps:
        data = dict(step)
        assert list(data) == ["muscle_force", "energy_rate", "energy_rate_total", "energy_total"]
        for topic, serialised in expected.items():
            assert len(data[topic]) == len(serialised), topic
        assert len(data["energy_rate"]) > 8 * 3 * 4 * len(names)
    forces = [dict(step)["muscle_force"] for step in steps]
    assert len(set(forces)) == 4  # different values in each step


def test_the_joint_node_s_rclpy_floor_publishes_the_joint_topics_bytes_sizes():
    """With output joints the floor's steps also carry joint_efforts and joint_effort_commands
    of the sizes of rclpy's own serialisation of the node's messages for those joints
    (vm_ros.telemetry's fields: a JointState with a name, position, velocity and effort per
    joint; a Float64MultiArray of one value per joint with its layout)."""
    require_ros()
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    from vm_ros import telemetry as tm
    from vm_ros.joint_space import JointEfforts
    from vm_ros.node.shell import fill_message
    from vm_ros_bench.rclpy_floor import output_bytes

    joints = ("hip_flexion_r", "knee_angle_r", "ankle_angle_r")
    zeros = np.zeros(len(joints))
    efforts = JointEfforts(joints, zeros, zeros, zeros)
    expected = {
        "joint_efforts": serialize_message(fill_message(
            JointState(), tm.joint_efforts_fields(efforts, 0))),
        "joint_effort_commands": serialize_message(fill_message(
            Float64MultiArray(), tm.joint_effort_commands_fields(efforts)))}
    steps = output_bytes(["soleus_0", "tibialis_anterior_1"], steps=3, joints=joints)
    for step in steps:
        data = dict(step)
        assert list(data) == ["muscle_force", "energy_rate", "energy_rate_total", "energy_total",
                              "joint_efforts", "joint_effort_commands"]
        for topic, serialised in expected.items():
            assert len(data[topic]) == len(serialised), topic
    assert len({dict(step)["joint_efforts"] for step in steps}) == 3
    assert [topic for topic, _ in output_bytes(["soleus_0"], steps=1)[0]] == [
        "muscle_force", "energy_rate", "energy_rate_total", "energy_total"]


def test_the_rclpy_floor_runs_in_place_of_the_node(tmp_path):
    """The floor at its last level publishes the four outputs at the publish rate and logs
    inputs and outputs; at its first level it only subscribes, and the run still starts (on
    the driver's publishers being matched) and measures its CPU."""
    require_ros()
    from mcap.reader import make_reader

    full = run_node_benchmark(3, duration_s=3.0, warmup_s=1.0, workdir=tmp_path / "mcap",
                              floor_level="mcap")
    assert full["floor_level"] == "mcap" and full["mcap"] and full["node_exit_code"] == 0
    assert full["cpu_percent_one_core"] > 0 and math.isnan(full["model_lag_p50_ms"])
    for topic in ("muscle_force", "energy_rate", "energy_rate_total", "energy_total"):
        assert 80 < full[f"rate_{topic}_hz"] < 120, topic
    with open(tmp_path / "mcap" / "node_bench.mcap", "rb") as stream:
        stats = make_reader(stream).get_summary().statistics
    assert stats.message_count > 6 * 100 * 3  # 2 inputs and 4 outputs at 100 Hz, 3 s and more

    bare = run_node_benchmark(3, duration_s=2.0, warmup_s=0.5, workdir=tmp_path / "subs",
                              floor_level="subscriptions")
    assert bare["floor_level"] == "subscriptions" and not bare["mcap"]
    assert bare["rate_muscle_force_hz"] == 0 and bare["cpu_percent_one_core"] > 0
    assert not (tmp_path / "subs" / "node_bench.mcap").exists()
    with pytest.raises(ValueError, match="floor_level"):
        run_node_benchmark(3, duration_s=1.0, floor_level="model")
