"""The published heat-rate models (vm_ros.model.energetics_models) against OpenSim 4.6's own probes.

A one-muscle OpenSim model (a Millard2012EquilibriumMuscle with a rigid tendon on a slider) carries
Umberger2010MuscleMetabolicsProbe and Bhargava2004MuscleMetabolicsProbe instances, one per option
set and per component (a probe with only that rate on reports that component). Over a grid of
states (excitation, activation including 0, fibre length 0.6-1.5 L0, velocity shortening,
isometric and lengthening) the state the probe reads is read back from OpenSim, fed to vm_ros's
functions, and every component compared. The config loader's bad entries are checked without
OpenSim.
"""

from __future__ import annotations

import dataclasses
import itertools
import types

import numpy as np
import pytest
import yaml

from vm_ros.errors import ConfigError
from vm_ros.model import energetics_models
from vm_ros.model.energetics_models import (
    MuscleState,
    bhargava2004,
    load_bhargava_constants,
    load_umberger_constants,
    muscle_mass,
    probe_total,
    umberger2003,
)
from vm_ros.model.energetics_models.in_bank import model_names
from vm_ros.model.energetics_models.umberger import force_length_multiplier_from_state
from vm_ros.model.energetics_models.vm_state import published_model
from vm_ros.resources import config_dir

RTOL = 1e-9
F0, L0, SLACK = 1000.0, 0.1, 0.2  # N, m, m
SLOW_FRACTION = 0.4
EXCITATIONS = (0.0, 0.3, 1.0)
ACTIVATIONS = (0.0, 0.05, 0.5, 1.0)
FIBRE_LENGTHS_L0 = (0.6, 0.8, 1.0, 1.1, 1.3, 1.5)
VELOCITIES = (-0.8, -0.3, -0.05, 0.0, 0.05, 0.3, 0.8)  # m/s (L0 = 0.1 m, Vmax = 10 L0/s)

UMBERGER_OPTIONS = {  # name: (variant, OpenSim property overrides)
    "uchida2016": ("uchida2016", {}),
    "umberger2003": ("umberger2003", {}),
    "umberger2010": ("umberger2010", {}),
    "anaerobic_scaled": ("uchida2016", {"aerobic_factor": 1.0,
                                        "muscle_effort_scaling_factor": 0.8,
                                        "enforce_minimum_heat_rate_per_muscle": False}),
}
UMBERGER_COMPONENTS = {  # component: the rate flags on
    "activation_maintenance": ("activation_maintenance_rate_on",),
    "shortening_lengthening": ("shortening_rate_on",),
    "mechanical_work": ("mechanical_work_rate_on",),
    "total": ("activation_maintenance_rate_on", "shortening_rate_on", "mechanical_work_rate_on"),
}
UMBERGER_FLAGS = UMBERGER_COMPONENTS["total"]
BHARGAVA_OPTIONS = {
    "default": {},
    "force_dependent": {"use_force_dependent_shortening_prop_constant": True},
    "published": {"include_negative_mechanical_work": False,
                  "forbid_negative_total_power": False},
    "scaled_no_minimum": {"muscle_effort_scaling_factor": 0.8,
                          "enforce_minimum_heat_rate_per_muscle": False},
}
BHARGAVA_FLAGS = ("activation_rate_on", "maintenance_rate_on", "shortening_rate_on",
                  "mechanical_work_rate_on")
BHARGAVA_MUSCLE_CONSTANTS = ("activation_constant_slow_twitch", "activation_constant_fast_twitch",
                             "maintenance_constant_slow_twitch", "maintenance_constant_fast_twitch")
BHARGAVA_COMPONENTS = {
    "activation_maintenance": ("activation_rate_on", "maintenance_rate_on"),
    "shortening_lengthening": ("shortening_rate_on",),
    "mechanical_work": ("mechanical_work_rate_on",),
    "total": BHARGAVA_FLAGS,
}


def _set(probe, name, value):
    getattr(probe, f"set_{name}")(value)


