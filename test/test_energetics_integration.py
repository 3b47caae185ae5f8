"""The published energetics models inside vm_ros: MuscleBank(energetics_models=...), the
energy_rate_models log channel of offline runs and recompute, and vm-ros report's totals.

Independent numbers: the bank's rates against published_rates / rates_from_inputs (the models
called on their own on the bank's outputs, stimulation duration from time_since_onset over the
whole series); cumulative energies against sums of rate * dt done here; logged values against
published_rates on a second bank stepped over the logged inputs.
"""

from __future__ import annotations

import csv

import numpy as np
import pytest

from vm_ros import telemetry as tm
from vm_ros.cli import main
from vm_ros.errors import InputError
from vm_ros.model import MuscleBank
from vm_ros.model import kernel as model_kernel
from vm_ros.model.energetics_models import MODEL_NAMES, published_rates
from vm_ros.model.energetics_models.in_bank import COMPONENTS
from vm_ros.model.energetics_models.vm_state import (
    VmMuscleConstants,
    rates_from_inputs,
    time_since_onset,
    vm_model_inputs,
    vm_model_inputs_from_outputs,
)
from vm_ros.recording import messages as msgs
from vm_ros.recording.run_log import read_run

DT = 1e-3
MUSCLES = ["vasti", "rectus_femoris"]
BACKENDS = ["numpy"] + (["numba"] if model_kernel.AVAILABLE else [])


def _inputs(bank, steps=400):
    """Drive pulses (on and off, so that the stimulation duration restarts) and a moving path."""
    t = DT * np.arange(steps)
    u = np.clip(np.sin(2 * np.pi * 4 * t)[:, None] * np.array([0.8, 0.5]), 0.0, 1.0)
    rest = bank.l0_m + bank.l0t_m
    lp = rest + 0.01 * np.sin(2 * np.pi * 2 * t)[:, None]
    vp = 0.01 * 2 * np.pi * 2 * np.cos(2 * np.pi * 2 * t)[:, None] * np.ones(bank.n)
    return u, lp, vp


