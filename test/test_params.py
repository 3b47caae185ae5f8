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


def test_unreadable_and_invalid_yaml(tmp_path):
    with pytest.raises(ConfigError, match="cannot read"):
        load_model_params(tmp_path / "absent.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("a: [1, 2\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_model_params(bad)