def _build(osim):
    """The model, its state, the muscle and the probes {(model, option set, component): probe}."""
    model = osim.Model()
    model.setGravity(osim.Vec3(0))
    body = osim.Body("slider", 1.0, osim.Vec3(0), osim.Inertia(0.01, 0.01, 0.01))
    model.addBody(body)
    joint = osim.SliderJoint("slide", model.getGround(), osim.Vec3(0), osim.Vec3(0),
                             body, osim.Vec3(0), osim.Vec3(0))
    joint.upd_coordinates(0).setName("x")
    model.addJoint(joint)
    muscle = osim.Millard2012EquilibriumMuscle("mus", F0, L0, SLACK, 0.0)
    muscle.addNewPathPoint("origin", model.getGround(), osim.Vec3(0))
    muscle.addNewPathPoint("insertion", body, osim.Vec3(0))
    muscle.set_ignore_tendon_compliance(True)
    muscle.set_minimum_activation(0.0)
    model.addForce(muscle)
    probes = {}
    for option_set, (variant, overrides) in UMBERGER_OPTIONS.items():
        constants = dataclasses.replace(load_umberger_constants(variant), **overrides)
        for component, flags in UMBERGER_COMPONENTS.items():
            probe = osim.Umberger2010MuscleMetabolicsProbe()
            probe.setName(f"umberger_{option_set}_{component}")
            probe.set_report_total_metabolics_only(False)
            for name in ("use_Bhargava_recruitment_model", "include_negative_mechanical_work",
                         "forbid_negative_total_power", "enforce_minimum_heat_rate_per_muscle",
                         "aerobic_factor", "muscle_effort_scaling_factor"):
                _set(probe, name, getattr(constants, name))
            _set(probe, "basal_rate_on", False)
            for flag in UMBERGER_FLAGS:
                _set(probe, flag, flag in flags)
            probe.addMuscle("mus", SLOW_FRACTION)
            model.addProbe(probe)
            probes["umberger", option_set, component] = probe
    for option_set, overrides in BHARGAVA_OPTIONS.items():
        constants = dataclasses.replace(load_bhargava_constants(), **overrides)
        for component, flags in BHARGAVA_COMPONENTS.items():
            probe = osim.Bhargava2004MuscleMetabolicsProbe()
            probe.setName(f"bhargava_{option_set}_{component}")
            probe.set_report_total_metabolics_only(False)
            for name in overrides:
                _set(probe, name, getattr(constants, name))
            _set(probe, "basal_rate_on", False)
            for flag in BHARGAVA_FLAGS:
                _set(probe, flag, flag in flags)
            probe.addMuscle("mus", SLOW_FRACTION, *(getattr(constants, f)
                                                    for f in BHARGAVA_MUSCLE_CONSTANTS))
            model.addProbe(probe)
            probes["bhargava", option_set, component] = probe
    for name, cls in (("umberger", osim.Umberger2010MuscleMetabolicsProbe),
                      ("bhargava", osim.Bhargava2004MuscleMetabolicsProbe)):
        probe = cls()  # OpenSim's defaults, basal_rate_on included: TOTAL = muscles + basal
        probe.setName(f"{name}_with_basal")
        probe.set_report_total_metabolics_only(False)
        if name == "umberger":
            probe.addMuscle("mus", SLOW_FRACTION)
        else:
            probe.addMuscle("mus", SLOW_FRACTION, *(getattr(load_bhargava_constants(), f)
                                                    for f in BHARGAVA_MUSCLE_CONSTANTS))
        model.addProbe(probe)
        probes[name, "with_basal", "total"] = probe
    state = model.initSystem()
    muscle = osim.Millard2012EquilibriumMuscle.safeDownCast(model.getMuscles().get("mus"))
    return model, state, muscle, probes


