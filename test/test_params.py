"""Configuration loading: every shipped value has a source; errors name the file and the field."""

from __future__ import annotations

import pytest
import yaml

from vm_ros.errors import ConfigError
from vm_ros.model import MuscleBank, load_model_params, load_muscle_library
from vm_ros.resources import config_dir

REQUIRED_MUSCLES = ("biceps_long_head", "soleus", "vastus_lateralis", "rectus_femoris", "vasti")


def test_every_model_entry_has_unit_tag_and_source():
    data = yaml.safe_load((config_dir() / "model.yaml").read_text())
    sections = [data["fibre_type_parameters"], data["generic"], data["energetics"],
                *data["recruitment"].values()]
    for section in sections:
        for name, entry in section.items():
            assert {"unit", "tag", "source"} <= set(entry), name
            assert entry["tag"] in ("C", "L", "R"), name
            assert len(entry["source"]) > 5, name


def test_library_has_required_muscles_with_sources_and_sane_lmax():
    library = load_muscle_library()
    assert set(REQUIRED_MUSCLES) <= set(library)
    assert len(library) >= 10
    bank = MuscleBank.from_config(sorted(library))
    for name, spec, lmax in zip(bank.names, bank.specs, bank.lmax, strict=True):
        assert spec.source, name
        for field in ("mass_kg", "l0_m", "l0t_m", "fpcsa_slow"):
            assert field in spec.source, (name, field)
        assert lmax >= 1.1 and lmax <= 1.4, (name, lmax)
    assert bank.specs[bank.names.index("biceps_long_head")].fpcsa_slow == pytest.approx(0.4)


def _write_library(tmp_path, fields):
    path = tmp_path / "lib.yaml"
    path.write_text(yaml.safe_dump({"muscles": {"m": fields}}))
    return path


GOOD = {"mass_kg": 0.1, "l0_m": 0.08, "l0t_m": 0.2, "lmax": 1.3, "fpcsa_slow": 0.5}


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"mass_kg": -1.0}, "muscles.m.mass_kg"),
        ({"fpcsa_slow": 1.5}, "muscles.m.fpcsa_slow"),
        ({"l0_m": "long"}, "muscles.m.l0_m"),
        ({"ur": 0.0}, "muscles.m.ur"),
        ({"lmax": 0.9}, "muscles.m.lmax"),
        ({"path_length_max_m": 0.5}, "muscles.m.path_length_max_m"),  # both given
        ({"colour": "red"}, "muscles.m.colour"),
        ({"specific_tension_pa": 60.0, "source": {"specific_tension_pa": "N/cm^2 by mistake"}},
         "muscles.m.specific_tension_pa"),
        ({"specific_tension_pa": 6e5}, "muscles.m.source.specific_tension_pa"),  # no source
    ],
)
def test_bad_muscle_field_names_file_and_field(tmp_path, change, field):
    path = _write_library(tmp_path, {**GOOD, **change})
    with pytest.raises(ConfigError) as info:
        MuscleBank.from_config(["m"], library=path)
    assert info.value.field == field
    assert str(path) in str(info.value)


def test_missing_muscle_lists_what_exists(tmp_path):
    path = _write_library(tmp_path, GOOD)
    with pytest.raises(ConfigError, match="not in the library"):
        MuscleBank.from_config(["nope"], library=path)


def test_overrides_apply_and_unknown_override_fails(tmp_path):
    path = _write_library(tmp_path, GOOD)
    bank = MuscleBank.from_config(["m"], library=path, overrides={"m": {"fpcsa_slow": 0.2}})
    assert bank.fpcsa[0] == pytest.approx([0.2, 0.8])
    with pytest.raises(ConfigError):
        MuscleBank.from_config(["m"], library=path, overrides={"other": {"mass_kg": 1.0}})


def test_a_muscle_s_own_specific_tension_sets_its_f0(tmp_path):
    """F0 = sigma * mass / (density * l0): 0.1 kg, 0.08 m, 1060 kg/m^3 -> PCSA 11.79 cm^2; at
    60 N/cm^2 F0 = 707.5 N, at the generic 31.8 N/cm^2 375.0 N. An override keeps the entry's
    other source notes."""
    path = _write_library(tmp_path, {**GOOD, "source": {"mass_kg": "a scale"}})
    generic = MuscleBank.from_config(["m"], library=path, backend="numpy")
    own = MuscleBank.from_config(["m"], library=path, backend="numpy", overrides={"m": {
        "specific_tension_pa": 6e5, "source": {"specific_tension_pa": "Rajagopal 2016"}}})
    assert generic.f0[0] == pytest.approx(31.8e4 * 0.1 / (1060.0 * 0.08), rel=1e-12)
    assert own.f0[0] == pytest.approx(6e5 * 0.1 / (1060.0 * 0.08), rel=1e-12)
    assert own.specs[0].source == {"mass_kg": "a scale", "specific_tension_pa": "Rajagopal 2016"}
    assert own.mass_kg[0] == generic.mass_kg[0]


def test_bad_model_file_names_field(tmp_path):
    data = yaml.safe_load((config_dir() / "model.yaml").read_text())
    data["fibre_type_parameters"]["tf1"]["slow"] = -1.0
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError) as info:
        load_model_params(path)
    assert "tf1" in info.value.field
    del data["generic"]["c1"]
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="generic.c1"):
        load_model_params(path)


