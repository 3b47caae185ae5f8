"""The unit table: every unit used in the shipped configuration is in it, conversions equal numbers
worked out by hand, and a unit of the wrong quantity or outside the table is a ConfigError."""

from __future__ import annotations

import math

import pytest
import yaml

from vm_ros.errors import ConfigError
from vm_ros.model.params import load_model_params
from vm_ros.model.units import UNITS, unit_for_field, units_for
from vm_ros.resources import config_dir


def _units_in(node):
    if isinstance(node, dict):
        if isinstance(node.get("unit"), str):
            yield node["unit"]
        for child in node.values():
            yield from _units_in(child)
    elif isinstance(node, list):
        for child in node:
            yield from _units_in(child)


def test_every_unit_in_the_shipped_config_is_in_the_table():
    seen = set()
    for path in sorted(config_dir().glob("*.yaml")):
        for unit in _units_in(yaml.safe_load(path.read_text())):
            assert unit in UNITS, (path.name, unit)
            seen.add(unit)
    assert {"ms", "s", "N/cm^2", "g/cm^3", "kJ/(kg K)", "deg"} <= seen


def test_each_si_form_is_itself_a_unit_of_factor_one():
    for unit in UNITS.values():
        assert UNITS[unit.si].factor == 1.0, unit
        assert UNITS[unit.si].quantity == unit.quantity, unit


# (value, unit, value in SI): the SI numbers are written out by hand, not computed from the table.
CONVERSIONS = [
    (34.3, "ms", 0.0343),  # tf1 slow: 34.3 ms
    (200.0, "ms", 0.2),
    (31.8, "N/cm^2", 318_000.0),  # 31.8 N over 1 cm^2 = 1e-4 m^2
    (1.06, "g/cm^3", 1060.0),  # 1.06 g per cm^3: 1.06e-3 kg / 1e-6 m^3
    (3.75, "kJ/(kg K)", 3750.0),
    (180.0, "deg", math.pi),
    (2.5, "cm", 0.025),
    (12.0, "mm", 0.012),
    (250.0, "g", 0.25),
    (4.0, "kPa", 4000.0),
    (8.5, "pulses/s", 8.5),
    (0.72, "L0/s", 0.72),  # normalised units stay as they are
]


@pytest.mark.parametrize(("value", "unit", "si_value"), CONVERSIONS)
def test_conversion_to_si(value, unit, si_value):
    assert value * UNITS[unit].factor == pytest.approx(si_value, rel=1e-12)


def test_shipped_model_values_in_si():
    p = load_model_params()
    assert p.fibre.tf1 == pytest.approx([0.0343, 0.0206], rel=1e-12)
    assert p.fibre.ty == pytest.approx([0.2, 0.2], rel=1e-12)
    assert p.generic.specific_tension == pytest.approx(318_000.0, rel=1e-12)
    assert p.generic.muscle_density == pytest.approx(1060.0, rel=1e-12)
    assert p.energetics.heat_capacity == pytest.approx(3750.0, rel=1e-12)
    assert p.continuous.tau_rise == pytest.approx(0.03, rel=1e-12)


def test_accepted_units_of_a_quantity():
    assert units_for("s") == ["s", "ms"]
    assert set(units_for("Pa")) == {"Pa", "N/m^2", "kPa", "N/cm^2"}


@pytest.mark.parametrize("written", ["msec", "MS", "", "sec", None, 1])
def test_unit_not_in_table_names_file_field_and_unit(written):
    with pytest.raises(ConfigError) as info:
        unit_for_field("model.yaml", "fibre_type_parameters.tf1.unit", written, "s")
    err = info.value
    assert (err.path, err.field, err.value) == ("model.yaml", "fibre_type_parameters.tf1.unit",
                                                written)
    assert "not an accepted unit" in str(err) and "s, ms" in str(err)


@pytest.mark.parametrize(("written", "holds"), [("mm", "s"), ("ms", "m"), ("L0", "m"),
                                                ("1", "s"), ("g/cm^3", "Pa"), ("s", "1")])
def test_unit_of_another_quantity_is_an_error(written, holds):
    with pytest.raises(ConfigError) as info:
        unit_for_field("f.yaml", "x.unit", written, holds)
    assert info.value.value == written
    assert UNITS[written].quantity in str(info.value)
    assert UNITS[holds].quantity in str(info.value)
