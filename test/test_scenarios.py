"""Scenario constants (config/scenarios.yaml): units are checked and converted like model.yaml's."""

from __future__ import annotations

import math

import pytest
import yaml

from vm_ros.errors import ConfigError
from vm_ros.offline.scenarios import load_scenario, scenario_names
from vm_ros.resources import config_dir


def _write_variant(tmp_path, key, **item):
    data = yaml.safe_load((config_dir() / "scenarios.yaml").read_text(encoding="utf-8"))
    data["scenarios"]["knee_extension"][key].update(item)
    path = tmp_path / "scenarios.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_every_shipped_scenario_loads():
    for name in scenario_names():
        assert load_scenario(name).duration_s > 0


def test_degrees_are_converted_to_radians():
    values = load_scenario("knee_extension").values
    assert values["angle_min"] == pytest.approx(80.0 * math.pi / 180.0, rel=1e-15)
    assert values["angle_max"] == pytest.approx(170.0 * math.pi / 180.0, rel=1e-15)


def test_milliseconds_are_converted_to_seconds(tmp_path):
    path = _write_variant(tmp_path, "duration", value=2500.0, unit="ms")
    assert load_scenario("knee_extension", path).duration_s == pytest.approx(2.5, rel=1e-15)


@pytest.mark.parametrize(("key", "unit"), [("duration", "min"), ("duration", "m"),
                                           ("angle_min", "degrees"), ("moment_arm", "s")])
def test_a_unit_outside_the_table_or_of_another_quantity_is_an_error(tmp_path, key, unit):
    path = _write_variant(tmp_path, key, unit=unit)
    with pytest.raises(ConfigError) as info:
        load_scenario("knee_extension", path)
    text = str(info.value)
    assert f"scenarios.knee_extension.{key}.unit" in text and unit in text and "\n" not in text


def test_an_unknown_constant_is_an_error(tmp_path):
    data = yaml.safe_load((config_dir() / "scenarios.yaml").read_text(encoding="utf-8"))
    data["scenarios"]["knee_extension"]["drive_fractoin"] = {"value": 0.2, "unit": "1"}
    path = tmp_path / "scenarios.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    with pytest.raises(ConfigError, match="drive_fractoin"):
        load_scenario("knee_extension", path)
