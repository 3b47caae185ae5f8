"""`vm-ros demo`: muscle_node driven by the knee-extension scenario; the summary table."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest
from conftest import require_ros

from vm_ros.child_process import module_command
from vm_ros.cli.demo import CATCH_UP_S, _node_command, demo_summary, format_summary
from vm_ros.report.summary import split_energy
from vm_ros.telemetry import COMPONENT_LABELS, FIBRE_LABELS


def _messages(k=101, n=2, step_ns=10_000_000, seed=0):
    """k messages of a made-up run: rates (k, n, 3, 4) W consistent with their fibres and
    components, totals the model's Euler sum of the whole-bank rate over 10 sub-steps."""
    rng = np.random.default_rng(seed)
    cells = rng.uniform(0.5, 5.0, size=(k, n, 2, 3))
    rates = np.concatenate([cells, cells.sum(axis=2, keepdims=True)], axis=2)
    rates = np.concatenate([rates, rates.sum(axis=3, keepdims=True)], axis=3)
    total_rate = cells.sum(axis=(1, 2, 3))
    totals = np.concatenate([[0.0], np.cumsum(total_rate[1:] * step_ns * 1e-9 * 1.03)])
    stamps = 5_000_000_000 + step_ns * np.arange(k)
    efforts = rng.uniform(0, 100, size=(k, n))
    return stamps, efforts, rates, totals


def test_energy_table_adds_up_to_energy_total_and_splits_by_rate():
    stamps, efforts, rates, totals = _messages()
    energy = split_energy(rates, totals)
    assert energy.shape == (2, 3, 4)
    assert energy[:, -1, -1].sum() == pytest.approx(totals[-1] - totals[0], rel=1e-12)
    # all fibres = slow + fast, total = sum of the components, in every cell
    np.testing.assert_allclose(energy[:, 2], energy[:, 0] + energy[:, 1], rtol=1e-12)
    np.testing.assert_allclose(energy[..., 3], energy[..., :3].sum(axis=-1), rtol=1e-12)
    # a constant split of the rates is kept exactly: one cell with 60 % of the rate gets 60 %
    constant = np.zeros_like(rates)
    constant[:, 0, 0, 1] = 6.0
    constant[:, 1, 1, 0] = 4.0
    energy = split_energy(constant, totals)
    assert energy[0, 0, 1] == pytest.approx(0.6 * (totals[-1] - totals[0]), rel=1e-12)
    assert energy[1, 1, 0] == pytest.approx(0.4 * (totals[-1] - totals[0]), rel=1e-12)


def test_summary_covers_the_duration_from_the_first_stamp_whatever_arrived_later():
    stamps, efforts, rates, totals = _messages(k=301)
    summary = demo_summary(("a", "b"), stamps, efforts, rates, totals, 1.0, {})
    assert summary.messages == 101 and summary.duration_s == pytest.approx(1.0)
    assert summary.energy_total == pytest.approx(totals[100] - totals[0])
    np.testing.assert_allclose(summary.peak_force, efforts[:101].max(axis=0))
    # energy_total lagging behind muscle_force: only messages with all three count
    summary = demo_summary(("a", "b"), stamps, efforts, rates, totals[:51], 1.0, {})
    assert summary.messages == 51


def test_summary_prints_one_total_and_the_skipped_time():
    stamps, efforts, rates, totals = _messages()
    diagnostics = {"skipped model time (s)": "0.25", "step time p50 (ms)": "0.03",
                   "step time p99 (ms)": "0.05", "model rate (Hz)": "1000.0"}
    summary = demo_summary(("rectus_femoris", "vasti"), stamps, efforts, rates, totals, 10.0,
                           diagnostics)
    text = format_summary(summary, None, "a scenario")
    assert "rectus_femoris" in text and "vasti" in text
    for label in (*FIBRE_LABELS, *COMPONENT_LABELS):
        assert label in text
    total = f"{totals[-1] - totals[0]:.3f}"
    assert text.count(total) == 2  # the table's all-muscles cell and the total line: one number
    assert "skipped 0.25 s" in text and "30 us median" in text and "1000 us per step" in text
    assert "NOT VALID" in text and "exit status 3" in text
    assert summary.validity.exit_status(accepted=False) == 3
    assert summary.validity.exit_status(accepted=True) == 0


def test_demo_node_catches_up_on_a_stall_and_runs_the_installed_package():
    from types import SimpleNamespace

    from vm_ros.offline.scenarios import load_scenario

    args = SimpleNamespace(recruitment="lumped", model_rate_hz=1000.0, executor="events")
    command = _node_command(args, load_scenario("knee_extension"), None)
    assert command[:len(module_command("vm_ros.node"))] == module_command("vm_ros.node")
    assert f"max_catch_up_steps:={round(CATCH_UP_S * 1000)}" in command


@pytest.mark.ros
def test_demo_runs_and_logs(tmp_path):
    require_ros()
    from vm_ros.recording import read_run

    path = tmp_path / "demo.mcap"
    proc = subprocess.run(module_command("vm_ros.cli", "demo", "--duration", "2",
                                         "--mcap", str(path), "--accept-skips"),
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr  # valid or not: that depends on the load
    out = proc.stdout
    assert "knee_extension" in out and "rectus_femoris" in out and "vasti" in out
    assert "peak force (N)" in out and "cross_bridge" in out and f"MCAP log: {path}" in out
    assert "2.00 s of model time, 201 messages" in out
    run = read_run(path)
    assert run.complete and run.info.source == "muscle_node"
    assert run.info.config.recovery_mode == "dynamic"
    assert len(run.get("muscle_force")) > 20 and len(run.get("muscle_kinematics")) > 100
    totals = run.get("energy_total").fields["data"]
    total_line = next(line for line in out.splitlines() if line.startswith("total energy:"))
    printed = float(total_line.split()[2])
    assert printed > 0 and any(abs(totals[j] - totals[0] - printed) < 1e-3
                               for j in range(len(totals)))


@pytest.mark.ros
@pytest.mark.parametrize("closed_loop", [False, True], ids=["knee", "closed loop"])
def test_a_failing_ros_start_leaves_no_node_running(monkeypatch, tmp_path, closed_loop):
    """rclpy's start failing (here: rclpy.init raising) must not leave muscle_node running on its
    own: the demos start it only once their ROS side is up, right before the block that stops
    it (before, the knee demo's node was orphaned and ran on)."""
    require_ros()
    import argparse

    import rclpy

    from vm_ros.cli import demo

    if closed_loop:
        pytest.importorskip("mujoco")
        monkeypatch.setattr(demo, "prepare_geometry", lambda model, out: (None, None))
        monkeypatch.setattr(demo, "loop_parameters", lambda *a: ({}, {}, argparse.Namespace(
            description="drive"), ["m"]))
    started = []

    class NoNode:
        def __init__(self, command, **options):
            started.append(command)

    def failing_init(**options):
        raise RuntimeError("rclpy could not start")

    monkeypatch.setattr(demo.subprocess, "Popen", NoNode)
    monkeypatch.setattr(rclpy, "init", failing_init)
    args = argparse.Namespace(duration=1.0, closed_loop=closed_loop, model=None, no_mcap=False,
                              mcap=None, out=str(tmp_path), executor="events",
                              model_rate_hz=1000.0, recruitment="lumped", startup_timeout=5.0,
                              accept_skips=False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(RuntimeError, match="rclpy could not start"):
        demo.run(args)
    assert started == []
