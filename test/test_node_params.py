"""muscle_node's parameter table and its validation (no ROS needed)."""

from __future__ import annotations

import dataclasses

import pytest
import yaml

from vm_ros.errors import ConfigError
from vm_ros.node.params import PARAMS, PARAMS_BY_NAME, NodeConfig, runtime_parameter_names
from vm_ros.resources import config_dir


def test_table_and_config_agree():
    assert {f.name for f in dataclasses.fields(NodeConfig)} == {p.field for p in PARAMS}
    assert len(PARAMS_BY_NAME) == len(PARAMS)
    for spec in PARAMS:
        assert spec.description and spec.unit, spec.name
        assert spec.describe().endswith("."), spec.name


def test_defaults_are_valid():
    config = NodeConfig.defaults()
    assert config.model_rate_hz == 1000.0 and config.publish_rate_hz == 100.0
    assert config.step_ns == 1_000_000 and config.publish_every_steps == 10
    assert config.as_parameters()["muscles"] == list(config.muscles)


def test_shipped_params_file_is_valid():
    data = yaml.safe_load((config_dir() / "muscle_node.yaml").read_text())
    values = data["/**"]["ros__parameters"]
    flat = {}
    for key, value in values.items():  # nested mappings are dotted parameter names
        if isinstance(value, dict):
            flat.update({f"{key}.{k}": v for k, v in value.items()})
        else:
            flat[key] = value
    flat.pop("use_sim_time", None)
    config = NodeConfig.from_values(flat)
    assert config.muscles


@pytest.mark.parametrize(
    ("values", "field"),
    [
        ({"model_rate_hz": -1.0}, "model_rate_hz"),
        ({"model_rate_hz": "fast"}, "model_rate_hz"),
        ({"model_rate_hz": float("nan")}, "model_rate_hz"),
        ({"model_rate_hz": True}, "model_rate_hz"),
        ({"publish_rate_hz": 2000.0}, "publish_rate_hz"),
        ({"recruitment": "nope"}, "recruitment"),
        ({"recovery_mode": "fast"}, "recovery_mode"),
        ({"drive_law": "song2008"}, "drive_law"),
        ({"stale_input_policy": "ignore"}, "stale_input_policy"),
        ({"max_catch_up_steps": 0}, "max_catch_up_steps"),
        ({"batch_steps": -1}, "batch_steps"),
        ({"batch_steps": 60}, "batch_steps"),  # more than max_catch_up_steps (50)
        ({"max_catch_up_steps": 5}, "batch_steps"),  # a publish period of 10 steps per tick
        ({"energetics_models": ["umberger2099"]}, "energetics_models"),
        ({"energetics_models": ["all", "margaria1968"]}, "energetics_models"),
        ({"qos_depth": 0}, "qos_depth"),
        ({"units_per_type": 2.5}, "units_per_type"),
        ({"muscles": []}, "muscles"),
        ({"muscles": ["vasti", "vasti"]}, "muscles"),
        ({"muscles": "vasti"}, "muscles"),
        ({"initial_path_length_m": [0.3]}, "initial_path_length_m"),
        ({"initial_path_length_m": [0.3, -0.1]}, "initial_path_length_m"),
        ({"initial_path_length_m": [0.3, float("inf")]}, "initial_path_length_m"),
        ({"overrides": "{vasti: 3}"}, "overrides"),
        ({"overrides": "{vasti: [unclosed"}, "overrides"),
        ({"mcap.enabled": "yes"}, "mcap.enabled"),
        ({"model_rate": 500.0}, "model_rate"),
    ],
)
def test_bad_value_names_the_parameter(values, field):
    with pytest.raises(ConfigError) as info:
        NodeConfig.from_values(values)
    assert info.value.field == field
    assert field in str(info.value)


def test_integers_are_accepted_for_doubles():
    config = NodeConfig.from_values({"model_rate_hz": 500, "publish_rate_hz": 50})
    assert config.model_rate_hz == 500.0 and isinstance(config.model_rate_hz, float)
    assert config.publish_every_steps == 10


def test_overrides_yaml():
    config = NodeConfig.from_values({"overrides": "{vasti: {fpcsa_slow: 0.5}}"})
    assert config.overrides_mapping() == {"vasti": {"fpcsa_slow": 0.5}}
    assert NodeConfig.defaults().overrides_mapping() == {}


def test_with_values_validates_runtime_changes():
    config = NodeConfig.defaults()
    assert config.with_values({"input_timeout_s": 2}).input_timeout_s == 2.0
    with pytest.raises(ConfigError):
        config.with_values({"stale_input_policy": "bogus"})
    assert set(runtime_parameter_names()) >= {"input_timeout_s", "stale_input_policy"}
    assert "model_rate_hz" not in runtime_parameter_names()
