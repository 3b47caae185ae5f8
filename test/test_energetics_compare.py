"""The mapping from Virtual Muscle's state to the published energetics models' inputs
(vm_ros.model.energetics_models.vm_state) and the ``vm-ros compare-energetics`` verb."""

from __future__ import annotations

import csv
import dataclasses
import operator

import numpy as np
import pytest
import yaml

from vm_ros.cli import main
from vm_ros.errors import InputError
from vm_ros.model import MuscleBank
from vm_ros.model.energetics_models.vm_state import (
    MODEL_NAMES,
    PUBLISHED_MODELS,
    VmMuscleConstants,
    published_model,
    published_rates,
    time_since_onset,
    vm_model_inputs,
    vm_model_inputs_from_outputs,
)
from vm_ros.validation import energetics_compare as compare

DT = 0.001


def _moving_run(recruitment="lumped", k=1500):
    """Two muscles, drive stepping 0 -> 0.6 / 1.0 and a 2 Hz path-length sine: shortening,
    lengthening, rest and full drive in one run."""
    bank = MuscleBank.from_config(["vasti", "soleus"], recruitment=recruitment)
    lp = compare.path_length_at(bank, 0.0, 1.0)
    bank.reset(lp)
    t = np.arange(k) * DT
    u = np.tile([0.6, 1.0], (k, 1))
    u[: k // 4] = 0.0
    amplitude = 0.1 * bank.l0_m
    path = lp + amplitude * np.sin(4 * np.pi * t)[:, None]
    velocity = amplitude * 4 * np.pi * np.cos(4 * np.pi * t)[:, None]
    return bank, bank.run(DT, u, path, velocity)


@pytest.mark.parametrize("recruitment", ["lumped", "natural", "continuous"])
def test_active_plus_passive_is_the_contractile_force(recruitment):
    bank, trajectory = _moving_run(recruitment)
    inputs = vm_model_inputs_from_outputs(bank, trajectory)
    state = inputs.state
    total = state.active_fibre_force + inputs.passive_fibre_force
    np.testing.assert_allclose(total, trajectory.contractile_force, rtol=0,
                               atol=1e-9 * bank.f0.max())
    assert np.all(trajectory.fascicle_velocity.min(axis=0) < 0)  # shortening and
    assert np.all(trajectory.fascicle_velocity.max(axis=0) > 0)  # lengthening were covered
    assert np.all((state.activation >= 0.0) & (state.activation <= 1.0))
    assert state.activation.max() > 0.3


def test_active_force_at_equilibrium_is_the_tendon_force():
    """At static equilibrium (reset) F_CE = F_SE: the mapping's active + passive force equals the
    tendon force, a number the mapping does not compute."""
    bank = MuscleBank.from_config(["vasti", "rectus_femoris", "soleus"])
    drive = np.array([0.3, 0.7, 1.0])
    out = bank.reset(bank.l0_m + bank.l0t_m, excitation=drive)
    inputs = vm_model_inputs_from_outputs(bank, out)
    np.testing.assert_allclose(inputs.state.active_fibre_force + inputs.passive_fibre_force,
                               out.force, rtol=1e-6)
    activation = inputs.state.activation  # full drive: the largest activation, still <= 1
    assert np.all((activation > 0.0) & (activation <= 1.0)) and activation[2] > 0.8


def test_isometric_force_at_optimal_length():
    """Fascicles held at L0 (FL = 1, V = 0): isometric force = active force = a F0, the
    force-length and force-velocity multipliers are 1."""
    bank = MuscleBank.from_config(["vasti", "soleus"])
    drive = np.array([0.4, 0.9])
    lp = compare.path_length_at(bank, 0.4, 1.0)[0], compare.path_length_at(bank, 0.9, 1.0)[1]
    out = bank.reset(np.array(lp), excitation=drive)
    np.testing.assert_allclose(out.length_l0, 1.0, atol=1e-9)
    inputs = vm_model_inputs_from_outputs(bank, out)
    s = inputs.state
    np.testing.assert_allclose(s.isometric_force, s.activation * bank.f0, rtol=1e-9)
    np.testing.assert_allclose(s.active_fibre_force, s.isometric_force, rtol=1e-12)
    np.testing.assert_allclose(inputs.force_length_multiplier, 1.0, atol=1e-9)
    np.testing.assert_allclose(inputs.force_velocity_multiplier, 1.0, atol=1e-12)
    np.testing.assert_allclose(s.slow_fraction, bank.fpcsa[:, 0])
    np.testing.assert_allclose(s.mass, bank.mass_kg)


def test_isometric_force_is_active_force_at_zero_velocity():
    bank, trajectory = _moving_run()
    constants = VmMuscleConstants.from_bank(bank)
    moving = vm_model_inputs_from_outputs(bank, trajectory).state
    still = vm_model_inputs(constants, trajectory.excitation, trajectory.effective_activation,
                            trajectory.fascicle_length, np.zeros_like(trajectory.fascicle_length))
    np.testing.assert_allclose(still.state.active_fibre_force, moving.isometric_force,
                               rtol=1e-12, atol=1e-12)
    shortening = trajectory.fascicle_velocity < -1e-3
    assert np.all(moving.active_fibre_force[shortening] <= moving.isometric_force[shortening])


def test_time_since_onset():
    t = np.arange(6) * 0.5
    u = np.array([[0, 1], [1, 1], [1, 0], [0, 1], [1, 1], [1, 1]], dtype=float)
    expected = np.array([[0, 0], [0, 0.5], [0.5, 0], [0, 0], [0, 0.5], [0.5, 1.0]])
    np.testing.assert_allclose(time_since_onset(t, u), expected)


def test_registry_and_published_rates():
    assert len(set(MODEL_NAMES)) == len(PUBLISHED_MODELS) == 8
    bank, trajectory = _moving_run(k=400)
    rates = published_rates(bank, trajectory)
    assert tuple(rates) == MODEL_NAMES
    for heat in rates.values():
        assert heat.total.shape == (400, 2) and np.all(np.isfinite(heat.total))
    one = published_rates(bank, trajectory.last, models=("umberger2010",))
    assert one["umberger2010"].total.shape == (2,)
    with pytest.raises(InputError, match="unknown"):
        published_model("nope")


def _table(path):
    with open(path, encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_verb_writes_one_row_per_model_scenario_composition(tmp_path, capsys):
    out = tmp_path / "cmp"
    code = main(["compare-energetics", "--duration", "2", "--no-plots", "--out", str(out),
                 "--compositions", "slow", "fast"])
    assert code == 0
    rows = _table(out / "energetics_comparison.csv")
    scenarios = {r["scenario"] for r in rows}
    settings = dataclasses.replace(compare.with_duration(compare.load_comparison_settings(), 2.0),
                                   compositions=("slow", "fast"))
    assert settings.knee_extension.duration == 2.0 and settings.gait_cycle.cycles == 2
    assert scenarios == {run.name for run in compare.scenario_set(settings)}
    keys = {(r["model"], r["scenario"], r["composition"]) for r in rows}
    assert len(rows) == len(keys) == (len(MODEL_NAMES) + 1) * len(scenarios) * 2
    for row in rows:
        assert np.isfinite(float(row["energy_j"])) and np.isfinite(float(row["mean_rate_w"]))
    assert "wall time" in capsys.readouterr().out

    # Tsianos 2012's integrated energy equals the bank's own cumulative energy for the same run
    knee = next(run for run in compare.scenario_set(settings) if run.name == "knee_extension")
    bank = compare.make_bank(knee, "fast", settings)
    u, lp, vp, reset_drive = knee.inputs(bank)
    bank.reset(lp[0], excitation=reset_drive)
    expected = bank.run(DT, u, lp, vp).last.total_energy
    tsianos = next(r for r in rows if r["model"] == "tsianos2012"
                   and r["scenario"] == "knee_extension" and r["composition"] == "fast")
    assert float(tsianos["energy_j"]) == pytest.approx(expected, rel=1e-5)
    assert float(tsianos["ratio_to_tsianos2012"]) == 1.0
    assert float(tsianos["duration_s"]) == pytest.approx(2.0)


@pytest.mark.parametrize("argv", [["--duration", "-3"], ["--duration", "abc"],
                                  ["--models", "umberger1999"], ["--compositions", "medium"],
                                  ["--scenarios", "running"]])
def test_bad_option_is_one_line_and_exit_2(tmp_path, capsys, argv):
    code = main(["compare-energetics", "--out", str(tmp_path / "x"), *argv])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "compare-energetics: error" in err[0]


# The scenario constants in config/energetics_compare.yaml: the values ComparisonSettings held as
# Python defaults before they moved to the file (so the comparison's numbers did not change).
PREVIOUS_DEFAULTS = {
    "run.dt": 0.001, "run.sweep_muscle": "vasti", "run.sweep_recovery_mode": "static",
    "isometric.drives": (0.1, 0.25, 0.5, 0.75, 1.0), "isometric.duration": 2.0,
    "isometric.fascicle_length": 1.0, "isovelocity.drive": 0.5,
    "isovelocity.speeds": (-2.0, -1.0, -0.5, -0.25, 0.25, 0.5, 1.0, 2.0),
    "isovelocity.centre_length": 1.0, "isovelocity.half_travel": 0.15,
    "knee_extension.duration": 180.0,
    "gait_cycle.frequency": 1.0, "gait_cycle.cycles": 20, "gait_cycle.peak_drive": 0.4,
    "gait_cycle.burst_fraction": 0.4, "gait_cycle.length_amplitude": 0.08,
    "gait_cycle.mid_length": 1.0,
    "slow_fractions.slow": 0.85, "slow_fractions.mixed": 0.50, "slow_fractions.fast": 0.15,
    "run.rate_bin": 1.0, "compositions": ("slow", "mixed", "fast", "library"),
    "groups": ("isometric", "isovelocity", "knee_extension", "gait_cycle"),
}


def test_shipped_config_holds_the_previous_defaults():
    settings = compare.load_comparison_settings()
    for name, value in PREVIOUS_DEFAULTS.items():
        assert operator.attrgetter(name)(settings) == value, name
    assert settings.slow_fractions.slow_fraction("library") is None
    assert isinstance(settings.gait_cycle.cycles, int)
    assert compare.comparison_config_path().name == "energetics_compare.yaml"
    assert compare.comparison_config_path().is_file()


def test_duration_cuts_the_gait_cycle_to_whole_cycles():
    settings = compare.load_comparison_settings()
    assert compare.with_duration(settings, 2.5).gait_cycle.cycles == 2
    assert compare.with_duration(settings, 0.3).gait_cycle.cycles == 1
    assert compare.with_duration(settings, 600.0).gait_cycle.cycles == 20
    assert compare.with_duration(settings, 2.5).knee_extension.duration == 2.5


def _shipped():
    with open(compare.comparison_config_path(), encoding="utf-8") as handle:
        return yaml.safe_load(handle)


def _write(tmp_path, data, name="compare.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _bad(edit):
    def apply(data):
        edit(data)
        return data
    return apply


BAD_ENTRIES = [
    ("isometric.duration.unit", _bad(lambda d: d["isometric"]["duration"].update(unit="L0"))),
    ("gait_cycle.frequency.unit", _bad(lambda d: d["gait_cycle"]["frequency"].update(unit="Hzz"))),
    ("compositions.slow.source", _bad(lambda d: d["compositions"]["slow"].pop("source"))),
    ("isovelocity.drive.value", _bad(lambda d: d["isovelocity"]["drive"].update(value="half"))),
    ("isometric.drives.value", _bad(lambda d: d["isometric"]["drives"].update(value=0.5))),
    ("run.sweep_muscle.value", _bad(lambda d: d["run"]["sweep_muscle"].update(value=3))),
    ("gait_cycle.cycles.value", _bad(lambda d: d["gait_cycle"]["cycles"].update(value=2.5))),
    ("compositions.fast.value", _bad(lambda d: d["compositions"]["fast"].update(value=1.5))),
    ("run.sweep_recovery_mode.value",
     _bad(lambda d: d["run"]["sweep_recovery_mode"].update(value="slow"))),
    ("knee_extension.duration.tag",
     _bad(lambda d: d["knee_extension"]["duration"].update(tag="X"))),
    ("knee_extension", _bad(lambda d: d.pop("knee_extension"))),
]


@pytest.mark.parametrize("field_name,edit", BAD_ENTRIES, ids=[b[0] for b in BAD_ENTRIES])
def test_bad_config_entry_is_one_line_naming_file_and_field(tmp_path, capsys, field_name, edit):
    path = _write(tmp_path, edit(_shipped()))
    out = tmp_path / "x"
    code = main(["compare-energetics", "--config", str(path), "--out", str(out), "--no-plots"])
    assert code == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "compare-energetics: error" in err[0], err
    assert str(path) in err[0] and f"'{field_name}" in err[0], err[0]
    assert "Traceback" not in captured.err and not out.exists()


def test_missing_config_file_is_one_line(tmp_path, capsys):
    code = main(["compare-energetics", "--config", str(tmp_path / "none.yaml"), "--out",
                 str(tmp_path / "x")])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "none.yaml" in err[0]


def test_config_option_changes_the_run(tmp_path):
    data = _shipped()
    data["isometric"]["drives"]["value"] = [0.3]
    data["isometric"]["duration"]["value"] = 50  # ms: a unit of time the loader converts
    data["isometric"]["duration"]["unit"] = "ms"
    data["compositions"]["fast"]["value"] = 0.25
    path = _write(tmp_path, data)
    settings = compare.load_comparison_settings(path)
    assert settings.isometric.drives == (0.3,) and settings.isometric.duration == 0.05
    out = tmp_path / "cmp"
    code = main(["compare-energetics", "--config", str(path), "--scenarios", "isometric",
                 "--compositions", "fast", "--models", "margaria1968", "--out", str(out)])
    assert code == 0
    rows = _table(out / "energetics_comparison.csv")
    assert {r["scenario"] for r in rows} == {"isometric_u0.30"}
    assert {r["fpcsa_slow"] for r in rows} == {"0.25"}  # the file's fast composition
    assert all(float(r["duration_s"]) == pytest.approx(0.05) for r in rows)
    # every margaria1968 ratio is round-off (no work isometric): a chart of ~0 marks only
    assert (out / "ratio_isometric.png").is_file() or not _has_matplotlib()


def _has_matplotlib():
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return False
    return True


def test_ratio_axis():
    assert compare.ratio_axis([0.24, 20.3, 1e-13, np.nan], 1e-3) == ("log", 0.1)
    assert compare.ratio_axis([-12.0, 0.032, 5.0], 1e-3) == ("symlog", 0.01)
    assert compare.ratio_axis([1e-12], 1e-3) == ("log", 1.0)
