"""One computation per printed quantity: the joint work and the Tsianos 2012 energy are the
model's sums over its steps wherever they are printed (simulate, report, recompute), never an
integral of the published samples beside them."""

from __future__ import annotations

import numpy as np
import pytest
from test_simulate_joint_space import _run, simulate_leg

from vm_ros.recording.run_log import read_run


def _joint_work(printed: str) -> dict:
    """W joint per joint from a printed joint summary (columns: joint, peak, mean, unit of one
    or two words, W joint, clamped)."""
    return {line.split()[0]: line.split()[-2] for line in printed.splitlines()
            if line.split()[:1] in (["hip_flexion"], ["knee_angle"])}


def test_simulate_and_report_print_the_same_joint_work(tmp_path):
    log, simulated = simulate_leg(tmp_path, "--excitation", "0.5")
    reported = _run(["report", str(log), "--out", str(tmp_path / "report"), "--no-plots"])
    work = _joint_work(simulated)
    assert set(work) == {"hip_flexion", "knee_angle"} and float(work["knee_angle"]) != 0.0
    assert _joint_work(reported) == work
    assert "W joint: sum over the model steps of tau qdot dt" in reported
    # the logged sum is the model's: with joint_efforts published at every step, the sum of
    # their tau qdot dt computed here is the same number
    (tmp_path / "every").mkdir()
    every_step, printed = simulate_leg(tmp_path / "every", "--excitation", "0.5",
                                       "--publish-rate", "1000")
    run = read_run(every_step)
    efforts = run.get("joint_efforts")
    dt = np.diff(efforts.time_ns) * 1e-9
    assert np.allclose(dt, 1e-3)
    steps = (efforts.fields["effort"][1:] * efforts.fields["velocity"][1:] * dt[:, None]).sum(0)
    logged = run.get("joint_work").fields["data"][-1]
    np.testing.assert_allclose(logged, steps, rtol=1e-9, atol=1e-12)
    assert _joint_work(printed) == {name: f"{w:.3f}" for name, w in zip(efforts.names, steps,
                                                                         strict=True)}


def test_simulate_prints_one_tsianos_total(tmp_path):
    log = tmp_path / "knee.mcap"
    printed = _run(["simulate", "--scenario", "knee_extension", "--duration", "1.5",
                    "--energetics-models", "umberger2010", "--out", str(log)])
    lines = printed.splitlines()
    table = next(line for line in lines if line.startswith("all muscles")).split()
    models = next(line for line in lines if line.startswith("tsianos2012")).split()
    total = float(read_run(log).get("energy_total").fields["data"][-1])  # the model's own sum
    assert table[6] == models[1] == f"{total:.2f}"
    assert float(table[6]) == pytest.approx(total, abs=0.006)