@pytest.fixture(scope="module")
def opensim_grid(osim):
    """Per grid state: OpenSim's state as the probes read it, and every probe's muscle output."""
    model, state, muscle, probes = _build(osim)
    coordinate = model.getCoordinateSet().get("x")
    rows, outputs = [], {key: [] for key in probes}
    for u, a, length, velocity in itertools.product(EXCITATIONS, ACTIVATIONS, FIBRE_LENGTHS_L0,
                                                    VELOCITIES):
        coordinate.setValue(state, SLACK + length * L0)
        coordinate.setSpeedValue(state, velocity)
        muscle.setActivation(state, a)
        model.realizeVelocity(state)
        controls = model.updControls(state)
        muscle.setControls(osim.Vector(1, u), controls)
        model.setControls(state, controls)
        model.realizeReport(state)
        rows.append({
            "excitation": muscle.getControl(state),
            "activation": muscle.getActivation(state),
            "fibre_length": muscle.getFiberLength(state),
            "fibre_velocity": muscle.getFiberVelocity(state),
            "active_fibre_force": muscle.getActiveFiberForce(state),
            "passive_fibre_force": muscle.getPassiveFiberForce(state),
            "force_length_multiplier": muscle.getActiveForceLengthMultiplier(state),
        })
        for key, probe in probes.items():
            values = probe.getProbeOutputs(state).to_numpy()
            if key[1] == "with_basal":
                outputs[key].append(values[0])  # TOTAL: the muscle's rate plus the basal rate
                continue
            assert values[1] == 0.0  # basal off
            outputs[key].append(values[2])  # the muscle's own rate (W)
    table = {name: np.array([row[name] for row in rows]) for name in rows[0]}
    masses = {probe.getMuscleMass("mus") for probe in probes.values()}
    assert len(masses) == 1
    table["mass"] = masses.pop()
    table["max_contraction_velocity"] = muscle.getMaxContractionVelocity()
    table["body_mass"] = model.getTotalMass(state)
    return table, {key: np.array(values) for key, values in outputs.items()}


def _muscle_state(table) -> MuscleState:
    n = len(table["excitation"])
    return MuscleState(
        excitation=table["excitation"],
        activation=table["activation"],
        fibre_length=table["fibre_length"],
        optimal_fibre_length=np.full(n, L0),
        fibre_velocity=table["fibre_velocity"],
        active_fibre_force=table["active_fibre_force"],
        isometric_force=table["activation"] * table["force_length_multiplier"] * F0,
        max_isometric_force=np.full(n, F0),
        mass=np.full(n, table["mass"]),
        slow_fraction=np.full(n, SLOW_FRACTION),
    )


def test_the_grid_covers_what_it_claims(opensim_grid):
    table, _ = opensim_grid
    assert table["activation"].min() == 0.0 and table["excitation"].min() == 0.0
    assert table["fibre_velocity"].min() < 0.0 < table["fibre_velocity"].max()
    assert table["fibre_length"].min() < L0 < table["fibre_length"].max()
    assert np.any(table["passive_fibre_force"] > 0.0)
    assert table["max_contraction_velocity"] == load_umberger_constants().max_contraction_velocity


def test_muscle_mass_is_opensims(opensim_grid):
    table, _ = opensim_grid
    c = load_umberger_constants()
    assert muscle_mass(F0, L0, c.specific_tension, c.density) == pytest.approx(table["mass"],
                                                                              rel=1e-15)


def _compare(name, ours, theirs):
    scale = np.maximum(np.abs(theirs), 1.0)  # W; the rates at 0 are compared absolutely to 1 W
    worst = np.max(np.abs(ours - theirs) / scale)
    assert worst <= RTOL, f"{name}: worst relative difference {worst:.3g}"
    return worst