def test_a_model_file_of_earlier_equations_is_refused_with_why(tmp_path):
    """A model file that still holds the drive filter's rise power (a log's attached model.yaml
    from before the filtered drive per fibre type) names the field and says the file was
    written by an earlier vm_ros; another unknown field is just unknown."""
    data = yaml.safe_load((config_dir() / "model.yaml").read_text())
    data["recruitment"]["lumped"]["relative_rise_power"] = {"value": 1.0, "unit": "1"}
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="earlier vm_ros") as info:
        load_model_params(path)
    assert info.value.field == "recruitment.lumped.relative_rise_power"
    del data["recruitment"]["lumped"]["relative_rise_power"]
    data["recruitment"]["lumped"]["no_such_constant"] = {"value": 1.0, "unit": "1"}
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match="unknown parameter"):
        load_model_params(path)


def test_unreadable_and_invalid_yaml(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_model_params(tmp_path / "absent.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: [1, 2\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_model_params(bad)


def _model_file(tmp_path, change):
    """The shipped model.yaml with ``change(data)`` applied, written to tmp_path."""
    data = yaml.safe_load((config_dir() / "model.yaml").read_text())
    change(data)
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _set(section, name, key, value):
    def change(data):
        node = data
        for part in section.split("."):
            node = node[part]
        node[name][key] = value

    return change


@pytest.mark.parametrize(
    ("section", "name", "unit"),
    [
        ("fibre_type_parameters", "tf1", "msec"),  # a typo once read as 34.3 s
        ("fibre_type_parameters", "tf1", "mm"),  # a length for a time constant
        ("generic", "specific_tension", "N/cm2"),
        ("generic", "muscle_density", "ms"),
        ("recruitment.continuous", "tau_rise", "L0"),
        ("energetics", "e1", "W s^2/(kg L0^2)"),  # the wrong power of velocity
        ("recruitment.lumped", "t_rise_poly", "1"),
    ],
)
def test_bad_unit_names_file_field_and_unit(tmp_path, section, name, unit):
    path = _model_file(tmp_path, _set(section, name, "unit", unit))
    with pytest.raises(ConfigError) as info:
        load_model_params(path)
    err = info.value
    assert err.field == f"{section}.{name}.unit"
    assert err.value == unit
    message = str(err)
    assert str(path) in message and f"{section}.{name}.unit" in message and repr(unit) in message
    assert "\n" not in message


def test_time_constant_in_s_or_ms_loads_the_same(tmp_path):
    path = _model_file(tmp_path, lambda d: d["fibre_type_parameters"]["tf1"].update(
        slow=0.0343, fast=0.0206, unit="s"))
    assert load_model_params(path).fibre.tf1 == pytest.approx(load_model_params().fibre.tf1,
                                                              rel=1e-12)


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (_set("generic", "fmin", "value", "low"), "generic.fmin.value"),
        (_set("generic", "fmin", "tag", "X"), "generic.fmin.tag"),
        (_set("generic", "fmin", "source", ""), "generic.fmin.source"),
        (_set("generic", "fmin", "sorce", "typo"), "generic.fmin.sorce"),
        (_set("fibre_type_parameters", "tf1", "medium", 1.0), "fibre_type_parameters.tf1.medium"),
        (_set("recruitment.lumped", "t_rise_poly", "value", 0.3),
         "recruitment.lumped.t_rise_poly.value"),
        (_set("recruitment.lumped", "cap_recruitment_at_full", "value", "yes"),
         "recruitment.lumped.cap_recruitment_at_full.value"),
        (_set("energetics", "recovery_mode", "value", 3), "energetics.recovery_mode.value"),
        (lambda d: d["recruitment"].pop("lumped"), "recruitment.lumped"),
    ],
)
def test_bad_entry_names_its_field(tmp_path, change, field):
    with pytest.raises(ConfigError) as info:
        load_model_params(_model_file(tmp_path, change))
    assert info.value.field == field


def test_loaded_parameters_keep_unit_tag_and_source():
    data = yaml.safe_load((config_dir() / "model.yaml").read_text())
    params = load_model_params()
    sections = {"fibre_type_parameters": data["fibre_type_parameters"],
                "generic": data["generic"], "energetics": data["energetics"],
                **{f"recruitment.{k}": v for k, v in data["recruitment"].items()}}
    expected = {f"{s}.{n}": e for s, entries in sections.items() for n, e in entries.items()}
    assert set(params.info) == set(expected)
    for name, entry in expected.items():
        info = params.info[name]
        assert (info.unit, info.tag, info.source) == (entry["unit"], entry["tag"],
                                                      entry["source"]), name
    assert params.info["fibre_type_parameters.tf1"].si == "s"
    assert params.value_of("fibre_type_parameters.tf1") == pytest.approx([0.0343, 0.0206])
    assert params.value_of("generic.specific_tension") == pytest.approx(318_000.0)


def test_repeated_muscle_is_named_once_in_a_short_message():
    with pytest.raises(ConfigError) as info:
        MuscleBank.from_config(["soleus"] * 10_000)
    assert info.value.value == "soleus"
    assert "10000 times" in str(info.value) and len(str(info.value)) < 300


def test_muscle_rows_give_units_and_sources(tmp_path):
    from vm_ros.model.params import muscle_rows, resolve_muscles

    path = _write_library(tmp_path, {**GOOD, "source": {"mass_kg": "weighed"}})
    (spec,) = resolve_muscles(["m"], path, None, ur_default=0.8)
    rows = {info.name: (info, value) for info, value in muscle_rows(spec)}
    assert set(rows) == {f"muscles.m.{f}" for f in ("mass_kg", "l0_m", "l0t_m", "fpcsa_slow",
                                                     "ur", "lmax")}
    info, value = rows["muscles.m.mass_kg"]
    assert (info.unit, info.source, value) == ("kg", "weighed", 0.1)
    assert rows["muscles.m.lmax"][0].unit == "L0"
    info, value = rows["muscles.m.ur"]
    assert value == 0.8 and "ur_default" in info.source
