"""`vm-ros bench --compare`: vm_ros beside OpenSim and MuJoCo in one process (a smoke run with
few steps: the timings are benchmarks, not tests). The peers' models are checked against the
vm_ros muscles they stand beside, and the timer against steppers of known cost."""

from __future__ import annotations

import csv
import json
import sys
import time

import numpy as np
import pytest

from vm_ros.cli import main
from vm_ros_bench import cli as bench
from vm_ros_bench import mujoco_compare, opensim_compare, peer_compare, peers

N = 3  # the larger bank of the quick runs


def _run(tmp_path, *extra):
    out = tmp_path / "bench"
    code = main(["bench", "--only", "natural", "--quick", "--repeats", "2", "--compare", *extra,
                 "--compare-muscles", str(N), "--out", str(out)])
    return code, out


def _installed(peer):
    return peer_compare.peer_missing(peer) is None


def test_compare_reports_every_installed_peer_beside_vm_ros(tmp_path, capsys):
    code, out = _run(tmp_path)
    assert code == 0
    compare = json.loads((out / "bench.json").read_text())["compare"]
    systems = {r["system"]: r for r in compare["systems"]}
    assert set(systems) == {"vm_ros", *bench.COMPARE_PEERS}
    vm = systems["vm_ros"]
    for name, r in systems.items():
        if "skipped" in r:
            assert not _installed(name) and r["skipped"]
            continue
        for key in ("step_1_cpu_us", "step_1_wall_us", "step_n_cpu_us", "step_n_wall_us"):
            assert r[key] > 0, (name, key)
        # the slope and the ratios are the definitions applied to the medians
        assert r["per_muscle_cpu_us"] == pytest.approx(
            (r["step_n_cpu_us"] - r["step_1_cpu_us"]) / (N - 1))
        assert r["timing_1"]["cpu_us_min"] <= r["step_1_cpu_us"] <= r["timing_1"]["cpu_us_max"]
        assert r["reading_n"]["total_force_n"] > 0
        if name != "vm_ros":
            assert r["over_vm_ros_step_1_cpu"] == pytest.approx(
                r["step_1_cpu_us"] / vm["step_1_cpu_us"])
            assert r["over_vm_ros_per_muscle_wall"] == pytest.approx(
                r["per_muscle_wall_us"] / vm["per_muscle_wall_us"])
    rows = list(csv.DictReader((out / "bench.csv").read_text().splitlines()))
    ratios = [r for r in rows if r["section"] == "compare" and r["unit"] == "ratio"]
    assert len(ratios) == 4 * sum("skipped" not in r for r in compare["systems"][1:])
    assert "per extra muscle, thread CPU" in capsys.readouterr().out


def test_a_peer_not_installed_is_skipped_with_the_reason(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco raises ImportError
    code, out = _run(tmp_path, "mujoco")
    assert code == 0
    compare = json.loads((out / "bench.json").read_text())["compare"]
    assert [r["system"] for r in compare["systems"]] == ["vm_ros", "mujoco"]
    assert compare["systems"][1] == {"system": "mujoco", "skipped": mujoco_compare.NEEDS_MUJOCO}
    rows = list(csv.DictReader((out / "bench.csv").read_text().splitlines()))
    assert {"section": "compare", "case": "mujoco", "metric": "skipped",
            "value": mujoco_compare.NEEDS_MUJOCO} in [
        {k: r[k] for k in ("section", "case", "metric", "value")} for r in rows]


def test_bad_compare_arguments_are_one_line_errors(tmp_path, capsys):
    for extra in (["--compare", "opensim,simbody"], ["--compare", "mujoco",
                                                     "--compare-muscles", "1"]):
        code = main(["bench", "--only", "natural", "--quick", *extra, "--out",
                     str(tmp_path / "x")])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1 and "--compare" in err
    assert not (tmp_path / "x" / "bench.json").exists()
    assert bench.COMPARE_PEERS == peer_compare.PEERS


class _Sleeper(peers.PeerStepper):
    """Wall time without CPU time: 1 ms asleep per step."""

    def advance(self, steps):
        time.sleep(1e-3 * steps)


class _Spinner(peers.PeerStepper):
    """CPU time in proportion to n: 20 us of busy work per muscle and step."""

    def __init__(self, n):
        self.n = n

    def advance(self, steps):
        end = time.thread_time_ns() + 20_000 * self.n * steps
        while time.thread_time_ns() < end:
            pass


def test_the_timer_tells_cpu_from_wall_and_recovers_a_known_slope():
    timing = peer_compare.time_interleaved(
        {"sleep": _Sleeper(), "one": _Spinner(1), "five": _Spinner(5)}, rounds=3,
        block_seconds=0.01)
    assert timing["sleep"]["wall_us"] >= 1000 and timing["sleep"]["cpu_us"] < 200
    slope = (timing["five"]["cpu_us"] - timing["one"]["cpu_us"]) / 4
    assert slope == pytest.approx(20.0, rel=0.1)


@pytest.mark.skipif(not _installed("mujoco"), reason="needs the mujoco extra")
def test_mujoco_muscles_match_the_vm_ros_muscles():
    """Each tendon is at its muscle's rest length L0 + L0T when the slider is at the first's; the
    actuator's optimal length (lengthrange over range) is L0, its peak force F0."""
    import mujoco

    stepper = mujoco_compare.MujocoMuscles(4)
    _, lp, _, bank = peers.bench_inputs(4)
    model, data = stepper.model, stepper.data
    data.qpos[0] = bank.l0_m[0] + bank.l0t_m[0]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.ten_length, bank.l0_m + bank.l0t_m, rtol=1e-9)
    lo, hi = mujoco_compare.MUSCLE_RANGE_L0
    l0 = (model.actuator_lengthrange[:, 1] - model.actuator_lengthrange[:, 0]) / (hi - lo)
    np.testing.assert_allclose(l0, bank.l0_m, rtol=1e-9)
    np.testing.assert_allclose(model.actuator_gainprm[:, 2], bank.f0, rtol=1e-9)
    stepper.advance(50)  # the path the vm_ros bank gets, as tendon lengths
    np.testing.assert_allclose(data.ten_length, lp[49], rtol=1e-9)


@pytest.mark.skipif(not _installed("opensim"), reason="needs the opensim extra")
def test_opensim_muscles_match_the_vm_ros_muscles():
    """Each Millard muscle's path is the vm_ros muscle's path length, its F0 and L0 the bank's;
    the probe reports the total, the basal rate and one rate per muscle."""
    stepper = opensim_compare.OpensimMuscles(3)
    _, lp, _, bank = peers.bench_inputs(3)
    stepper.advance(50)
    state = stepper.manager.getState()
    stepper.model.realizePosition(state)
    lengths = [m.getLength(state) for m in stepper.muscles]
    np.testing.assert_allclose(lengths, lp[50], rtol=1e-9)
    np.testing.assert_allclose([m.getMaxIsometricForce() for m in stepper.muscles], bank.f0)
    np.testing.assert_allclose([m.getOptimalFiberLength() for m in stepper.muscles], bank.l0_m)
    assert len(stepper.rate) == 2 + 3
    assert stepper.rate[0] == pytest.approx(sum(stepper.rate[1:]))