@pytest.mark.parametrize("option_set", sorted(UMBERGER_OPTIONS))
def test_umberger_equals_opensims_probe(opensim_grid, option_set):
    table, outputs = opensim_grid
    variant, overrides = UMBERGER_OPTIONS[option_set]
    constants = dataclasses.replace(load_umberger_constants(variant), **overrides)
    state = _muscle_state(table)
    rates = umberger2003(state, constants, force_length_multiplier=table["force_length_multiplier"])
    for component in UMBERGER_COMPONENTS:
        _compare(component, getattr(rates, component), outputs["umberger", option_set, component])
    active = table["activation"] > 0.0  # there the multiplier follows from the state itself
    derived = umberger2003(state, constants,
                           force_length_multiplier=force_length_multiplier_from_state(state))
    assert np.allclose(force_length_multiplier_from_state(state)[active],
                       table["force_length_multiplier"][active], rtol=1e-12, atol=0.0)
    _compare("total (F_iso from the state)", derived.total[active],
             outputs["umberger", option_set, "total"][active])


@pytest.mark.parametrize("option_set", sorted(BHARGAVA_OPTIONS))
def test_bhargava_equals_opensims_probe(opensim_grid, option_set):
    table, outputs = opensim_grid
    constants = dataclasses.replace(load_bhargava_constants(), **BHARGAVA_OPTIONS[option_set])
    rates = bhargava2004(_muscle_state(table), constants,
                         passive_fibre_force=table["passive_fibre_force"])
    for component in BHARGAVA_COMPONENTS:
        _compare(component, getattr(rates, component), outputs["bhargava", option_set, component])


def test_bhargava_without_passive_force_differs_by_its_shortening_heat(opensim_grid):
    """Without the passive force (not in MuscleState) the shortening heat lacks 0.25 F_p |V|."""
    table, _ = opensim_grid
    constants = load_bhargava_constants()
    state = _muscle_state(table)
    shortening_only = dataclasses.replace(constants, forbid_negative_total_power=False)
    full = bhargava2004(state, shortening_only, passive_fibre_force=table["passive_fibre_force"])
    without = bhargava2004(state, shortening_only, passive_fibre_force=0.0)
    expected = np.where(table["fibre_velocity"] <= 0.0,
                        -0.25 * table["passive_fibre_force"] * table["fibre_velocity"], 0.0)
    assert np.allclose(full.shortening_lengthening - without.shortening_lengthening, expected,
                       rtol=1e-12, atol=1e-12)


# --- the loader ---------------------------------------------------------------------------------


def _write_bad(tmp_path, edit):
    data = yaml.safe_load((config_dir() / "energetics_models.yaml").read_text(encoding="utf-8"))
    edit(data)
    path = tmp_path / "energetics_models.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


@pytest.mark.parametrize(("edit", "field", "words"), [
    (lambda d: d["umberger"]["aerobic_factor"].update(value="high"),
     "umberger.aerobic_factor.value", "finite number"),
    (lambda d: d["umberger"]["max_contraction_velocity"].update(unit="m/s"),
     "umberger.max_contraction_velocity.unit", "not an accepted unit"),
    (lambda d: d["umberger"]["density"].update(unit="W/kg"), "umberger.density.unit",
     "power per mass"),
    (lambda d: d["umberger"]["basal_rate_on"].update(value=1), "umberger.basal_rate_on.value",
     "true or false"),
    (lambda d: d["umberger"].pop("minimum_heat_rate"), "umberger.minimum_heat_rate", "missing"),
    (lambda d: d["umberger"].update(extra={"value": 1, "unit": "1", "tag": "L", "source": "x"}),
     "umberger.extra", "unknown parameter"),
    (lambda d: d["umberger"]["aerobic_factor"].pop("source"), "umberger.aerobic_factor.source",
     "missing"),
    (lambda d: d["umberger_variants"]["uchida2016"].update(aerobic_factor=True),
     "umberger_variants.uchida2016", "option names"),
])
def test_a_bad_umberger_entry_is_a_one_line_config_error(tmp_path, edit, field, words):
    with pytest.raises(ConfigError) as caught:
        load_umberger_constants(path=_write_bad(tmp_path, edit))
    message = str(caught.value)
    assert f"'{field}'" in message and words in message and "\n" not in message