@pytest.mark.parametrize("backend", BACKENDS)
def test_step_by_step_equals_run_and_published_rates(backend):
    bank = MuscleBank.from_config(MUSCLES, backend=backend, energetics_models="all")
    assert bank.energetics_models == MODEL_NAMES
    u, lp, vp = _inputs(bank)
    bank.reset(lp[0])
    run = bank.run(DT, u, lp, vp)
    k, n, m = len(u), bank.n, len(MODEL_NAMES)
    assert run.energy_rate_models.shape == (k, n, m, len(COMPONENTS))
    assert run.energy_models.shape == (k, n, m)
    # read after every step (the models computed one step at a time), then read at the end
    # (the bank's pending steps computed in one batch)
    for read_each_step in (True, False):
        bank.reset(lp[0])
        outs = []
        for j in range(k):
            outs.append(bank.step(DT, u[j], lp[j], vp[j]))
            if read_each_step:
                assert outs[-1].energy_rate_models.shape == (n, m, len(COMPONENTS))
        stepped = np.array([o.energy_rate_models for o in outs])
        np.testing.assert_allclose(stepped, run.energy_rate_models, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(np.array([o.energy_models for o in outs]),
                                   run.energy_models, rtol=1e-12, atol=1e-12)
    # the models called on their own on the run's outputs
    reference = published_rates(bank, run)
    for j, name in enumerate(MODEL_NAMES):
        for c, component in enumerate(COMPONENTS):
            np.testing.assert_allclose(run.energy_rate_models[:, :, j, c],
                                       getattr(reference[name], component),
                                       rtol=1e-12, atol=1e-12, equal_nan=True)
    # ... and on each step's outputs, the stimulation duration counted over the series
    duration = time_since_onset(run.time_s, run.excitation)
    for row in (0, 57, k - 1):
        inputs = vm_model_inputs_from_outputs(bank, outs[row])
        inputs = type(inputs)(inputs.state, inputs.force_length_multiplier,
                              inputs.force_velocity_multiplier, inputs.passive_fibre_force,
                              duration[row])
        one = rates_from_inputs(inputs)
        for j, name in enumerate(MODEL_NAMES):
            np.testing.assert_allclose(outs[row].energy_rate_models[:, j, -1], one[name].total,
                                       rtol=1e-12, atol=1e-12)
    # the pulses switch the drive off and on: Lichtwark's duration restarted
    assert np.any(duration[1:] < duration[:-1])
    # cumulative energy = sum of total rate * dt since reset
    np.testing.assert_allclose(run.energy_models[-1],
                               (run.energy_rate_models[..., -1] * DT).sum(axis=0), rtol=1e-12)
    assert np.all(run.energy_models[-1] > 0)


def test_run_in_pieces_equals_one_run_and_reset_clears():
    bank = MuscleBank.from_config(MUSCLES, energetics_models=("umberger2010", "lichtwark2005"))
    u, lp, vp = _inputs(bank, 300)
    bank.reset(lp[0])
    whole = bank.run(DT, u, lp, vp)
    start = bank.reset(lp[0])
    assert start.energy_rate_models.shape == (2, 2, 5)
    assert np.all(start.energy_models == 0.0)
    first = bank.run(DT, u[:137], lp[:137], vp[:137])
    second = bank.run(DT, u[137:], lp[137:], vp[137:])
    np.testing.assert_allclose(np.concatenate([first.energy_rate_models,
                                               second.energy_rate_models]),
                               whole.energy_rate_models, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(second.last.energy_models, whole.last.energy_models, rtol=1e-12)


def test_no_models_by_default_and_bad_names():
    bank = MuscleBank.from_config(MUSCLES)
    assert bank.energetics_models == ()
    out = bank.reset(bank.l0_m + bank.l0t_m)
    assert out.energy_rate_models is None
    with pytest.raises(InputError, match="known: umberger2003"):
        MuscleBank.from_config(MUSCLES, energetics_models=["umberger2010", "nonsense"])


# --- logs: simulate, recompute, report -----------------------------------------------------


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A short knee extension with every model, and one without (an "old" log)."""
    folder = tmp_path_factory.mktemp("models")
    with_models, without = folder / "knee-models.mcap", folder / "knee.mcap"
    common = ["simulate", "--scenario", "knee_extension", "--duration", "0.6",
              "--start-time", "0"]
    assert main([*common, "--energetics-models", "all", "--out", str(with_models)]) == 0
    assert main([*common, "--out", str(without)]) == 0
    return with_models, without


def _logged_models(path):
    run = read_run(path)
    series = run.get(tm.TOPIC_ENERGY_RATE_MODELS)
    assert series is not None
    axes = [tm.split_dim_label(dim["label"]) for dim in series.layout]
    return run, series, axes


def _reference_rates(run, tmp_path, models):
    """published models on the logged bank outputs (muscle_telemetry at the publish ticks),
    Lichtwark's stimulation duration counted from the drive logged at every step."""
    bank = run.config(tmp_path).make_bank()
    n = bank.n
    telemetry = run.get(msgs.TOPIC_TELEMETRY)
    dt = run.info.timing.dt_s
    excitation = run.get(tm.TOPIC_EXCITATION)
    ends = run.model_time_ns(excitation.time_ns) * 1e-9 + dt  # step k ends at t_k + dt
    duration = time_since_onset(ends, np.clip(excitation.fields["position"], 0.0, 1.0))
    stamps = run.model_time_ns(telemetry.fields["stamp_ns"]) * 1e-9
    rows = np.searchsorted(ends, stamps - 1e-12)
    np.testing.assert_allclose(ends[rows], stamps, atol=1e-9)
    inputs = vm_model_inputs(VmMuscleConstants.from_bank(bank),
                             telemetry.fields["excitation"],
                             telemetry.fields["effective_activation"].reshape(-1, n, 2),
                             telemetry.fields["fascicle_length"],
                             telemetry.fields["fascicle_velocity"], duration[rows])
    return rates_from_inputs(inputs, models), telemetry


def test_simulate_logs_every_model_as_published_rates_give(logs, tmp_path):
    run, series, axes = _logged_models(logs[0])
    muscles = run.info.config.muscles
    assert run.info.config.energetics_models == MODEL_NAMES
    assert axes == [("muscle", tuple(muscles)), ("model", MODEL_NAMES),
                    ("component", COMPONENTS)]
    assert [d["size"] for d in series.layout] == [len(muscles), len(MODEL_NAMES), 5]
    k = len(series)
    assert k == 60  # 0.6 s at the default 100 Hz publish rate
    data = series.fields["data"].reshape(k, len(muscles), len(MODEL_NAMES), len(COMPONENTS))
    reference, telemetry = _reference_rates(run, tmp_path, MODEL_NAMES)
    np.testing.assert_array_equal(series.time_ns, telemetry.time_ns)
    for j, name in enumerate(MODEL_NAMES):
        for c, component in enumerate(COMPONENTS):
            np.testing.assert_allclose(data[:, :, j, c], getattr(reference[name], component),
                                       rtol=1e-9, atol=1e-9, equal_nan=True)
    assert np.all(np.isfinite(data[..., -1]))


def test_block_and_stepwise_offline_runs_log_the_same_models(tmp_path):
    from vm_ros.model.run_config import RunConfig
    from vm_ros.offline.runner import OfflineRun, SampledInputs
    from vm_ros.offline.scenarios import load_scenario
    from vm_ros.recording.run_log import RunInfo, RunTiming, open_run_log

    scenario = load_scenario("knee_extension")
    config = RunConfig(scenario.muscles, energetics_models=("lichtwark2005", "margaria1968"))
    timing = RunTiming(dt_s=DT, publish_rate_hz=200.0, telemetry_rate_hz=50.0, start_time_ns=0)
    data = []
    for block_steps in (0, 97):
        bank = config.make_bank()
        path = tmp_path / f"run-{block_steps}.mcap"
        with open_run_log(path, RunInfo(config, timing, "test"), bank) as recorder:
            offline = OfflineRun(bank, timing, recorder)
            functions = scenario.inputs(bank)
            inputs = SampledInputs(bank.names, functions.excitation, functions.path_length,
                                   functions.path_velocity, timing.dt_ns, 0, offline.sink)
            offline.run(inputs, 450, block_steps=block_steps)
        series = read_run(path).get(tm.TOPIC_ENERGY_RATE_MODELS)
        data.append((series.time_ns, series.fields["data"]))
    np.testing.assert_array_equal(data[0][0], data[1][0])
    np.testing.assert_array_equal(data[0][1], data[1][1])


def test_recompute_adds_the_channel_to_an_old_log(logs, tmp_path, capsys):
    old = read_run(logs[1])
    assert old.get(tm.TOPIC_ENERGY_RATE_MODELS) is None
    assert "energetics_models" not in old.metadata["vm_ros.run"]
    out = tmp_path / "recomputed.mcap"
    capsys.readouterr()
    assert main(["recompute", str(logs[1]), "--energetics-models",
                 "umberger2010,bhargava2004", "--out", str(out)]) == 0
    printed = capsys.readouterr().out  # the totals per model, as report gives them
    lines = [x.split() for x in printed.splitlines()
             if x.split()[:1] in (["tsianos2012"], ["umberger2010"], ["bhargava2004"])]
    assert [x[0] for x in lines] == ["tsianos2012", "umberger2010", "bhargava2004"]
    from vm_ros.report.tables import model_totals

    totals = {row.model: row.total for row in model_totals(read_run(out))}
    assert [float(x[1]) for x in lines] == [round(totals[x[0]], 2) for x in lines]
    run, series, axes = _logged_models(out)
    assert axes[1] == ("model", ("umberger2010", "bhargava2004"))
    assert run.info.config.energetics_models == ("umberger2010", "bhargava2004")
    reference, _ = _reference_rates(run, tmp_path, ("umberger2010", "bhargava2004"))
    data = series.fields["data"].reshape(len(series), -1, 2, 5)
    np.testing.assert_allclose(data[:, :, 1, -1], reference["bhargava2004"].total, rtol=1e-9)
    # a log with models recomputes with them (no option)
    again = tmp_path / "again.mcap"
    assert main(["recompute", str(out), "--out", str(again)]) == 0
    np.testing.assert_array_equal(_logged_models(again)[1].fields["data"],
                                  series.fields["data"])


def test_report_prints_and_writes_the_totals_per_model(logs, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["report", str(logs[0]), "--out", str(out), "--no-plots"]) == 0
    printed = capsys.readouterr().out
    run, series, _ = _logged_models(logs[0])
    muscles = run.info.config.muscles
    t = (series.time_ns - series.time_ns[0]) * 1e-9
    totals = series.fields["data"].reshape(len(t), len(muscles), len(MODEL_NAMES), 5)[..., -1]
    energy = [float(np.sum((totals[1:] + totals[:-1]) / 2 * np.diff(t)[:, None, None],
                           axis=(0, 1))[j]) for j in range(len(MODEL_NAMES))]
    # Tsianos 2012: the model's own sum over its steps (energy_total, the summary's E total),
    # not an integral of the published rates
    tsianos = float(run.get(tm.TOPIC_ENERGY_TOTAL).fields["data"][-1])
    with open(out / "model_totals.csv", newline="") as handle:
        rows = {row["model"]: row for row in csv.DictReader(handle)}
    assert list(rows) == ["tsianos2012", *MODEL_NAMES]
    assert float(rows["tsianos2012"]["energy_J"]) == pytest.approx(tsianos, rel=1e-9)
    for j, name in enumerate(MODEL_NAMES):
        assert float(rows[name]["energy_J"]) == pytest.approx(energy[j], rel=1e-12)
        assert float(rows[name]["relative_to_tsianos"]) == pytest.approx(energy[j] / tsianos,
                                                                         rel=1e-9)
        line = next(x for x in printed.splitlines() if x.startswith(name + " "))
        assert f"{energy[j]:.2f}" in line and f"{energy[j] / tsianos:.3f}" in line
    assert (out / "energy_rate_models.csv").exists()


@pytest.mark.parametrize("verb", ["simulate", "recompute"])
def test_bad_model_names_exit_2_with_one_line(logs, tmp_path, capsys, verb):
    args = (["simulate", "--scenario", "knee_extension", "--duration", "0.01"] if
            verb == "simulate" else ["recompute", str(logs[1])])
    assert main([*args, "--energetics-models", "umberger2010,nonsense", "--out",
                 str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nonsense" in err[0] and "umberger2003" in err[0]
    assert not (tmp_path / "x.mcap").exists()
