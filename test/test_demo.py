"""`vm-ros demo`: muscle_node driven by the knee-extension scenario; the summary table."""

from __future__ import annotations

import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import require_ros

from vm_ros.cli.demo import format_summary
from vm_ros.telemetry import COMPONENT_LABELS, FIBRE_LABELS


def test_summary_table_lists_every_muscle_fibre_and_component():
    energy = np.arange(2 * 3 * 4, dtype=float).reshape(2, 3, 4)
    summary = SimpleNamespace(names=("rectus_femoris", "vasti"), duration_s=2.0, messages=200,
                              peak_force=np.array([210.0, 1250.0]),
                              mean_force=np.array([50.0, 190.0]), energy=energy,
                              energy_total=40.0,
                              diagnostics={"skipped model time (s)": "0.25"})
    text = format_summary(summary, None)
    assert "rectus_femoris" in text and "vasti" in text and "1250.0" in text
    for label in (*FIBRE_LABELS, *COMPONENT_LABELS):
        assert label in text
    assert f"{energy[:, -1].sum(axis=0)[-1]:.3f}" in text  # all muscles, all fibres, total
    assert "skipped 0.25 s" in text


@pytest.mark.ros
def test_demo_runs_and_logs(tmp_path):
    require_ros()
    from vm_ros.recording import read_run

    path = tmp_path / "demo.mcap"
    proc = subprocess.run([sys.executable, "-m", "vm_ros.cli", "demo", "--duration", "2",
                           "--mcap", str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "knee_extension" in out and "rectus_femoris" in out and "vasti" in out
    assert "peak force (N)" in out and "cross_bridge" in out and f"MCAP log: {path}" in out
    run = read_run(path)
    assert run.complete and run.info.source == "muscle_node"
    assert run.info.config.recovery_mode == "dynamic"
    assert len(run.get("muscle_force")) > 20 and len(run.get("muscle_kinematics")) > 100