def test_a_bad_bhargava_curve_or_variant_is_a_config_error(tmp_path):
    path = _write_bad(tmp_path, lambda d: d["bhargava"]["maintenance_length_dependence_x"].update(
        value=[0.0, 1.0, 0.5, 1.5, 2.0]))
    with pytest.raises(ConfigError, match="rise strictly"):
        load_bhargava_constants(path=path)
    with pytest.raises(ConfigError, match="unknown variant; known: umberger2003"):
        load_umberger_constants("umberger2020")


def test_the_shipped_file_holds_opensims_defaults():
    """Independent numbers: OpenSim 4.6's property defaults (constructProperties)."""
    u, b = load_umberger_constants(), load_bhargava_constants()
    assert (u.aerobic_factor, u.basal_coefficient, u.specific_tension, u.density) == (
        1.5, 1.2, 0.25e6, 1059.7)
    assert not u.basal_rate_on and not b.basal_rate_on
    assert (b.activation_constant_slow_twitch, b.activation_constant_fast_twitch,
            b.maintenance_constant_slow_twitch, b.maintenance_constant_fast_twitch) == (
        40.0, 133.0, 74.0, 111.0)
    assert b.maintenance_length_dependence_y == (0.5, 0.5, 1.0, 0.0, 0.0)


@pytest.mark.parametrize("name", ["umberger", "bhargava"])
def test_probe_total_with_basal_equals_opensims_total(opensim_grid, name):
    """OpenSim's probes with their defaults (basal_rate_on true) report TOTAL = the muscles'
    rates + basal_coefficient * body mass^basal_exponent, once: probe_total(include_basal=True)
    gives the same; without the basal rate it is 1.2 W/kg x 1 kg short."""
    table, outputs = opensim_grid
    state = _muscle_state(table)
    if name == "umberger":
        constants = load_umberger_constants("uchida2016")
        rates = umberger2003(state, constants,
                             force_length_multiplier=table["force_length_multiplier"])
    else:
        constants = load_bhargava_constants()
        rates = bhargava2004(state, constants, passive_fibre_force=table["passive_fibre_force"])
    per_state = types.SimpleNamespace(total=rates.total[:, None])  # one muscle per grid state
    theirs = outputs[name, "with_basal", "total"]
    _compare("total with basal", probe_total(per_state, table["body_mass"], constants), theirs)
    without = probe_total(per_state, table["body_mass"], constants, include_basal=False)
    np.testing.assert_allclose(theirs - without, 1.2 * table["body_mass"], rtol=1e-9)
    assert constants.basal_rate_on is False  # the shipped default: per muscle, no basal


def test_former_model_names_still_work_for_one_release():
    assert model_names("lichtwark_wilson, minetti_alexander") == ("lichtwark2005", "minetti1997")
    assert published_model("lichtwark_wilson").name == "lichtwark2005"
    state = _muscle_state({k: np.array([v]) for k, v in (
        ("excitation", 0.5), ("activation", 0.5), ("fibre_length", L0), ("fibre_velocity", -0.1),
        ("active_fibre_force", 300.0), ("force_length_multiplier", 1.0))} | {"mass": 0.5})
    constants = load_umberger_constants()
    with pytest.warns(DeprecationWarning, match="umberger is now umberger2003"):
        old = energetics_models.umberger(state, constants, force_length_multiplier=1.0)
    assert old.total == umberger2003(state, constants, force_length_multiplier=1.0).total
    with pytest.raises(TypeError, match="force_length_multiplier"):
        umberger2003(state, constants)  # required: no silent F_iso = 1 or state-derived value
    with pytest.raises(TypeError, match="passive_fibre_force"):
        bhargava2004(state, load_bhargava_constants())


def test_a_former_name_on_the_command_line_says_its_new_name(capsys):
    from vm_ros.cli.simulate import energetics_models_option

    assert energetics_models_option("lichtwark_wilson,umberger2003") == ("lichtwark2005",
                                                                        "umberger2003")
    assert capsys.readouterr().err == ("vm-ros: --energetics-models lichtwark_wilson is now "
                                       "lichtwark2005; the former name goes in the next release\n")
    energetics_models_option("lichtwark2005")
    assert capsys.readouterr().err == ""
